"""The udpin link: a UDP server on ADDR:PORT that ground stations call, serving several
at once as an autopilot's UDP server does. Loaded only by a board that listens.

An address becomes a peer with its first CRC-valid MAVLink frame (heard(now)), never
with anything else: junk from anywhere changes nothing. Frames go to every peer heard
from lately and always to the last one heard. Each peer has its own connected socket
(stream calls, allocating nothing); newcomers arrive on an unconnected one, a rare
event that opens a locked heap for its moment.
Reference (peers, slots, sockets): docs/core.md.
"""
from ..compat import MICROPYTHON, ticks_diff, ticks_add, heap_open, heap_close
from .udp import UdpTransport, sockaddr

_PEERS = 4  # ground stations served at once
_PEER_QUIET_MS = 5000  # a peer silent this long gets no more writes (but the last heard)
_SWEEP_MS = 1000


class UdpServer(UdpTransport):
    def __init__(self, host, port, bytes_per_s=None, rx_chunk=0, peers=_PEERS):
        import select

        UdpTransport.__init__(self, "udpin", host, port, bytes_per_s, rx_chunk)
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
        self._addr = sockaddr(self._socket, host, port)
        self._listen = self._bound(self._addr)
        self._poll = select.poll()
        self._poll.register(self._listen, select.POLLIN)
        self._primed = False  # the poll object has made its event tuple

    @property
    def peer(self):
        """The address heard from last, or None."""
        return self._addrs[self._last] if self._last >= 0 else None

    @peer.setter
    def peer(self, addr):
        pass  # (UdpTransport's __init__ sets it; here it follows the slots)

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

    # --- reading: every poll (small functions of few locals: docs/design.md) -----------
    def readinto(self, buf):
        n = self._read_peers(buf)
        if not n and self._waiting():
            n = self._newcomer(buf)
        return n

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

    def _closed(self, i):
        """Peer i's port is closed: no more writes until it speaks again, and its slot
        may go to a newcomer -> 0."""
        self._live[i] = 0
        return 0

    def _waiting(self):
        """Is a datagram waiting on the listening socket? (Asked on every poll: apart
        from _newcomer, whose try and locals make a large frame: docs/design.md.)"""
        if not self._primed:
            return self._first_wait()
        for _obj, _ev in (self._poll.ipoll(0) if MICROPYTHON else self._poll.poll(0)):
            return True
        return False

    def _first_wait(self):
        depth = heap_open()
        try:
            for _obj, _ev in (self._poll.ipoll(0) if MICROPYTHON else self._poll.poll(0)):
                self._primed = True
                return True
            return False
        finally:
            heap_close(depth)

    def _newcomer(self, buf):
        # An address no peer socket is connected to (or a peer's datagram that came
        # before its socket was). It becomes a peer only if the link finds a valid frame
        # in it (heard).
        depth = heap_open()
        try:
            data, addr = self._listen.recvfrom(len(buf))
            self._rx = self._slot_of(addr)
            self.rx_peer = addr if self._rx < 0 else self._addrs[self._rx]
            n = len(data)
            buf[0:n] = data
            return n
        except OSError:
            return 0
        finally:
            heap_close(depth)

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
        if self.rx_peer is None:
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
            depth = heap_open()
            try:
                self._connect_slot(pick)
            finally:
                heap_close(depth)
        return pick

    def _connect_slot(self, pick):
        if self._socks[pick] is not None:
            self._socks[pick].close()
        s = self._bound(self._addr)
        s.connect(self.rx_peer)
        self._socks[pick] = s
        self._addrs[pick] = self.rx_peer
        self._rx = pick

    # --- writing: to every live peer ---------------------------------------------------
    def write(self, buf, n):
        """buf[0:n] to every live peer -> n if any took it, else 0."""
        self._n = n
        took = 0
        i = 0
        while i < len(self._socks):
            if self._live[i]:
                self._cur = self._socks[i]
                k = self._send(buf)
                if k == n:
                    took = n
                elif k < 0:
                    self._closed(i)
            i += 1
        return took

    def close(self):
        for s in self._socks:
            if s is not None:
                s.close()
        self._listen.close()
