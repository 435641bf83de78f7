"""The direct frame writer (``protocols.mavlink.encode``) against pymavlink's own ``pack()``: the same bytes for
the same message, sequence number, ids, link id and signing timestamp, signed and not; and decoded by pymavlink."""

from __future__ import annotations

import numpy as np
import pytest

from protocols.mavlink import accel_batches, dialect, enable_signing, tilt_batches, unpack_accel_batch
from protocols.mavlink.encode import FrameWriter

KEY = bytes(range(32))


def _mav(system: int, component: int, *, signed: bool, link_id: int = 0, timestamp: int = 0) -> object:
    mav = dialect().MAVLink(None, srcSystem=system, srcComponent=component)
    if signed:
        enable_signing(mav, KEY, link_id=link_id, timestamp=timestamp)
    return mav


def _pair(seq: int, *, signed: bool, link_id: int = 0, timestamp: int = 0) -> tuple[object, object]:
    """Two identical links: one packs with pymavlink, the other writes frames."""
    ours, theirs = (_mav(7, 3, signed=signed, link_id=link_id, timestamp=timestamp) for _ in range(2))
    ours.seq = theirs.seq = seq  # type: ignore[attr-defined]  # pymavlink's MAVLink is untyped
    return ours, theirs


CASES = [  # (sequence number, signed, link id, timestamp)
    (0, False, 0, 0),
    (255, False, 0, 0),
    (0, True, 0, 0),
    (17, True, 1, 2**48 - 2),
    (254, True, 255, 123_456_789_012),
]


@pytest.mark.parametrize(("seq", "signed", "link_id", "stamp"), CASES)
@pytest.mark.parametrize("n", [1, 7, 19])
def test_accel_batch_frames_are_pymavlinks(seq: int, signed: bool, link_id: int, stamp: int, n: int) -> None:
    rng = np.random.default_rng(seq + n)
    samples = rng.normal(0.0, 9.81, (n, 3))
    samples[-1, -1] = 0.0  # trailing zeros of a partial batch's last sample are cut too
    ours, theirs = _pair(seq, signed=signed, link_id=link_id, timestamp=stamp)
    for batch_seq, t0 in ((0, 0), (2**32 - 1, 2**64 - 2**40), (4242, 1_234_567_890_123)):
        (message,) = accel_batches(samples, 2, t0, 1_000_000, batch_seq)
        expected = message.pack(theirs)
        written = FrameWriter(ours).accel_batch(samples, 2, t0, 1_000_000, batch_seq)
        assert written == expected
        if signed:
            assert ours.signing.timestamp == theirs.signing.timestamp  # type: ignore[attr-defined]  # untyped
        (decoded,) = _mav(1, 1, signed=signed).parse_buffer(written)  # type: ignore[attr-defined]  # untyped
        series = unpack_accel_batch(decoded)
        assert np.array_equal(series.samples, samples.astype(np.float32).astype(np.float64))
        assert decoded.get_signed() is signed


@pytest.mark.parametrize(("seq", "signed", "link_id", "stamp"), CASES)
@pytest.mark.parametrize("n", [1, 30, 59])
def test_tilt_batch_frames_are_pymavlinks(seq: int, signed: bool, link_id: int, stamp: int, n: int) -> None:
    angles = np.linspace(-0.3, 0.5, n)
    ours, theirs = _pair(seq, signed=signed, link_id=link_id, timestamp=stamp)
    for body_id in (0, 6, 65535):
        (message,) = tilt_batches(angles, body_id, 10_000_000, 10_000_000, 9)
        assert FrameWriter(ours).tilt_batch(angles, body_id, 10_000_000, 10_000_000, 9) == message.pack(theirs)


def test_a_payload_of_zeros_keeps_one_byte() -> None:
    d = dialect()
    for signed in (False, True):
        ours, theirs = _pair(3, signed=signed, timestamp=99)
        message = d.MAVLink_shaketable_body_message(0, 0, 0.0, 0.0, 0.0, 0.0, 0.0)
        payload = message.unpacker.pack(0.0, 0.0, 0.0, 0.0, 0.0, 0, 0)
        assert FrameWriter(ours).frame(message.id, message.crc_extra, payload) == message.pack(theirs)


def test_samples_not_finite_in_float32_are_refused() -> None:
    writer = FrameWriter(_mav(1, 1, signed=True))
    for bad in (np.nan, np.inf, 1e39):
        samples = np.zeros((3, 3))
        samples[1, 2] = bad
        with pytest.raises(ValueError, match="finite"):
            writer.accel_batch(samples, 0, 0, 1, 0)
    with pytest.raises(ValueError, match="fit"):
        writer.tilt_batch(np.zeros(60), 0, 0, 1, 0)


@pytest.mark.parametrize(("seq", "signed", "link_id", "stamp"), CASES)
def test_status_frames_are_pymavlinks(seq: int, signed: bool, link_id: int, stamp: int) -> None:
    d = dialect()
    pose = [0.0123456789, -0.25, 1e-9, 0.0, -3.0e-3, 0.5]
    for fields in ((1_234_567_890_123_456, d.SHAKETABLE_STATE_STREAMING, 65535, 2**32 - 1, 7, 0x1234, 3, pose, 4096,
                    2**32 - 1, 1000, 0b101, [1e-4, -2e-5, 0.0, 3e-6, 0.0, 0.0]),
                   (0, d.SHAKETABLE_STATE_IDLE, 0, 0, 0, 0, 0, [0.0] * 6, 0, 0, 0, 0, [0.0] * 6)):
        ours, theirs = _pair(seq, signed=signed, link_id=link_id, timestamp=stamp)
        expected = d.MAVLink_shaketable_status_message(*fields).pack(theirs)
        assert FrameWriter(ours).status(*fields) == expected
