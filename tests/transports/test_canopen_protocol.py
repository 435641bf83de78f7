"""CANopen CiA 402 wire formats of the leg drives: the EDS, PDO maps, unit scaling, state machine words and bus
load, then the real ``canopen`` stack on python-can's ``virtual`` bus (a ``LocalNode`` drive and a ``RemoteNode``
master built from the EDS, in one process) and on ``udp_multicast`` inside a network namespace (two processes)."""

from __future__ import annotations

import configparser
import json
import os
import queue
import shlex
import shutil
import socket
import subprocess
import sys
import textwrap
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import canopen
import numpy as np
import pytest
from canopen.objectdictionary import datatypes
from hypothesis import given
from hypothesis import strategies as st

from analysis.table.model import TableModel
from protocols.canopen import (
    DEFAULT_LIMIT,
    DEFAULT_RATE_HZ,
    EDS_PATH,
    LEG_NODE_IDS,
    MASTER_NODE_ID,
    PDO_MAPS,
    RPDO1,
    TPDO1,
    TPDO1_COUNTED,
    BusLoadError,
    Command,
    Feedback,
    LegRangeError,
    LegScaling,
    PdoError,
    Setpoint,
    State,
    StatusBit,
    bus_load,
    check_bus_load,
    command_towards_operation,
    configure,
    controlword,
    cycle_bits,
    cycle_period_us,
    decode_controlword,
    decode_heartbeat_consumer_entry,
    decode_statusword,
    frame_bits,
    heartbeat_consumer_entry,
    load_od,
    max_rate_hz,
    statusword,
    transition,
    velocity,
    velocity_increments,
)
from protocols.canopen import od as objects
from protocols.canopen.receive_buffer import widen_receive_buffer

NODE = 3
WAIT = 5.0
"""Upper bound [s] on waiting for a frame that must come (never reached when the stack works)."""

GEOMETRY = TableModel().geometry
SCALING = LegScaling(GEOMETRY.leg_min, GEOMETRY.leg_max)

# ----- EDS ----------------------------------------------------------------------------------------------------

REQUIRED = {
    0x1000, 0x1001, 0x1005, 0x1006, 0x1014, 0x1016, 0x1017, 0x1018, 0x1400, 0x1600, 0x1800, 0x1A00,
    0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x6065, 0x607A, 0x607D, 0x607F, 0x60F4, 0x60A8, 0x60A9, 0x6502,
}
"""The objects the leg drive must have."""


def test_eds_has_every_object_of_the_drive() -> None:
    od = load_od(NODE)
    assert set(od.indices) >= REQUIRED
    assert od[objects.DEVICE_TYPE].default == objects.DEVICE_TYPE_CIA402_SERVO == 0x00020192
    assert od[objects.DEVICE_TYPE].default & 0xFFFF == 402
    assert od[objects.SUPPORTED_DRIVE_MODES].default & objects.SUPPORTED_MODE_CSP
    assert objects.SUPPORTED_MODE_CSP == 1 << (objects.MODE_CYCLIC_SYNCHRONOUS_POSITION - 1)
    assert od[objects.COB_ID_SYNC].default == 0x80
    assert od[objects.COB_ID_EMCY].default == 0x80 + NODE
    assert od[objects.SI_UNIT_POSITION].default == objects.SI_UNIT_MICROMETRE
    assert od[objects.SI_UNIT_VELOCITY].default == objects.SI_UNIT_MICROMETRE_PER_SECOND
    assert od[objects.COMMUNICATION_CYCLE_PERIOD].default == cycle_period_us(DEFAULT_RATE_HZ) == 2000
    assert (od[objects.SOFTWARE_POSITION_LIMIT][1].default,
            od[objects.SOFTWARE_POSITION_LIMIT][2].default) == SCALING.software_position_limits == (0, 1_250_000)
    assert od[objects.MAX_PROFILE_VELOCITY].default == velocity_increments(GEOMETRY.leg_speed) == 900_000
    assert od[objects.CONSUMER_HEARTBEAT_TIME][0].default == 1
    assert od[objects.IDENTITY][2].default == objects.LEG_DRIVE_PRODUCT_CODE


