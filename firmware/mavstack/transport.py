"""Byte transports a link runs over: UDP, a tty/pty, a board's UART.

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
    fills them is counted in rx_overruns.
    """

    rx_chunk = 4096

    def __init__(self, mode, host, port, bytes_per_s=UDP_BYTES_PER_S):
        import socket
        import select

        self._socket = socket
        self.mode = mode
        self.host = host
        self.port = port
        self.bytes_per_s = bytes_per_s
        self.name = "%s:%s:%d" % (mode, host, port)
        self.peer = None
        self.sock = None
        self.rx_overruns = 0
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

    def readinto(self, buf):
        n = 0
        if self.sock is not None:
            try:
                n = self.sock.readinto(buf) if MICROPYTHON else self.sock.recv_into(buf)
            except OSError:  # nothing waiting, or the peer's port is closed
                n = 0
            if n is None:
                n = 0
            elif n == len(buf) and MICROPYTHON:
                self.rx_overruns += 1
        if not n and self._listen is not None:
            n = self._newcomer(buf)
        return n

    if MICROPYTHON:

        def write(self, buf, n):
            if self.sock is None:
                return 0
            try:
                return self.sock.write(buf, n) or 0
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


class SerialTransport:
    """A tty or pty on a unix host (MicroPython's unix port or CPython), raw mode.

    Reads never wait: the terminal is set to return at once with what it has
    (VMIN=0, VTIME=0). Writes are skipped while the device cannot take them.
    """

    def __init__(self, device, baud):
        import termios

        self.device = device
        self.baud = baud
        self.bytes_per_s = baud // 10  # 8N1: ten bit times a byte
        self.name = "serial:%s:%d" % (device, baud)
        if MICROPYTHON:
            self._f = open(device, "r+b")
            fd = self._f.fileno()
        else:
            import os

            fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            self._f = None
        self.fd = fd
        if MICROPYTHON:
            termios.setraw(fd)
        else:  # CPython keeps setraw in the tty module
            import tty

            tty.setraw(fd)
        attr = termios.tcgetattr(fd)
        attr[6][6] = 0  # VMIN
        attr[6][5] = 0  # VTIME
        speed = getattr(termios, "B%d" % baud, None)
        if speed is not None:
            attr[4] = attr[5] = speed
        termios.tcsetattr(fd, termios.TCSANOW, attr)
        import select

        self._poll = select.poll()
        self._poll.register(self._f if MICROPYTHON else fd, select.POLLOUT)
        self._POLLOUT = select.POLLOUT

    if MICROPYTHON:

        def readinto(self, buf):
            try:
                return self._f.readinto(buf) or 0
            except OSError:
                return 0

        def write(self, buf, n):
            for _obj, ev in self._poll.ipoll(0):
                if ev & self._POLLOUT:
                    try:
                        return self._f.write(buf, n) or 0
                    except OSError:
                        return 0
            return 0

    else:

        def readinto(self, buf):
            import os

            try:
                return os.readv(self.fd, [buf])
            except OSError:
                return 0

        def write(self, buf, n):
            import os

            try:
                return os.write(self.fd, memoryview(buf)[:n])
            except OSError:
                return 0

    def close(self):
        if self._f is not None:
            self._f.close()
        else:
            import os

            os.close(self.fd)


class UartTransport:
    """A board's machine.UART, created by the board profile."""

    def __init__(self, uart, baud, name="uart"):
        self.uart = uart
        self.bytes_per_s = baud // 10
        self.name = name

    def readinto(self, buf):
        if not self.uart.any():
            return 0
        return self.uart.readinto(buf) or 0

    def write(self, buf, n):
        return self.uart.write(buf, n) or 0

    def close(self):
        pass


def open_transport(spec, udp_bytes_per_s=UDP_BYTES_PER_S):
    """Build a transport from udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD."""
    kind, _, rest = spec.partition(":")
    if kind in ("udpout", "udpin"):
        host, _, port = rest.rpartition(":")
        return UdpTransport(kind, host or "0.0.0.0", int(port), udp_bytes_per_s)
    if kind == "serial":
        device, _, baud = rest.rpartition(":")
        return SerialTransport(device, int(baud))
    raise ValueError("link spec: udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD")
