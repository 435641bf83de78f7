"""The emulator's command line, apart from its models: ``python -m sim_table --help`` answers without loading
MuJoCo, numba or the transports (what ``rig emulate --help`` shows)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from protocols.signing_key import KEY_ENV

DYNAMICS = ("lag", "servo")
"""The emulator's leg models: ``lag`` (first-order lag, :mod:`sim_table.actuators`) and ``servo``
(:mod:`sim_table.dynamics`)."""


def _speed(text: str) -> float:
    """``--speed``: a factor > 0, or ``max`` (virtual time: math.inf)."""
    if text.strip().lower() == "max":
        return math.inf
    try:
        speed = float(text)
    except ValueError:
        speed = math.nan
    if not (math.isfinite(speed) and speed > 0):
        raise argparse.ArgumentTypeError(f"expected a factor > 0 or max, got {text!r}")
    return speed


def _point(text: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    return x, y, z


def _leg_stall(text: str) -> tuple[int, float]:
    leg, _, at = text.partition("@")
    try:
        stall = int(leg), float(at)
    except ValueError:
        stall = (0, math.nan)
    if not (1 <= stall[0] <= 6 and math.isfinite(stall[1]) and stall[1] >= 0):
        raise argparse.ArgumentTypeError(f"expected LEG@S, a leg 1..6 and seconds >= 0, got {text!r}")
    return stall


def _door(text: str) -> tuple[float, float]:
    opens, _, lasts = text.partition(":")
    try:
        door = float(opens), float(lasts)
    except ValueError:
        door = (math.nan, math.nan)
    if not (math.isfinite(door[0]) and door[0] >= 0 and math.isfinite(door[1]) and door[1] > 0):
        raise argparse.ArgumentTypeError(f"expected S:D, seconds >= 0 and a duration > 0 s, got {text!r}")
    return door


def _accel_noisy(text: str) -> tuple[int, float, float]:
    sensor, _, span = text.partition("@")
    opens, _, lasts = span.partition(":")
    try:
        noisy = int(sensor), float(opens), float(lasts)
    except ValueError:
        noisy = (-1, math.nan, math.nan)
    if not (0 <= noisy[0] <= 255 and math.isfinite(noisy[1]) and noisy[1] >= 0 and math.isfinite(noisy[2])
            and noisy[2] > 0):
        raise argparse.ArgumentTypeError(f"expected ID@S:D, an accelerometer id 0..255, seconds >= 0 and a duration "
                                         f"> 0 s, got {text!r}")
    return noisy


def argument_parser() -> argparse.ArgumentParser:
    """The emulator's command line (``python -m sim_table --help``)."""
    p = argparse.ArgumentParser(prog="python -m sim_table", formatter_class=argparse.ArgumentDefaultsHelpFormatter,
                                description="The emulated shake-table controller (docs/table-controller.md): "
                                            "runs until SIGINT/SIGTERM, then prints its counters as JSON.")
    p.add_argument("--listen", required=True, metavar="URL",
                   help="the transport and address to listen on: mavlink://HOST:PORT, zenoh://HOST:PORT/TABLE "
                        "(port 0: any free port) or canopen://CHANNEL?interface=…")
    p.add_argument("--speed", type=_speed, default=1.0, metavar="FACTOR|max",
                   help="controller time per real time, or max: virtual time, as fast as the emulator computes "
                        "while the host's setpoints allow (docs/table-controller.md)")
    p.add_argument("--body", action="append", default=[], metavar="BxH@X,Y[;depth=D][;mass=M][;mu=F][;restitution=E]",
                   help="a specimen b x h [m] at plate (x, y) [m], optionally its depth [m], mass [kg], "
                        "friction coefficient and measured restitution (its impacts reproduce it; default: the "
                        "contact's own, Housner's); repeat for more (body ids 0, 1, … in this order)")
    p.add_argument("--accel", action="append", type=_point, metavar="X,Y,Z",
                   help="an accelerometer at plate (x, y, z) [m], with the plate's axes; repeat for more (default: "
                        "where the rig configuration's [sensors] sheets put them, with their axes; without sheets "
                        "one at the centre)")
    p.add_argument("--loss", type=float, default=0.0, metavar="PCT", help="drop this %% of datagrams, both ways")
    p.add_argument("--delay", type=float, default=0.0, metavar="MS", help="delay every datagram, both ways")
    p.add_argument("--drive-fault-at", type=float, metavar="S", help="drive fault S s after the first stream start")
    p.add_argument("--stall-at", type=float, metavar="S", help="drop all chunks from S s after the first stream start")
    p.add_argument("--door-open", type=_door, metavar="S:D",
                   help="the enclosure door (an interlock input in every status) opens S s after the first stream "
                        "start and closes D s later")
    p.add_argument("--accel-noisy", type=_accel_noisy, metavar="ID@S:D",
                   help="accelerometer ID turns noisy (σ 0.5 m/s² more on every axis: a loose mount, a bad cable) S s "
                        "after the first stream start, for D s")
    p.add_argument("--leg-stall", type=_leg_stall, metavar="LEG@S",
                   help="leg LEG's actuator (1..6) seizes S s after the first stream start: it brakes to rest and "
                        "stops following its command (CANopen: its drive's following-error supervision trips)")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="seed of every random number (noise, loss)")
    p.add_argument("--watchdog", type=float, metavar="S",
                   help="host-heartbeat and setpoint watchdogs [s, controller time] (default: the rig "
                        "configuration's [controller] watchdog_s, 1 s; virtual time uses 1 s of host time)")
    p.add_argument("--buffer", type=float, metavar="S",
                   help="setpoint buffer capacity [s of samples] (default: the rig configuration's [controller] "
                        "buffer_s, 4 s)")
    p.add_argument("--exit-with-parent", action="store_true",
                   help="stop (as on SIGINT) when the process that started this one exits, even by kill -9: "
                        "no emulator is left holding its port")
    p.add_argument("--key-file", type=Path, metavar="FILE",
                   help=f"signing key file (default: ${KEY_ENV}); mavlink and zenoh only: canopen does not sign")
    p.add_argument("--tls-ca", type=Path, metavar="FILE",
                   help="zenoh: the lab's CA certificate; with --tls-cert and --tls-key the link is tls/HOST:PORT with "
                        "mutual authentication (rig certs make; docs/lab-network.md)")
    p.add_argument("--tls-cert", type=Path, metavar="FILE", help="zenoh: this controller's certificate (signed by the "
                                                                  "CA, naming the address it listens on)")
    p.add_argument("--tls-key", type=Path, metavar="FILE", help="zenoh: the private key of --tls-cert (mode 0600)")
    p.add_argument("--insecure-plain-tcp", action="store_true",
                   help="zenoh: allow a plain tcp/ link off loopback (nothing encrypted; a bench network only)")
    p.add_argument("--replay-state", type=Path, metavar="FILE",
                   help="where the signatures' last stamps are kept across restarts, written crash-safe (default: "
                        "beside --key-file, KEYFILE.<transport>-replay.json; required with the key from "
                        f"${KEY_ENV}); mavlink and zenoh only")
    p.add_argument("--rig-config", type=Path, metavar="FILE",
                   help="rig configuration TOML (default: Table IV, default hexapod); its [network] gives a zenoh "
                        "link's TLS identity when --tls-ca/--tls-cert/--tls-key are not given")
    p.add_argument("--leg-noise", type=float, metavar="M",
                   help="σ of a leg-length reading [m] (default: sim_table.actuators.ActuatorSettings's, 1 µm)")
    p.add_argument("--dynamics", choices=DYNAMICS, default="lag",
                   help="the legs' model: lag (first-order lag) or servo (servo-valve, oil column and displacement "
                        "loop from the rig configuration's [dynamics], docs/table-dynamics.md)")
    p.add_argument("--accel-noise", type=float, default=0.02, metavar="M/S2", help="σ of accelerometer noise")
    p.add_argument("--counters", type=Path, metavar="FILE", help="write the exit counters here, not to stdout")
    return p


def describe() -> dict[str, object]:
    """The command line as plain data (``python -m sim_table --help-json``): the description and each option's
    flags, metavar, help, default, whether it is required, repeatable or a switch, and its choices — what
    ``rig emulate --help`` shows in the style of the other ``rig`` commands (``rig`` does not import sim_table)."""
    parser = argument_parser()
    options = []
    for action in parser._actions:  # argparse keeps no public list of its actions
        if isinstance(action, argparse._HelpAction):
            continue
        default = action.default
        options.append({
            "flags": list(action.option_strings), "metavar": action.metavar, "help": action.help,
            "default": default if isinstance(default, str | int | float | bool) and default != [] else None,
            "required": action.required, "repeat": isinstance(action, argparse._AppendAction),
            "switch": action.nargs == 0, "choices": list(action.choices) if action.choices else None,
            "dest": action.dest})
    return {"description": parser.description, "options": options}