def test_eds_lists_exactly_its_objects_and_every_entry_has_a_default() -> None:
    """The object lists agree with the sections, and no value was silently dropped by the parser (which ignores a
    DefaultValue it cannot parse)."""
    eds = configparser.RawConfigParser()
    eds.optionxform = str
    eds.read(EDS_PATH)
    listed = []
    for section in ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects"):
        count = int(eds.get(section, "SupportedObjects"), 0)
        assert sorted(eds.options(section)) == sorted(["SupportedObjects", *map(str, range(1, count + 1))])
        listed += [int(eds.get(section, str(k)), 0) for k in range(1, count + 1)]
    sections = {int(s, 16) for s in eds.sections() if len(s) == 4}
    assert sorted(listed) == sorted(sections)
    od = load_od(NODE)
    for index in od.indices:
        obj = od[index]
        records = canopen.objectdictionary.ODRecord | canopen.objectdictionary.ODArray
        variables = obj.values() if isinstance(obj, records) else [obj]
        for var in variables:
            assert var.default is not None, f"0x{index:04X}:{var.subindex} has no default"
            assert var.min is None or var.min <= var.default


@pytest.mark.parametrize("spec", PDO_MAPS, ids=lambda s: s.name)
def test_eds_pdo_defaults_are_the_pdo_maps(spec) -> None:
    od = load_od(NODE)
    com, mapping = od[spec.communication_index], od[spec.mapping_index]
    assert com[1].default == spec.cob_id_entry(NODE)
    assert com[2].default == spec.transmission_type == 1
    assert mapping[0].default == len(spec.objects)
    assert [mapping[k].default for k in range(1, len(spec.objects) + 1)] == [o.mapping_entry for o in spec.objects]
    assert all(mapping[k].default == 0 for k in range(len(spec.objects) + 1, 5))
    for obj in spec.objects:
        var = od[obj.index]
        assert var.pdo_mappable and len(var) == obj.bits
        assert (var.data_type in datatypes.SIGNED_TYPES) == obj.signed
    assert isinstance(mapping, canopen.objectdictionary.ODRecord)  # canopen's PdoMap.save needs a RECORD


@pytest.mark.parametrize("node_id", [0, 128, True, 2.0])
def test_load_od_refuses_bad_node_ids(node_id) -> None:
    with pytest.raises(ValueError, match=r"node id must be an integer in 1\.\.127"):
        load_od(node_id)


def test_heartbeat_consumer_entry_layout() -> None:
    assert heartbeat_consumer_entry(0x7F, 250) == 0x007F_00FA
    assert decode_heartbeat_consumer_entry(0x007F_00FA) == (0x7F, 250)
    assert decode_heartbeat_consumer_entry(heartbeat_consumer_entry(1, 0xFFFF)) == (1, 0xFFFF)
    with pytest.raises(ValueError, match=r"node id must be an integer in 0\.\.127, got 128"):
        heartbeat_consumer_entry(128, 10)
    with pytest.raises(ValueError, match=r"heartbeat consumer time must be an integer in 0\.\.65535, got 65536"):
        heartbeat_consumer_entry(1, 65536)
    with pytest.raises(ValueError, match=r"bits 24\.\.31 clear"):
        decode_heartbeat_consumer_entry(0x0100_0000)


def test_node_ids_are_the_leg_numbers() -> None:
    assert LEG_NODE_IDS == (1, 2, 3, 4, 5, 6)
    assert MASTER_NODE_ID not in LEG_NODE_IDS


# ----- PDO maps -----------------------------------------------------------------------------------------------


def test_pdo_maps_layout() -> None:
    assert (RPDO1.communication_index, RPDO1.mapping_index) == (0x1400, 0x1600)
    assert (TPDO1.communication_index, TPDO1.mapping_index) == (0x1800, 0x1A00)
    assert [o.mapping_entry for o in RPDO1.objects] == [0x6040_0010, 0x607A_0020]
    assert [o.mapping_entry for o in TPDO1.objects] == [0x6041_0010, 0x6064_0020]
    assert RPDO1.size == TPDO1.size == 6
    assert [o.mapping_entry for o in TPDO1_COUNTED.objects] == [0x6041_0010, 0x6064_0020, 0x2012_0008]
    assert TPDO1_COUNTED.size == 7 and TPDO1_COUNTED.mapping_index == 0x1A00
    assert TPDO1_COUNTED.decode(TPDO1_COUNTED.encode((0x1237, -5, 240))) == (0x1237, -5, 240)
    assert RPDO1.cob_id(5) == 0x205 and TPDO1.cob_id(5) == 0x185
    assert RPDO1.cob_id_entry(5) == 0x205 and TPDO1.cob_id_entry(5) == 0x4000_0185


def test_pdo_payloads_are_little_endian_in_map_order() -> None:
    assert RPDO1.encode(Setpoint(0x000F, -2)) == b"\x0f\x00\xfe\xff\xff\xff"
    assert TPDO1.encode(Feedback(0x1237, 1_250_000)) == b"\x37\x12" + (1_250_000).to_bytes(4, "little")
    assert TPDO1.decode(b"\x37\x12\xd0\x12\x13\x00") == Feedback(statusword=0x1237, position_actual=1_250_000)


