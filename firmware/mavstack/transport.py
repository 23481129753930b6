"""Byte transports a link runs over: UDP here; a tty/pty or a board's UART in
transport_serial.py (loaded only where used, to spare a small board's heap).

Every transport has the same small, non-blocking, allocation-free face:
    readinto(buf) -> bytes read (0 when none)
    write(buf, n) -> bytes taken from buf[0:n] (0 when it cannot take them now)
    bytes_per_s   what the medium carries: the link's byte budget (link.py)
    rx_peer       the address that sent what readinto returned last (UDP), or None
    heard(now)    optional: the link found a valid frame in it (UDP servers pick
                  their peers by this)
Specs as on the command line: udpout:HOST:PORT, udpin:ADDR:PORT, serial:DEVICE:BAUD.
"""
from .compat import MICROPYTHON, ticks_diff, ticks_add

UDP_BYTES_PER_S = 200000  # nominal budget for UDP links; boards may override


def _sockaddr(socket, host, port):
    return socket.getaddrinfo(host, port, 0, socket.SOCK_DGRAM)[0][-1]


_PEERS = 4  # ground stations a udpin link answers at once
_PEER_QUIET_MS = 5000  # a peer silent this long gets no more writes (but the last heard)
_SWEEP_MS = 1000


class UdpTransport:
    """udpout sends to HOST:PORT and hears its replies (the SITL convention);
    udpin listens on ADDR:PORT and serves up to `peers` ground stations at once, as an
    autopilot's UDP server does.

    udpin peers. An address becomes a peer with its first CRC-valid MAVLink frame (the
    link calls heard(now) for every valid frame; the address that sent the datagram
    being parsed is rx_peer), never with anything else: junk from anywhere changes
    nothing. Every frame is written to every peer heard from in the last
    _PEER_QUIET_MS, and always to the one heard last, so a ground station that only
    listens keeps its stream; a peer whose port is closed (a write fails: a one-shot
    tool that finished) gets no more until it speaks again. A newcomer takes a free
    slot, or one that gets no writes, or the slot of a peer silent that long; while
    every slot is busy with a live ground station its frames are still handled, but
    it hears nothing back.

    Traffic goes through sockets connect()ed to the peers (one each), so that reads and
    writes are the stream calls, which allocate nothing. udpin also keeps an unconnected
    socket bound to the same port: the kernel hands it only datagrams from addresses no
    socket is connected to, read with recvfrom (it allocates: an address that is not a
    peer is not the steady state), and the socket of a new peer is made then (rare).
    MicroPython's readinto fills the whole buffer with as many queued datagrams as
    fit and cuts short the one that does not (its tail is lost), so a link reads UDP
    in rx_chunk bytes, far more than a burst of ground-station traffic; a read that
    fills them is counted in rx_overruns. A board short of RAM may read in less
    (UDP_RX_CHUNK): a ground station sends a mission item at a time.
    """

    rx_chunk = 4096

    def __init__(self, mode, host, port, bytes_per_s=UDP_BYTES_PER_S, rx_chunk=0, peers=_PEERS):
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
        self.rx_overruns = 0
        self.rx_peer = None  # the address that sent the datagram being parsed
        self._n = 0  # write's count for _send (made here: the heap may be locked later)
        self._cur = None  # the socket _read or _send works on
        self._listen = None
        if mode != "udpin":
            peers = 1
        # Per peer slot: its connected socket, address, when it was last heard (ticks_ms)
        # and whether it gets writes.
        self._socks = [None] * peers
        self._addrs = [None] * peers
        self._heard_at = [0] * peers
        self._live = bytearray(peers)
        self._last = -1  # the slot heard from last
        self._rx = -1  # the slot the datagram being parsed came from, -1: none (yet)
        self._next = 0  # the slot read first next time (round robin)
        self._sweep_at = 0
        addr = _sockaddr(socket, host, port)
        if mode == "udpin":
            self._listen = self._bound(addr)
            self._poll = select.poll()
            self._poll.register(self._listen, select.POLLIN)
            self._addr = addr
        else:
            self._connect(0, None, addr)
            self._live[0] = 1
            self._last = 0

    @property
    def peer(self):
        """The address heard from last (udpout: the one it sends to), or None."""
        return self._addrs[self._last] if self._last >= 0 else None

    def peers(self):
        """Addresses that get writes now."""
        return [self._addrs[i] for i in range(len(self._socks)) if self._live[i]]

    def _bound(self, addr):
        socket = self._socket
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(addr)
        s.setblocking(False)
        return s

    def _connect(self, i, local, peer):
        if self._socks[i] is not None:
            self._socks[i].close()
            self._socks[i] = None
        if local is None:
            socket = self._socket
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        else:
            s = self._bound(local)
        s.connect(peer)
        s.setblocking(False)
        self._socks[i] = s
        self._addrs[i] = peer

    # --- reading: every poll (small functions of few locals: MicroPython takes a frame
    # state of more than about 11 words, locals, value stack, three for a try, from the
    # heap on every call) -------------------------------------------------------------
    def readinto(self, buf):
        n = self._read_peers(buf)
        if not n and self._listen is not None and self._waiting():
            n = self._newcomer(buf)
        return n

    def _waiting(self):
        """Is a datagram waiting on the listening socket? (Asked on every poll: apart
        from _newcomer, whose try, loop and locals take a frame state from the heap.)"""
        for _obj, _ev in (self._poll.ipoll(0) if MICROPYTHON else self._poll.poll(0)):
            return True
        return False

    def _read_peers(self, buf):
        socks = self._socks
        i = self._next
        k = len(socks)
        while k:
            k -= 1
            if i >= len(socks):
                i = 0
            if socks[i] is not None:
                self._cur = socks[i]
                n = self._read(buf)
                if n < 0:
                    n = self._closed(i)
                if n:
                    self._next = i + 1  # the others first next time
                    self._rx = i
                    self.rx_peer = self._addrs[i]
                    if n == len(buf) and MICROPYTHON:
                        self.rx_overruns += 1
                    return n
            i += 1
        return 0

    # _read and _send take the socket in self._cur: one argument more would take their
    # frame state (a try is three words) over what MicroPython keeps off the heap.
    # -> bytes read, 0 if none are waiting, -1 on an error: the peer's port is closed
    # (the kernel's "port unreachable" comes back to a connected socket).
    if MICROPYTHON:

        def _read(self, buf):
            try:
                return self._cur.readinto(buf) or 0  # None: nothing waiting
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

    def _closed(self, i):
        """Peer i's port is closed (a one-shot tool that finished): on udpin it gets no
        more writes until it speaks again, and its slot may go to a newcomer -> 0."""
        if self._listen is not None:
            self._live[i] = 0
        return 0

    def _newcomer(self, buf):
        # Something on the listening socket: an address no peer socket is connected to
        # (or a peer's datagram that came before its socket was). It becomes a peer only
        # if the link finds a valid frame in it (heard).
        try:
            data, addr = self._listen.recvfrom(len(buf))
        except OSError:
            return 0
        self._rx = self._slot_of(addr)
        self.rx_peer = addr if self._rx < 0 else self._addrs[self._rx]
        n = len(data)
        buf[0:n] = data
        return n

    def _slot_of(self, addr):
        for i in range(len(self._socks)):
            if self._addrs[i] == addr:
                return i
        return -1

    def heard(self, now):
        """The link found a CRC-valid frame in the datagram being parsed: its sender is
        (or becomes) a peer, heard now (ticks_ms)."""
        i = self._rx
        if i < 0:
            i = self._adopt(now)  # rare: a new ground station
            if i < 0:
                return
        self._heard_at[i] = now
        self._live[i] = 1
        self._last = i
        if ticks_diff(now, self._sweep_at) >= 0:
            self._sweep_at = ticks_add(now, _SWEEP_MS)
            self._sweep(now)

    def _sweep(self, now):
        """Peers silent for _PEER_QUIET_MS get no more writes, but the last heard."""
        i = 0
        while i < len(self._socks):
            if i != self._last and ticks_diff(now, self._heard_at[i]) > _PEER_QUIET_MS:
                self._live[i] = 0
            i += 1

    def _adopt(self, now):
        """A slot for rx_peer: a free one, or one that gets no writes, else the one
        silent longest if that is longer than _PEER_QUIET_MS -> its index, -1 if every
        slot has a live ground station."""
        if self._listen is None or self.rx_peer is None:
            return -1
        pick = -1
        for i in range(len(self._socks)):
            if self._socks[i] is None or not self._live[i]:
                pick = i
                break
            quiet = ticks_diff(now, self._heard_at[i])
            if quiet > _PEER_QUIET_MS and (pick < 0 or quiet > ticks_diff(now, self._heard_at[pick])):
                pick = i
        if pick >= 0:
            self._connect(pick, self._addr, self.rx_peer)
            self._rx = pick
        return pick

    # --- writing: to every live peer ---------------------------------------------------
    def write(self, buf, n):
        """buf[0:n] to every live peer -> n if any took it, else 0."""
        self._n = n
        took = 0
        i = 0
        while i < len(self._socks):
            if self._live[i]:
                self._cur = self._socks[i]
                if self._send(buf) == n:
                    took = n
                else:
                    self._closed(i)
            i += 1
        return took

    if MICROPYTHON:

        def _send(self, buf):
            try:
                return self._cur.write(buf, self._n) or 0
            except OSError:
                return 0

    else:

        def _send(self, buf):
            try:
                return self._cur.send(memoryview(buf)[: self._n])
            except OSError:
                return 0

    def close(self):
        for s in self._socks:
            if s is not None:
                s.close()
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
