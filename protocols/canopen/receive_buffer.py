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
"""

from __future__ import annotations

import socket

import can

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