@given(st.integers(0, 0xFFFF), st.integers(-(2**31), 2**31 - 1))
def test_pdo_round_trip(word: int, position: int) -> None:
    assert RPDO1.decode(RPDO1.encode(Setpoint(word, position))) == (word, position)
    assert TPDO1.decode(TPDO1.encode(Feedback(word, position))) == (word, position)


def test_pdo_errors_name_the_problem() -> None:
    with pytest.raises(PdoError, match="RPDO1 payload is 5 bytes, expected 6"):
        RPDO1.decode(b"\x00" * 5)
    with pytest.raises(PdoError, match="TPDO1 payload is 8 bytes, expected 6"):
        TPDO1.decode(b"\x00" * 8)
    with pytest.raises(PdoError, match=r"controlword must be an integer in 0\.\.65535, got 65536"):
        RPDO1.encode(Setpoint(0x10000, 0))
    with pytest.raises(PdoError, match=r"target_position must be an integer in -2147483648\.\.2147483647"):
        RPDO1.encode(Setpoint(0, 2**31))
    with pytest.raises(PdoError, match=r"target_position must be an integer .* got 1\.5"):
        RPDO1.encode(Setpoint(0, 1.5))
    with pytest.raises(PdoError, match="RPDO1 carries 2 values, got 1"):
        RPDO1.encode((1,))
    with pytest.raises(PdoError, match=r"node id must be an integer in 1\.\.127, got 0"):
        RPDO1.cob_id(0)


def test_configure_refuses_the_wrong_map() -> None:
    node = canopen.RemoteNode(NODE, load_od(NODE))
    with pytest.raises(PdoError, match="RPDO1 is mapped at 0x1600, not at this map's 0x1A00"):
        configure(node.tpdo[1], RPDO1, NODE)


# ----- unit scaling -------------------------------------------------------------------------------------------


def test_scaling_is_micrometres_from_the_minimum_length() -> None:
    s = SCALING
    assert s.position(1.6) == 0 and s.position(2.85) == 1_250_000 == s.stroke
    assert s.position(1.600001) == 1 and s.position(2.849999) == 1_249_999
    assert s.position(1.6 + 0.4e-6) == 0 and s.position(1.6 + 0.6e-6) == 1
    assert s.position(2.2) == 600_000 and s.length(600_000) == 2.2
    assert s.length(0) == 1.6 and s.length(1_250_000) == 2.85
    assert s.length(-5) == 1.599995  # an actual position may overshoot the range
    assert s.positions(np.array([1.6, 1.7, 1.8, 1.9, 2.0, 2.85])) == (0, 100_000, 200_000, 300_000, 400_000, 1_250_000)
    assert s.lengths([0, 1, 2]) == (1.6, 1.600001, 1.600002)


@given(st.integers(0, 1_250_000))
def test_scaling_round_trips_every_increment_exactly(position: int) -> None:
    length = SCALING.length(position)
    assert SCALING.position(length) == position
    assert length == float(f"{1.6 + position / 1e6:.6f}")


def test_scaling_refuses_lengths_outside_the_range() -> None:
    with pytest.raises(LegRangeError, match=r"leg length 2\.9 m is outside the leg's range \[1\.6, 2\.85\] m"):
        SCALING.position(2.9)
    with pytest.raises(LegRangeError, match=r"leg length 1\.5999999 m is outside the leg's range \[1\.6, 2\.85\] m"):
        SCALING.position(1.5999999)
    with pytest.raises(LegRangeError, match=r"leg 4 length 2\.850001 m is outside .*\[1\.6, 2\.85\] m"):
        SCALING.positions([2.0, 2.0, 2.0, 2.850001, 2.0, 2.0])
    with pytest.raises(LegRangeError, match="leg length must be a finite number, got nan"):
        SCALING.position(float("nan"))
    with pytest.raises(LegRangeError, match="position must be an INTEGER32, got 2147483648"):
        SCALING.length(2**31)
    with pytest.raises(LegRangeError, match=r"position must be an INTEGER32, got 1\.0"):
        SCALING.length(1.0)
    with pytest.raises(LegRangeError, match=r"0 < leg_min < leg_max, got \[2\.0, 1\.0\] m"):
        LegScaling(2.0, 1.0)
    with pytest.raises(LegRangeError, match="does not fit an INTEGER32"):
        LegScaling(1.0, 3000.0)


