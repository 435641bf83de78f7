"""Open MAVLink 2 links that speak the project's dialect: a plain UDP endpoint, or pymavlink's ``mavutil``.

:class:`UdpLink` is the small one: one UDP socket, one dialect ``MAVLink`` object (framing, sequence numbers,
signing), every message of every datagram returned at once. Use it for the setpoint stream and telemetry.

:func:`mavlink_connection` is pymavlink's ``mavutil.mavlink_connection`` with this dialect, for code that wants
mavutil's conveniences (``recv_match``, heartbeat bookkeeping). mavutil keeps its dialect in a module global and
picks the MAVLink 2 module only when the environment variable ``MAVLINK20`` is set, so this function sets
``MAVLINK20=1`` and switches mavutil's global dialect to ``shaketable`` for the whole process.
"""

from __future__ import annotations

import os
import socket
from typing import Any

from protocols.mavlink.codegen import DIALECT_NAME, dialect
from protocols.mavlink.signing import SIGNED_FRAME, enable_signing

Address = tuple[str, int]

MAX_DATAGRAM = 65535
"""Largest UDP datagram read at once [bytes]."""

MAGIC_V2 = 0xFD
"""First byte of a MAVLink 2 frame."""

_FRAME_OVERHEAD = 12  # header 10 + checksum 2 [bytes]
_SIGNATURE_BYTES = 13  # link id 1 + timestamp 6 + signature 6


def whole_frames(data: bytes) -> list[bytes] | None:
    """The MAVLink 2 frames a datagram is made of, or None when it is not a whole number of them (junk: dropped
    before any parsing, in time proportional to the number of frames, not of bytes). The checksum and the signature
    are pymavlink's to check."""
    frames = []
    start, size = 0, len(data)
    while start < size:
        if size - start < _FRAME_OVERHEAD or data[start] != MAGIC_V2:
            return None
        end = start + _FRAME_OVERHEAD + data[start + 1] + (_SIGNATURE_BYTES if data[start + 2] & SIGNED_FRAME else 0)
        if end > size:
            return None
        frames.append(data[start:end])
        start = end
    return frames or None


class UdpLink:
    """A MAVLink 2 endpoint of the dialect on one UDP socket.

    ``peer`` is where :meth:`send` goes; when None, it becomes the source of the first datagram received (a
    controller answers whichever host spoke to it). ``mav`` is the dialect ``MAVLink`` object: use its
    ``*_encode`` / ``*_send`` methods, and :func:`protocols.mavlink.signing.enable_signing` on it.
    """

    def __init__(self, sock: socket.socket, peer: Address | None = None, *, source_system: int,
                 source_component: int) -> None:
        self.sock = sock
        self.peer = peer
        self.mav = dialect().MAVLink(self, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True  # garbage becomes BAD_DATA (dropped, counted) instead of an exception
        self.junk = 0
        """Datagrams dropped unread by :meth:`receive`: not a whole number of MAVLink 2 frames."""

    @classmethod
    def open(cls, local: Address = ("127.0.0.1", 0), peer: Address | None = None, *, source_system: int,
             source_component: int, key: bytes | None = None, link_id: int = 0,
             receive_buffer: int | None = None) -> UdpLink:
        """Bind a new UDP socket to ``local`` (port 0: any free port) and wrap it; sign with ``key`` if given
        (``link_id`` as in :func:`~protocols.mavlink.signing.enable_signing`). ``receive_buffer`` [bytes] enlarges
        the socket's receive buffer (streams must be drained continuously or datagrams are lost)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if receive_buffer is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
            sock.bind(local)
            link = cls(sock, peer, source_system=source_system, source_component=source_component)
            if key is not None:
                enable_signing(link.mav, key, link_id=link_id)
        except BaseException:
            sock.close()
            raise
        return link

    @property
    def local_address(self) -> Address:
        """The (host, port) the socket is bound to."""
        host, port = self.sock.getsockname()[:2]
        return host, port

    def write(self, buf: bytes) -> None:
        """Send one framed message as one datagram (called by ``mav.send``)."""
        if self.peer is None:
            raise ConnectionError("no peer to send to yet: give one, or receive from it first")
        self.sock.sendto(buf, self.peer)

    def send(self, msg: Any) -> None:
        """Frame (sequence number, source ids, signature) and send one dialect message."""
        self.mav.send(msg)

    def receive(self, timeout: float | None = 0.0) -> list[Any]:
        """The messages of the next datagram, waiting up to ``timeout`` [s] (None: forever); [] if none came.

        A datagram that is not a whole number of MAVLink 2 frames is dropped unread (counted in ``junk``);
        undecodable frames are dropped (``mav.total_receive_errors`` counts them); unsigned or badly signed
        messages on a signing link are returned, flagged (see :mod:`protocols.mavlink.signing`).
        """
        self.sock.settimeout(timeout)
        try:
            data, source = self.sock.recvfrom(MAX_DATAGRAM)
        except (BlockingIOError, TimeoutError):
            return []
        if whole_frames(data) is None:
            self.junk += 1
            return []
        if self.peer is None:
            self.peer = source
        return [m for m in self.mav.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> UdpLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def mavlink_connection(device: str, *, source_system: int = 255, source_component: int = 0,
                       key: bytes | None = None, link_id: int = 0, **kwargs: Any) -> Any:
    """``pymavlink.mavutil.mavlink_connection(device, ...)`` speaking the dialect in MAVLink 2, signing with
    ``key`` if given (``link_id`` as in :func:`~protocols.mavlink.signing.enable_signing`).

    ``device`` is mavutil's: ``udpin:HOST:PORT`` (listen, answer the last sender), ``udpout:HOST:PORT``,
    ``tcp:HOST:PORT``, a serial port, ... ``kwargs`` go to mavutil unchanged. Side effects: ``MAVLINK20=1`` in
    ``os.environ`` and mavutil's process-wide dialect set to ``shaketable``.
    """
    dialect()  # generates and registers pymavlink.dialects.v20.shaketable
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(device, source_system=source_system, source_component=source_component,
                                      dialect=DIALECT_NAME, **kwargs)
    if key is not None:
        enable_signing(conn.mav, key, link_id=link_id)
    return conn
