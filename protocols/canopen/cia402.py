"""The CiA 402 (IEC 61800-7-201) power drive state machine: controlword commands, statusword states.

Pure functions of 16-bit words, shared by the master (which commands a drive towards *operation enabled*) and
the emulated drive (which moves through the states it is commanded to).

Statusword (0x6041) state bits: 0 ready to switch on, 1 switched on, 2 operation enabled, 3 fault,
5 quick stop (active low), 6 switch on disabled; bit 4 (voltage enabled) and bits 7..15 are flags beside the
state (:class:`StatusBit`). Controlword (0x6040) command bits: 0 switch on, 1 enable voltage, 2 quick stop
(active low), 3 enable operation, 7 fault reset (acts on its 0 → 1 edge); bit 8 halt. In cyclic synchronous
position mode bits 4..6 of the controlword are reserved and bit 12 of the statusword means "drive follows the
target position", bit 13 "following error".
"""

from __future__ import annotations

from enum import Enum, IntEnum, IntFlag


class State(Enum):
    """The eight states of the drive (values are their names in the standard)."""

    NOT_READY_TO_SWITCH_ON = "not ready to switch on"
    SWITCH_ON_DISABLED = "switch on disabled"
    READY_TO_SWITCH_ON = "ready to switch on"
    SWITCHED_ON = "switched on"
    OPERATION_ENABLED = "operation enabled"
    QUICK_STOP_ACTIVE = "quick stop active"
    FAULT_REACTION_ACTIVE = "fault reaction active"
    FAULT = "fault"


class Command(IntEnum):
    """Device control commands as the controlword values that carry them (other bits 0).

    ``DISABLE_OPERATION`` is the same word as ``SWITCH_ON`` (0x07) and ``ENABLE_OPERATION`` the same as the
    standard's "switch on + enable operation" (0x0F): the drive's state tells them apart.
    """

    DISABLE_VOLTAGE = 0x00
    QUICK_STOP = 0x02
    SHUTDOWN = 0x06
    SWITCH_ON = 0x07
    DISABLE_OPERATION = 0x07
    ENABLE_OPERATION = 0x0F
    FAULT_RESET = 0x80


class StatusBit(IntFlag):
    """Statusword flags beside the state bits (``flags`` of :func:`statusword`)."""

    VOLTAGE_ENABLED = 1 << 4
    WARNING = 1 << 7
    REMOTE = 1 << 9
    TARGET_REACHED = 1 << 10
    INTERNAL_LIMIT_ACTIVE = 1 << 11
    FOLLOWS_TARGET = 1 << 12
    FOLLOWING_ERROR = 1 << 13


HALT = 1 << 8
"""Controlword bit 8: halt."""

_STATE_BITS = 0x006F
"""Statusword bits that carry the state (0..3, 5, 6)."""

_STATUS_PATTERNS: tuple[tuple[int, int, State], ...] = (
    (0x4F, 0x00, State.NOT_READY_TO_SWITCH_ON),  # xxxx xxxx x0xx 0000
    (0x4F, 0x40, State.SWITCH_ON_DISABLED),  # xxxx xxxx x1xx 0000
    (0x6F, 0x21, State.READY_TO_SWITCH_ON),  # xxxx xxxx x01x 0001
    (0x6F, 0x23, State.SWITCHED_ON),  # xxxx xxxx x01x 0011
    (0x6F, 0x27, State.OPERATION_ENABLED),  # xxxx xxxx x01x 0111
    (0x6F, 0x07, State.QUICK_STOP_ACTIVE),  # xxxx xxxx x00x 0111
    (0x4F, 0x0F, State.FAULT_REACTION_ACTIVE),  # xxxx xxxx x0xx 1111
    (0x4F, 0x08, State.FAULT),  # xxxx xxxx x0xx 1000
)
"""(mask, value, state) of the standard's statusword table."""

_STATE_WORDS = {state: value for _, value, state in _STATUS_PATTERNS}
"""The state bits a drive reports in each state: the pattern's value, bits the pattern leaves free clear."""