def test_scaling_of_the_table_models_leg_lengths() -> None:
    """Inverse kinematics of poses inside the workspace give positions inside the software limits."""
    model = TableModel()
    poses = np.array([[0, 0, 0, 0, 0, 0], [0.2, -0.1, 0.05, 0.02, 0.087, -0.03]])
    for lengths in model.leg_lengths(poses):
        positions = SCALING.positions(lengths)
        assert all(0 <= p <= SCALING.stroke for p in positions)
        assert np.allclose(SCALING.lengths(positions), lengths, rtol=0, atol=0.5e-6)


def test_velocity_scaling() -> None:
    assert velocity_increments(0.9) == 900_000 and velocity(900_000) == 0.9
    assert velocity_increments(-0.0000014) == -1 and velocity(-1) == -0.000001
    with pytest.raises(LegRangeError, match=r"velocity 3000\.0 m/s does not fit an INTEGER32 in µm/s"):
        velocity_increments(3000.0)
    with pytest.raises(LegRangeError, match="velocity must be a finite number, got inf"):
        velocity_increments(float("inf"))


# ----- CiA 402 state machine ----------------------------------------------------------------------------------

STANDARD_STATUS = [  # (mask, value) from the standard's table
    (0x4F, 0x00, State.NOT_READY_TO_SWITCH_ON),
    (0x4F, 0x40, State.SWITCH_ON_DISABLED),
    (0x6F, 0x21, State.READY_TO_SWITCH_ON),
    (0x6F, 0x23, State.SWITCHED_ON),
    (0x6F, 0x27, State.OPERATION_ENABLED),
    (0x6F, 0x07, State.QUICK_STOP_ACTIVE),
    (0x4F, 0x0F, State.FAULT_REACTION_ACTIVE),
    (0x4F, 0x08, State.FAULT),
]


@pytest.mark.parametrize(("word", "state"), [
    (0x0250, State.SWITCH_ON_DISABLED), (0x0231, State.READY_TO_SWITCH_ON), (0x0233, State.SWITCHED_ON),
    (0x1637, State.OPERATION_ENABLED), (0x0217, State.QUICK_STOP_ACTIVE), (0x021F, State.FAULT_REACTION_ACTIVE),
    (0x2238, State.FAULT), (0x0000, State.NOT_READY_TO_SWITCH_ON), (0x0060, State.SWITCH_ON_DISABLED),
])
def test_decode_statusword_examples(word: int, state: State) -> None:
    assert decode_statusword(word) is state


@given(st.sampled_from(STANDARD_STATUS), st.integers(0, 0xFFFF))
def test_decode_statusword_ignores_the_dont_care_bits(pattern, noise: int) -> None:
    mask, value, state = pattern
    assert decode_statusword(value | (noise & ~mask & 0xFFFF)) is state


@pytest.mark.parametrize("word", [0x0022, 0x0001, 0x0003, 0x0025])
def test_decode_statusword_refuses_undefined_words(word: int) -> None:
    with pytest.raises(ValueError, match=f"statusword 0x{word:04X} matches no CiA 402 state"):
        decode_statusword(word)


@pytest.mark.parametrize("state", list(State))
def test_statusword_round_trips_with_flags(state: State) -> None:
    flags = StatusBit.VOLTAGE_ENABLED | StatusBit.REMOTE | StatusBit.FOLLOWING_ERROR
    word = statusword(state, flags)
    assert decode_statusword(word) is state and word & flags == flags


def test_statusword_flags_must_not_touch_the_state_bits() -> None:
    with pytest.raises(ValueError, match="statusword flags 0x0020 overlap the state bits 0x006F"):
        statusword(State.FAULT, 0x20)
    with pytest.raises(ValueError, match="statusword must be an UNSIGNED16"):
        decode_statusword(0x10000)


def test_controlword_commands_are_the_standards_bit_patterns() -> None:
    assert controlword(Command.SHUTDOWN) == 0b0110
    assert controlword(Command.SWITCH_ON) == controlword(Command.DISABLE_OPERATION) == 0b0111
    assert controlword(Command.ENABLE_OPERATION) == 0b1111
    assert controlword(Command.DISABLE_VOLTAGE) == 0b0000
    assert controlword(Command.QUICK_STOP) == 0b0010
    assert controlword(Command.FAULT_RESET) == 0b1000_0000
    assert controlword(Command.ENABLE_OPERATION, halt=True) == 0x010F


