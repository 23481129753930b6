"""Byte transports a link runs over: UDP here; a tty/pty or a board's UART in
transport_serial.py (loaded only where used, to spare a small board's heap).

Every transport has the same small, non-blocking, allocation-free face:
    readinto(buf) -> bytes read (0 when none)
    write(buf, n) -> bytes taken from buf[0:n] (0 when it cannot take them now)
    bytes_per_s   what the medium carries, for pacing and stream budgets
Specs as on the command line: udpout:HOST:PORT, udpin:ADDR:PORT, serial:DEVICE:BAUD.
"""
from .compat import MICROPYTHON

UDP_BYTES_PER_S = 200000  # nominal budget for UDP links; boards may override


def _sockaddr(socket, host, port):
    return socket.getaddrinfo(host, port, 0, socket.SOCK_DGRAM)[0][-1]


class UdpTransport:
    """udpout sends to HOST:PORT and hears its replies (the SITL convention);
    udpin listens on ADDR:PORT and answers the ground station that spoke last.

    Traffic goes through a socket connect()ed to the peer, so that reads and writes
    are the stream calls, which allocate nothing. udpin also keeps an unconnected
    socket bound to the same port: the kernel hands it only datagrams from other
    addresses, so a new ground station is heard at once (one recvfrom, a rare event)
    and becomes the peer.
    MicroPython's readinto fills the whole buffer with as many queued datagrams as
    fit and cuts short the one that does not (its tail is lost), so a link reads UDP
    in rx_chunk bytes, far more than a burst of ground-station traffic; a read that
    fills them is counted in rx_overruns. A board short of RAM may read in less
    (UDP_RX_CHUNK): a ground station sends a mission item at a time.
    """

    rx_chunk = 4096

    def __init__(self, mode, host, port, bytes_per_s=UDP_BYTES_PER_S, rx_chunk=0):
        import socket
        import select

        if rx_chunk:
            self.rx_chunk = rx_chunk
        self._socket = socket
        self.mode = mode
        self.host = host
        self.port = port
        self.bytes_per_s = bytes_per_s
        self.name = "%s:%s:%d" % (mode, host, port)
        self.peer = None
        self.sock = None
        self.rx_overruns = 0
        self._n = 0  # write's count for _send (made here: the heap may be locked later)
        self._listen = None
        addr = _sockaddr(socket, host, port)
        if mode == "udpin":
            self._listen = self._bound(addr)
            self._poll = select.poll()
            self._poll.register(self._listen, select.POLLIN)
            self._addr = addr
        else:
            self._connect(None, addr)

    def _bound(self, addr):
        socket = self._socket
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(addr)
        s.setblocking(False)
        return s

    def _connect(self, local, peer):
        if self.sock is not None:
            self.sock.close()
        if local is None:
            socket = self._socket
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        else:
            s = self._bound(local)
        s.connect(peer)
        s.setblocking(False)
        self.sock = s
        self.peer = peer

    def _newcomer(self, buf):
        # Something on the listening socket: a ground station that is not our peer.
        for _obj, _ev in (self._poll.ipoll(0) if MICROPYTHON else self._poll.poll(0)):
            try:
                data, addr = self._listen.recvfrom(len(buf))
            except OSError:
                return 0
            if addr != self.peer:
                self._connect(self._addr, addr)
            n = len(data)
            buf[0:n] = data
            return n
        return 0

    # readinto and write run on every poll: the try is in small helpers of few locals,
    # since MicroPython takes a frame state of more than about 11 words (locals, value
    # stack, three for a try) from the heap on every call.
    def readinto(self, buf):
        n = 0
        if self.sock is not None:
            n = self._read(buf)
            if n == len(buf) and MICROPYTHON:
                self.rx_overruns += 1
        if not n and self._listen is not None:
            n = self._newcomer(buf)
        return n

    def _read(self, buf):
        try:
            return (self.sock.readinto(buf) if MICROPYTHON else self.sock.recv_into(buf)) or 0
        except OSError:  # nothing waiting, or the peer's port is closed
            return 0

    if MICROPYTHON:

        def write(self, buf, n):
            if self.sock is None:
                return 0
            self._n = n
            return self._send(buf)

        def _send(self, buf):
            try:
                return self.sock.write(buf, self._n) or 0
            except OSError:
                return 0

    else:

        def write(self, buf, n):
            if self.sock is None:
                return 0
            try:
                return self.sock.send(memoryview(buf)[:n])
            except OSError:
                return 0

    def close(self):
        if self.sock is not None:
            self.sock.close()
        if self._listen is not None:
            self._listen.close()


def open_transport(spec, udp_bytes_per_s=UDP_BYTES_PER_S, udp_rx_chunk=0):
    """Build a transport from udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD
    (udp_rx_chunk: bytes a UDP link reads at a time, 0 for UdpTransport.rx_chunk)."""
    kind, _, rest = spec.partition(":")
    if kind in ("udpout", "udpin"):
        host, _, port = rest.rpartition(":")
        return UdpTransport(kind, host or "0.0.0.0", int(port), udp_bytes_per_s, udp_rx_chunk)
    if kind == "serial":
        from .transport_serial import SerialTransport

        device, _, baud = rest.rpartition(":")
        return SerialTransport(device, int(baud))
    raise ValueError("link spec: udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD")