def _word(value: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
        raise ValueError(f"{what} must be an UNSIGNED16 (0..0xFFFF), got {value!r}")
    return value


def decode_statusword(word: int) -> State:
    """The state a statusword reports; :class:`ValueError` for a word that matches no state."""
    _word(word, "statusword")
    for mask, value, state in _STATUS_PATTERNS:
        if word & mask == value:
            return state
    raise ValueError(f"statusword 0x{word:04X} matches no CiA 402 state (state bits 0x{word & _STATE_BITS:02X})")


def statusword(state: State, flags: int = 0) -> int:
    """The statusword of a drive in ``state`` with ``flags`` (:class:`StatusBit`) set."""
    if _word(flags, "statusword flags") & _STATE_BITS:
        raise ValueError(f"statusword flags 0x{flags:04X} overlap the state bits 0x{_STATE_BITS:04X}")
    return _STATE_WORDS[state] | flags


def controlword(command: Command, *, halt: bool = False) -> int:
    """The controlword that carries ``command`` (with bit 8 set when ``halt``)."""
    return int(command) | (HALT if halt else 0)


def decode_controlword(word: int) -> Command:
    """The command a controlword carries, by the standard's priorities (fault reset bit first).

    Returns ``SWITCH_ON`` for 0bxxx0_x111 (also "disable operation") and ``ENABLE_OPERATION`` for 0bxxx0_1111.
    Whether a ``FAULT_RESET`` acts depends on the previous word (edge): see :func:`transition`.
    """
    _word(word, "controlword")
    if word & 0x80:
        return Command.FAULT_RESET
    if not word & 0x02:
        return Command.DISABLE_VOLTAGE
    if not word & 0x04:
        return Command.QUICK_STOP
    if not word & 0x01:
        return Command.SHUTDOWN
    return Command.ENABLE_OPERATION if word & 0x08 else Command.SWITCH_ON


_TRANSITIONS: dict[tuple[State, Command], State] = {
    (State.SWITCH_ON_DISABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 2
    (State.READY_TO_SWITCH_ON, Command.SWITCH_ON): State.SWITCHED_ON,  # 3
    (State.READY_TO_SWITCH_ON, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,  # 3 + 4
    (State.READY_TO_SWITCH_ON, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 7
    (State.READY_TO_SWITCH_ON, Command.QUICK_STOP): State.SWITCH_ON_DISABLED,  # 7
    (State.SWITCHED_ON, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,  # 4
    (State.SWITCHED_ON, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 6
    (State.SWITCHED_ON, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 10
    (State.SWITCHED_ON, Command.QUICK_STOP): State.SWITCH_ON_DISABLED,  # 10
    (State.OPERATION_ENABLED, Command.DISABLE_OPERATION): State.SWITCHED_ON,  # 5
    (State.OPERATION_ENABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 8
    (State.OPERATION_ENABLED, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 9
    (State.OPERATION_ENABLED, Command.QUICK_STOP): State.QUICK_STOP_ACTIVE,  # 11
    (State.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 12
    (State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,  # 16
}
"""The controlword-driven transitions (standard's numbers in the comments)."""


def transition(state: State, word: int, previous_word: int = 0) -> State:
    """The state a drive in ``state`` goes to on receiving controlword ``word`` after ``previous_word``.

    Covers the controlword-driven transitions 2..12, 15 and 16. Fault reset (15) needs bit 7's rising edge
    (clear in ``previous_word``). Transitions the drive makes on its own — 0/1 (power-up and self-test,
    *not ready to switch on* → *switch on disabled*), 12 when a quick stop ramp completes, 13/14 (a fault,
    then the end of the fault reaction) — are the drive's business and not here; a command that has no
    transition from ``state`` leaves it unchanged.
    """
    command = decode_controlword(word)
    _word(previous_word, "previous controlword")
    if command is Command.FAULT_RESET:
        rising = not previous_word & 0x80
        return State.SWITCH_ON_DISABLED if state is State.FAULT and rising else state
    return _TRANSITIONS.get((state, command), state)


_TOWARDS_OPERATION = {
    State.SWITCH_ON_DISABLED: Command.SHUTDOWN,
    State.READY_TO_SWITCH_ON: Command.SWITCH_ON,
    State.SWITCHED_ON: Command.ENABLE_OPERATION,
    State.QUICK_STOP_ACTIVE: Command.DISABLE_VOLTAGE,
    State.FAULT: Command.FAULT_RESET,
}


def command_towards_operation(state: State) -> Command | None:
    """The next command that brings a drive in ``state`` closer to *operation enabled*.

    ``None`` when there is nothing to send: already enabled, or a state the drive leaves on its own
    (*not ready to switch on*, *fault reaction active*). From *quick stop active* the way back goes through
    *switch on disabled* (transition 16 is optional in the standard). A ``FAULT_RESET`` acts on bit 7's
    rising edge: the word sent before it must have bit 7 clear.
    """
    return _TOWARDS_OPERATION.get(state)
