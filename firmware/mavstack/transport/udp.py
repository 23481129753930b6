"""udpout: a UDP link to one ground station (the SITL convention); udpin.py builds on it.

Reference: docs/core.md.
"""
from ..compat import MICROPYTHON

UDP_BYTES_PER_S = 200000  # a UDP link's nominal budget; boards may set their own


def sockaddr(socket, host, port):
    return socket.getaddrinfo(host, port, 0, socket.SOCK_DGRAM)[0][-1]


class UdpTransport:
    """udpout: sends to HOST:PORT and hears its replies (the SITL convention). The
    udpin server, which serves several ground stations, is UdpServer in
    udpin.py (loaded only where used).

    Traffic goes through a socket connect()ed to the peer, so that reads and writes
    are the stream calls, which allocate nothing. MicroPython's readinto fills the whole
    buffer with as many queued datagrams as fit and cuts short the one that does not
    (its tail is lost), so a link reads UDP in rx_chunk bytes, far more than a burst of
    ground-station traffic; a read that fills them is counted in rx_overruns. A board
    short of RAM may read in less (UDP_RX_CHUNK): a ground station sends a mission item
    at a time.
    """

    rx_chunk = 4096

    def __init__(self, mode, host, port, bytes_per_s=None, rx_chunk=0):
        import socket

        if rx_chunk:
            self.rx_chunk = rx_chunk
        self._socket = socket
        self.mode = mode
        self.host = host
        self.port = port
        self.bytes_per_s = UDP_BYTES_PER_S if bytes_per_s is None else bytes_per_s
        self.name = "%s:%s:%d" % (mode, host, port)
        self.rx_overruns = 0
        self._n = 0  # write's count for _send (made here: the heap may be locked later)
        self._cur = None  # the socket _read and _send work on
        self.rx_peer = self.peer = None  # the address of what is being parsed; the peer
        if mode == "udpout":
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.rx_peer = self.peer = sockaddr(socket, host, port)
            s.connect(self.peer)
            s.setblocking(False)
            self._cur = s
            self.waitable = s  # what the loop's sleep watches for bytes (sleeper.py)

    def readinto(self, buf):
        n = self._read(buf)
        if n == len(buf) and MICROPYTHON:
            self.rx_overruns += 1
        return n if n > 0 else 0

    def write(self, buf, n):
        self._n = n
        return self._send(buf) if self._cur is not None else 0

    # _read and _send: -> bytes, 0 when the socket cannot now (nothing waiting, no room),
    # -1 on an error (the peer's port is closed: the kernel's "port unreachable" comes
    # back to a connected socket). Small, with the socket in self._cur: a try takes frame
    # words too (docs/design.md).
    if MICROPYTHON:

        def _read(self, buf):
            try:
                return self._cur.readinto(buf) or 0  # None: nothing waiting
            except OSError:
                return -1

        def _send(self, buf):
            try:
                return self._cur.write(buf, self._n) or 0  # None: no room now
            except OSError:
                return -1

    else:

        def _read(self, buf):
            try:
                return self._cur.recv_into(buf)
            except BlockingIOError:
                return 0
            except OSError:
                return -1

        def _send(self, buf):
            try:
                return self._cur.send(memoryview(buf)[: self._n])
            except BlockingIOError:
                return 0
            except OSError:
                return -1

    def close(self):
        if self._cur is not None:
            self._cur.close()