@pytest.mark.parametrize(("word", "command"), [
    (0x0006, Command.SHUTDOWN), (0x000E, Command.SHUTDOWN), (0x0007, Command.SWITCH_ON), (0x000F,
     Command.ENABLE_OPERATION), (0x0000, Command.DISABLE_VOLTAGE), (0x000D, Command.DISABLE_VOLTAGE),
    (0x0002, Command.QUICK_STOP), (0x000B, Command.QUICK_STOP), (0x0080, Command.FAULT_RESET),
    (0x008F, Command.FAULT_RESET), (0x010F, Command.ENABLE_OPERATION), (0x0107, Command.SWITCH_ON),
])
def test_decode_controlword(word: int, command: Command) -> None:
    assert decode_controlword(word) is command


@pytest.mark.parametrize("start", [State.SWITCH_ON_DISABLED, State.FAULT, State.QUICK_STOP_ACTIVE,
                                   State.SWITCHED_ON, State.READY_TO_SWITCH_ON])
def test_commands_towards_operation_reach_it_through_the_device_transitions(start: State) -> None:
    state, previous, steps = start, 0, 0
    while (command := command_towards_operation(state)) is not None:
        word = controlword(command)
        state, previous, steps = transition(state, word, previous), word, steps + 1
        assert steps <= 5
    assert state is State.OPERATION_ENABLED


def test_transitions_of_the_standard() -> None:
    oe = State.OPERATION_ENABLED
    assert transition(oe, controlword(Command.QUICK_STOP)) is State.QUICK_STOP_ACTIVE  # 11
    assert transition(oe, controlword(Command.DISABLE_OPERATION)) is State.SWITCHED_ON  # 5
    assert transition(oe, controlword(Command.SHUTDOWN)) is State.READY_TO_SWITCH_ON  # 8
    assert transition(oe, controlword(Command.DISABLE_VOLTAGE)) is State.SWITCH_ON_DISABLED  # 9
    assert transition(State.READY_TO_SWITCH_ON, 0x0F) is oe  # 3 + 4
    assert transition(State.QUICK_STOP_ACTIVE, 0x0F) is oe  # 16
    assert transition(State.SWITCH_ON_DISABLED, 0x0F) is State.SWITCH_ON_DISABLED  # no transition
    assert transition(State.FAULT, 0x80, previous_word=0x00) is State.SWITCH_ON_DISABLED  # 15: rising edge
    assert transition(State.FAULT, 0x80, previous_word=0x80) is State.FAULT  # bit 7 held: no edge
    assert transition(State.FAULT, 0x0F) is State.FAULT
    assert transition(State.FAULT_REACTION_ACTIVE, 0x80) is State.FAULT_REACTION_ACTIVE
    assert command_towards_operation(oe) is None
    assert command_towards_operation(State.NOT_READY_TO_SWITCH_ON) is None


# ----- bus load -----------------------------------------------------------------------------------------------


def test_frame_bits_with_worst_case_stuffing() -> None:
    assert [frame_bits(n) for n in (0, 6, 8)] == [55, 115, 135]
    assert all(frame_bits(n) == 55 + 10 * n for n in range(0, 9, 4))  # Davis et al.: 55 + 10 n where exact
    assert cycle_bits(6) == 55 + 12 * 115 == 1435
    with pytest.raises(BusLoadError, match=r"0\.\.8 data bytes, got 9"):
        frame_bits(9)
    with pytest.raises(BusLoadError, match="axes must be a positive integer, got 0"):
        cycle_bits(0)


def test_one_kilohertz_of_six_axes_does_not_fit_one_megabit() -> None:
    assert bus_load(1000, 6, 1_000_000) == pytest.approx(1.435)
    with pytest.raises(BusLoadError) as info:
        check_bus_load(1000, 6, 1_000_000)
    message = str(info.value)
    for part in ("6 axes at 1000 Hz", "1435000 bit/s", "1435 bits per cycle", "SYNC 55", "RPDO1 115",
                 "TPDO1 115", "143.5% of 1000000 bit/s", "over the 80% limit", "557.5 Hz"):
        assert part in message
    with pytest.raises(BusLoadError):
        check_bus_load(1000, 6, 1_000_000, limit=1.0)


def test_five_hundred_hertz_fits_and_is_the_default() -> None:
    assert check_bus_load(DEFAULT_RATE_HZ, 6, 1_000_000) == pytest.approx(0.7175)
    assert check_bus_load(250, 6, 1_000_000) == pytest.approx(0.35875)
    assert max_rate_hz(6, 1_000_000) == pytest.approx(557.49, abs=0.01)
    assert max_rate_hz(6, 1_000_000, limit=1.0) < 1000
    assert DEFAULT_LIMIT == 0.8
    with pytest.raises(BusLoadError, match="6 axes at 500 Hz"):
        check_bus_load(500, 6, 500_000)  # 143.5 % of 500 kbit/s


