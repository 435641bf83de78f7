"""The receive buffer of a bus that is a datagram socket (python-can's ``udp_multicast``): deep enough that a
process left unscheduled for a while loses no frame.

A CAN interface queues received frames in its driver; python-can's ``udp_multicast`` leaves them in the socket's
receive buffer, by default ``net.core.rmem_default`` (208 KiB on Linux). Each frame is a datagram that takes about
1 KiB of it (the kernel counts the buffer it allocates, not the payload), every process also receives what it sends
(multicast loops back), and a 100 Hz cycle of six drives and an accelerometer carries about 30 datagrams a cycle both
ways: 208 KiB last about 70 ms. Measured beside two busy processes and an fsync writer on 2 cores: the emulator read
SYNCs up to 0.45 s after the kernel stamped them, and both ends lost frames (the master 36–106 accelerometer samples
of about 400 in a 4 s stream; the drives' targets with them). :data:`RECEIVE_BUFFER_BYTES` holds over a second of
that traffic.

A deep buffer lets the receive thread fall behind; :class:`ReceiveBacklog` tells another thread of the same
process whether it has (frames the kernel or the virtual bus still holds, or one being handled), so that thread
can wait for it instead of judging the bus by what the receive thread has not read yet.
"""

from __future__ import annotations

import select
import socket
import time

import can
from can.interfaces.virtual import VirtualBus

BACKLOG_POLL_S = 0.0002
"""How long :meth:`ReceiveBacklog.wait` sleeps between two looks [s] (the sleep lets the receive thread run)."""

SO_RCVBUFFORCE = 33
"""Linux's socket option (asm-generic/socket.h) that sets a receive buffer beyond ``net.core.rmem_max``; Python's
socket module does not name it."""

RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024
"""The receive buffer asked for a datagram bus [bytes] (the kernel doubles what it grants for its bookkeeping)."""


def widen_receive_buffer(bus: can.BusABC, size: int = RECEIVE_BUFFER_BYTES) -> int:
    """Ask for a receive buffer of ``size`` bytes on ``bus``'s socket: beyond ``net.core.rmem_max`` where the process
    may (``SO_RCVBUFFORCE``, CAP_NET_ADMIN), else up to it (``SO_RCVBUF``). The buffer granted [bytes, as the kernel
    reports it], or 0 for a bus that is not a socket (python-can's ``virtual``: a queue in the process)."""
    try:
        fd = bus.fileno()
    except NotImplementedError:
        return 0
    if fd < 0:
        return 0
    sock = socket.socket(fileno=socket.dup(fd))  # the same socket, through a descriptor of our own
    try:
        if sock.type != socket.SOCK_DGRAM:
            return 0
        try:
            sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, size)
        except OSError:  # not permitted, or not Linux
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
        return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    finally:
        sock.close()


class ReceiveBacklog(can.Listener):
    """The listener a notifier's receive thread calls for every frame of ``bus``: it hands the frame to ``inner``
    (canopen's ``MessageListener``) and knows whether that thread is behind — frames wait in the socket's receive
    buffer (or the virtual bus's queue), or one is being handled.

    Measured beside six busy processes and an fsync writer on 2 cores (the CANopen two-process test): the
    emulator's receive thread handled a SYNC 1.24 s after the kernel stamped it while the same process's tick
    thread, never more than 0.17 s late, found no master heartbeat for 1 s and stopped the table
    (HEARTBEAT_LOST), with the heartbeats unread in the socket. :meth:`wait` lets the tick thread wait for them."""

    def __init__(self, bus: can.BusABC, inner: can.Listener) -> None:
        self._inner = inner
        self._handling = False
        self._queue = bus.queue if isinstance(bus, VirtualBus) else None
        self._poll: select.poll | None = None
        try:
            fd = bus.fileno()
        except NotImplementedError:
            fd = -1
        if fd >= 0 and self._queue is None:
            self._poll = select.poll()
            self._poll.register(fd, select.POLLIN)

    def on_message_received(self, msg: can.Message) -> None:
        self._handling = True
        try:
            self._inner.on_message_received(msg)
        finally:
            self._handling = False

    def stop(self) -> None:
        self._inner.stop()

    def pending(self) -> bool:
        """Whether a frame received is not handled yet (unread, or being handled)."""
        if self._handling:
            return True
        if self._queue is not None:
            return not self._queue.empty()
        return self._poll is not None and bool(self._poll.poll(0))

    def wait(self, limit: float) -> tuple[float, bool]:
        """Wait until every frame received so far is handled, at most ``limit`` [s]: (seconds waited — 0 when
        nothing was pending —, whether the backlog was cleared). A frame that arrives while this waits extends
        the wait (the limit bounds that)."""
        if not self.pending():
            return 0.0, True
        start = time.monotonic()
        while True:
            time.sleep(BACKLOG_POLL_S)
            waited = time.monotonic() - start
            if not self.pending():
                return waited, True
            if waited >= limit:
                return waited, False