def test_cycle_period() -> None:
    assert cycle_period_us(500) == 2000 and cycle_period_us(1000) == 1000 and cycle_period_us(400) == 2500
    with pytest.raises(BusLoadError, match=r"300 Hz has a period of 3333\.33 µs, not a whole number of µs"):
        cycle_period_us(300)
    with pytest.raises(BusLoadError, match="rate_hz must be a positive number, got 0"):
        cycle_period_us(0)


# ----- the real canopen stack on python-can's virtual bus ----------------------------------------------------


class Drive:
    """A LocalNode from the EDS that acts as the drive does on SYNC: latch the last RPDO1 into the object
    dictionary, step the CiA 402 state machine with its controlword, follow the target ideally, send TPDO1."""

    def __init__(self, network: canopen.Network) -> None:
        self.node = network.create_node(NODE, load_od(NODE))
        self.state = State.SWITCH_ON_DISABLED
        self.previous_word = 0
        self.errors: list[BaseException] = []
        self.rpdo_seen = threading.Event()
        network.subscribe(0x80, self.on_sync)

    def start_pdos(self) -> None:
        """Take the PDO configuration the master wrote by SDO (a LocalNode does not do it by itself)."""
        self.node.rpdo.read()
        self.node.tpdo.read()
        self.node.rpdo[1].add_callback(lambda _map: self.rpdo_seen.set())

    def value(self, index: int) -> int:
        return self.node.sdo[index].raw

    def on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        try:
            rx, tx = self.node.rpdo[1], self.node.tpdo[1]
            if self.node.nmt.state != "OPERATIONAL" or not rx.map or not tx.map:
                return
            if rx.timestamp is not None:
                for var in rx:
                    self.node.set_data(var.index, var.subindex, var.get_data())
            word = self.value(objects.CONTROLWORD)
            self.state, self.previous_word = transition(self.state, word, self.previous_word), word
            if self.state is State.OPERATION_ENABLED:
                self.node.sdo[objects.POSITION_ACTUAL_VALUE].raw = self.value(objects.TARGET_POSITION)
            self.node.sdo[objects.STATUSWORD].raw = statusword(self.state, StatusBit.VOLTAGE_ENABLED)
            for var in tx:
                var.set_data(self.node.get_data(var.index, var.subindex))
            tx.transmit()
        except Exception as exc:  # the network's listener would only log it
            self.errors.append(exc)


@pytest.fixture
def bus_pair() -> Iterator[tuple[canopen.Network, canopen.Network]]:
    """Two canopen networks, each on its own python-can virtual Bus of one fresh channel."""
    channel = f"coz-{uuid.uuid4().hex}"
    networks = [canopen.Network(can.Bus(interface="virtual", channel=channel)) for _ in range(2)]
    for network in networks:
        network.NOTIFIER_CYCLE = 0.05  # disconnect() waits up to one cycle (1 s by default) per network
        network.connect()
    yield networks[0], networks[1]
    for network in networks:
        network.disconnect()


def wait_for(predicate, what: str) -> None:
    done = threading.Event()
    for _ in range(int(WAIT / 0.01)):
        if predicate():
            return
        done.wait(0.01)
    raise AssertionError(f"timed out waiting for {what}")


def test_sdo_read_write_between_master_and_drive(bus_pair) -> None:
    drive_net, master_net = bus_pair
    drive = Drive(drive_net)
    master = master_net.add_node(NODE, load_od(NODE))
    assert master.sdo[objects.DEVICE_TYPE].raw == objects.DEVICE_TYPE_CIA402_SERVO
    assert master.sdo[objects.SOFTWARE_POSITION_LIMIT][2].raw == SCALING.stroke
    master.sdo[objects.MODES_OF_OPERATION].raw = objects.MODE_CYCLIC_SYNCHRONOUS_POSITION
    target = SCALING.position(2.123456)
    master.sdo[objects.TARGET_POSITION].raw = target
    assert master.sdo[objects.MODES_OF_OPERATION].raw == 8
    assert master.sdo[objects.TARGET_POSITION].raw == target == 523_456
    assert drive.node.data_store[objects.TARGET_POSITION][0] == target.to_bytes(4, "little", signed=True)
    with pytest.raises(canopen.SdoAbortedError, match="read only"):
        master.sdo[objects.STATUSWORD].raw = 0
    with pytest.raises(canopen.SdoAbortedError):
        master.sdo.upload(0x2000, 0)  # not in the dictionary


def test_pdo_configuration_and_sync_cycle(bus_pair) -> None:
    """The master maps RPDO1/TPDO1 by SDO, starts the node, enables the drive through the CiA 402 states over
    SYNC-driven PDOs and sets a leg length; the drive acts on the RPDO only at SYNC."""
    drive_net, master_net = bus_pair
    drive = Drive(drive_net)
    master = master_net.add_node(NODE, load_od(NODE))
    for pdo_map, spec in ((master.rpdo[1], RPDO1), (master.tpdo[1], TPDO1)):
        configure(pdo_map, spec, NODE)
        pdo_map.save()
    store = drive.node.data_store
    for spec in PDO_MAPS:  # written by SDO: present in the drive's store, not only EDS defaults
        assert store[spec.communication_index][1] == spec.cob_id_entry(NODE).to_bytes(4, "little")
        assert [int.from_bytes(store[spec.mapping_index][k + 1], "little") for k in range(len(spec.objects))] \
            == [o.mapping_entry for o in spec.objects]
    drive.start_pdos()
    master.nmt.state = "OPERATIONAL"
    wait_for(lambda: drive.node.nmt.state == "OPERATIONAL", "the drive to enter OPERATIONAL")

    feedback: queue.Queue[Feedback] = queue.Queue()
    master.tpdo[1].add_callback(lambda pdo_map: feedback.put(TPDO1.decode(bytes(pdo_map.data))))
    rpdo = master.rpdo[1]

    latched = [Setpoint(0, 0)]

    def cycle(word: int, target: int) -> Feedback:
        rpdo["Controlword"].raw = word
        rpdo["Target position"].raw = target
        assert bytes(rpdo.data) == RPDO1.encode(Setpoint(word, target))
        drive.rpdo_seen.clear()
        rpdo.transmit()
        assert drive.rpdo_seen.wait(WAIT)
        held = Setpoint(drive.value(objects.CONTROLWORD), drive.value(objects.TARGET_POSITION))
        assert held == latched[-1]  # received, but not acted on before SYNC
        master_net.sync.transmit()
        latched.append(Setpoint(word, target))
        return feedback.get(timeout=WAIT)

    state, steps = State.SWITCH_ON_DISABLED, 0
    while (command := command_towards_operation(state)) is not None:
        state, steps = decode_statusword(cycle(controlword(command), 0).statusword), steps + 1
        assert steps <= 3
    assert state is State.OPERATION_ENABLED and steps == 3

    target = SCALING.position(2.5)
    result = cycle(controlword(Command.ENABLE_OPERATION), target)
    assert result == Feedback(statusword(State.OPERATION_ENABLED, StatusBit.VOLTAGE_ENABLED), 900_000)
    assert SCALING.length(result.position_actual) == 2.5
    assert drive.value(objects.TARGET_POSITION) == target
    assert drive.errors == []


def test_heartbeat_producer_and_consumer(bus_pair) -> None:
    drive_net, master_net = bus_pair
    drive = Drive(drive_net)
    master = master_net.add_node(NODE, load_od(NODE))
    master.nmt.state = "OPERATIONAL"
    wait_for(lambda: drive.node.nmt.state == "OPERATIONAL", "the drive to enter OPERATIONAL")
    master.sdo[objects.PRODUCER_HEARTBEAT_TIME].raw = 10  # [ms]: the drive starts producing
    assert master.nmt.wait_for_heartbeat(timeout=WAIT) == "OPERATIONAL"
    assert master.nmt.timestamp is not None  # the master checks the heartbeat's age against it

    master.sdo[objects.CONSUMER_HEARTBEAT_TIME][1].raw = heartbeat_consumer_entry(MASTER_NODE_ID, 100)
    producer_id, _ = decode_heartbeat_consumer_entry(drive.node.sdo[objects.CONSUMER_HEARTBEAT_TIME][1].raw)
    beats: queue.Queue[int] = queue.Queue()
    drive_net.subscribe(0x700 + producer_id, lambda can_id, data, ts: beats.put(data[0]))
    task = master_net.send_periodic(0x700 + MASTER_NODE_ID, [0x05], 0.01)
    try:
        assert beats.get(timeout=WAIT) == 0x05
    finally:
        task.stop()
    master.sdo[objects.PRODUCER_HEARTBEAT_TIME].raw = 0
    drive.node.nmt.stop_heartbeat()


def test_emcy_from_the_drive_reaches_the_masters_consumer(bus_pair) -> None:
    drive_net, master_net = bus_pair
    drive = Drive(drive_net)
    master = master_net.add_node(NODE, load_od(NODE))
    assert drive.node.emcy.cob_id == load_od(NODE)[objects.COB_ID_EMCY].default
    received: queue.Queue = queue.Queue()
    master.emcy.add_callback(received.put)
    register = objects.ERROR_REGISTER_GENERIC | objects.ERROR_REGISTER_DEVICE_PROFILE
    drive.node.emcy.send(objects.EMCY_FOLLOWING_ERROR, register, b"\x01\x02")
    error = received.get(timeout=WAIT)
    assert (error.code, error.register, error.data) == (0x8611, 0x21, b"\x01\x02\x00\x00\x00")
    assert error.get_desc() == "Monitoring"
    assert master.emcy.active == [error]
    drive.node.emcy.reset()
    assert received.get(timeout=WAIT).code == 0
    assert master.emcy.active == []


# ----- udp_multicast across two processes, inside a network namespace -------------------------------------------

_NETNS_SETUP = "ip link set lo up && ip route add 224.0.0.0/4 dev lo"

_DRIVE = """
import canopen, sys, threading
net = canopen.Network()
net.connect(interface="udp_multicast", channel="239.74.163.2")
node = net.create_node({node}, canopen.import_od({eds!r}, {node}))
node.nmt.state = "PRE-OPERATIONAL"
node.sdo[0x1017].raw = 20  # heartbeats from now on, each saying PRE-OPERATIONAL
stopped = threading.Event()
for _ in range(1000):
    if node.nmt.state == "STOPPED" or stopped.wait(0.01):
        break
net.disconnect()
sys.exit(0 if node.nmt.state == "STOPPED" else 1)
"""

_MASTER = """
import canopen, json
net = canopen.Network()
net.connect(interface="udp_multicast", channel="239.74.163.2")
node = net.add_node({node}, canopen.import_od({eds!r}, {node}))
state = node.nmt.wait_for_heartbeat(timeout=10)
node.sdo[0x6060].raw = 8
result = {{"heartbeat": state, "device_type": node.sdo[0x1000].raw, "mode": node.sdo[0x6060].raw}}
node.nmt.state = "STOPPED"
net.disconnect()
print(json.dumps(result))
"""


def _can_unshare() -> bool:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    probe = subprocess.run(["unshare", "--net", "sh", "-c", _NETNS_SETUP], capture_output=True, timeout=30)
    return probe.returncode == 0


@pytest.mark.integration
def test_udp_multicast_between_processes_in_a_network_namespace() -> None:
    """Drive and master in two processes on python-can's udp_multicast, in a network namespace of their own
    (loopback only; it vanishes with them). Without one, the multicast group is routed through the default
    interface, off the host — so the test does not run outside a namespace."""
    if not _can_unshare():
        pytest.skip("cannot create a network namespace here (needs unshare and CAP_SYS_ADMIN)")
    drive, master = (shlex.join([sys.executable, "-c", textwrap.dedent(code.format(node=NODE, eds=str(EDS_PATH)))])
                     for code in (_DRIVE, _MASTER))
    script = f"{_NETNS_SETUP} && {{ {drive} & }} && {master} && wait $!"
    done = subprocess.run(["unshare", "--net", "sh", "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {"heartbeat": "PRE-OPERATIONAL", "device_type": 0x00020192, "mode": 8}


# ----- the receive buffer of a datagram bus -------------------------------------------------------------------------


class _SocketBus(can.BusABC):
    """A bus whose file descriptor is a real UDP socket on loopback (as python-can's udp_multicast's is)."""

    def __init__(self, sock: socket.socket) -> None:
        super().__init__(channel="loopback")
        self.sock = sock

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise NotImplementedError

    def _recv_internal(self, timeout: float | None) -> tuple[None, bool]:
        return None, False

    def fileno(self) -> int:
        return self.sock.fileno()


@pytest.mark.integration  # a UDP socket on loopback
def test_the_receive_buffer_of_a_datagram_bus_is_widened_and_a_queue_is_left_alone() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        bus = _SocketBus(sock)
        size, rmem_max = 1 << 20, int(Path("/proc/sys/net/core/rmem_max").read_text())
        granted = widen_receive_buffer(bus, size)
        assert granted == sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)  # the bus's own socket
        # the kernel doubles what it grants: all of it where forcing is permitted (CAP_NET_ADMIN), else to rmem_max
        assert granted in (2 * size, 2 * min(size, rmem_max))
        assert sock.fileno() >= 0  # and it stays open
        bus.shutdown()
    virtual = can.Bus(interface="virtual", channel=f"queue-{os.getpid()}")
    try:
        assert widen_receive_buffer(virtual) == 0
    finally:
        virtual.shutdown()
