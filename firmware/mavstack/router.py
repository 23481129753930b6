"""Routing between links by the MAVLink routing rules: a fixed table of the (system,
component)s heard and the links they were heard on, learned from every frame, and each
frame forwarded, as it came, to the other links its target was seen on (a broadcast to
every other link). main.py adds it to a board with more than one link.
Reference (the rules, the table, ranks, signing, private links): docs/routing.md.
"""
from .compat import const, ticks_diff
from .kernels import crc16, copy, id_info
from .parser import STX_V2, HEADER_V1, HEADER_V2, SIGNATURE_LEN, FRAME_MAX

_MSG_SYSTEM_TIME = const(2)
_MSG_RADIO_STATUS = const(109)
_MSG_RADIO = const(166)
_ALL = const(0x3FFFFFFF)  # every link (30 at most)
_SWEEP_MS = const(1000)  # how often routes gone silent are forgotten


class Router:
    NAME = "router"
    CLOCK = False

    def __init__(self, capacity=16, timeout_ms=10000, private=0):
        self.capacity = capacity
        self.timeout_ms = timeout_ms
        self.private = private  # bit i: link i is private (nothing forwarded to or from it)
        # The table, one entry a (system, component), by index:
        self.keys = [0] * capacity  # (sysid << 8 | compid) + 1; 0: free
        self.links = [0] * capacity  # bit i: heard on link i
        self.heard = [0] * capacity  # ticks_ms when last heard
        self.boot = [-1] * capacity  # its SYSTEM_TIME's time_boot_ms >> 2, -1: none yet
        self.frame = bytearray(FRAME_MAX)  # the frame being forwarded, as it came
        self._at = 0  # the entry found last (most frames come from the sender before)
        self._sweep_at = 0
        # Statistics (wrap as the links' counters): frames forwarded (one a link written
        # to), not written (budget or transport), entries evicted, systems forgotten.
        self.forwarded = 0
        self.not_sent = 0
        self.evicted = 0
        self.forgotten = 0

    def attach(self, ep):
        self.ep = ep
        ep.router = self
        self.targets = ep.dialect.TARGETS
        self.targets_high = ep.dialect.TARGETS_HIGH
        self._sweep_at = ep.now

    # --- every frame (allocation-free, small frames: docs/design.md) -------------------
    def route(self, link, msgid):
        """A frame arrived on link (its parser holds it): learn its sender, forward it."""
        rx = link.rx
        i = self._sender(rx, link.index)
        if i < 0:
            return  # our own, looped back
        if msgid == _MSG_SYSTEM_TIME:
            i = self._time(i, rx, link.index)
        if msgid == _MSG_RADIO_STATUS or msgid == _MSG_RADIO or self.private >> link.index & 1:
            return
        # Never to a link its sender was heard on (the arrival link among them): with two
        # paths to one peer, a broadcast does not come back round.
        mask = self._where(msgid, rx.payload) & ~self.links[i] & ~self.private
        if mask:
            self._forward(rx, mask)

    def _sender(self, rx, index):
        """The sender's entry, learnt (-1: the sender is us)."""
        key = (rx.sysid << 8 | rx.compid) + 1
        if key == (self.ep.sysid << 8 | self.ep.compid) + 1:
            return -1
        i = self._at
        if self.keys[i] != key:
            i = self._find(key)
            if i < 0:
                i = self._take(key)
            self._at = i
        self.heard[i] = self.ep.now
        self.links[i] |= 1 << index
        return i

    def learn(self, sysid, compid, index):
        """Learn a route as a frame from (sysid, compid) on link index would (tests, benches)."""
        key = (sysid << 8 | compid) + 1
        i = self._find(key)
        if i < 0:
            i = self._take(key)
        self.heard[i] = self.ep.now
        self.links[i] |= 1 << index

    def _find(self, key):
        keys = self.keys
        i = 0
        while i < self.capacity:
            if keys[i] == key:
                return i
            i += 1
        return -1

    def _take(self, key):
        """A free entry for key, else the one heard least lately (evicted)."""
        now = self.ep.now
        heard = self.heard
        best = 0
        i = 0
        while i < self.capacity:
            if self.keys[i] == 0:
                best = i
                break
            if ticks_diff(now, heard[i]) > ticks_diff(now, heard[best]):
                best = i
            i += 1
        if self.keys[best] != 0:
            self.evicted += 1
        self.keys[best] = key
        self.links[best] = 0
        self.boot[best] = -1
        return best

    def _time(self, i, rx, index):
        """SYSTEM_TIME: a time_boot_ms lower than its last one is a reboot, and the
        system's routes are forgotten (then this sender learnt again) -> its entry."""
        p = rx.payload
        t = p[8] >> 2 | p[9] << 6 | p[10] << 14 | p[11] << 22  # time_boot_ms >> 2, < 2^30
        if 0 <= t < self.boot[i]:
            self.forget(rx.sysid)
            i = self._sender(rx, index)  # learnt again
        self.boot[i] = t
        return i

    def _target(self, msgid):
        """Where the targets of a message id >= 256 sit: system offset + 1 | component
        offset + 1 << 8 (TARGETS_HIGH; those below 256 are read in _where)."""
        t = self.targets_high
        i = 0
        while i < len(t):
            if t[i] == msgid & 0xFF and t[i + 1] == msgid >> 8 & 0xFF and t[i + 2] == msgid >> 16:
                return t[i + 3] | t[i + 4] << 8
            i += 5
        return 0

    def _where(self, msgid, p):
        """The links the frame goes to, as a mask (the arrival link not yet taken out)."""
        if msgid < 256:
            t = self.targets[2 * msgid]
            ts = p[t - 1] if t else 0
            t |= self.targets[2 * msgid + 1] << 8
        else:
            t = self._target(msgid)
            ts = p[(t & 0xFF) - 1] if t & 0xFF else 0
        if ts == 0:
            return _ALL  # broadcast (or no target at all)
        tc = p[(t >> 8) - 1] if t >> 8 else 0
        ep = self.ep
        if ts != ep.sysid:
            return self.seen(ts, 0)  # another system: wherever it was heard
        if tc == ep.compid:
            return 0  # ours alone
        return self.seen(ts, tc)  # another component of ours (0: all of them)

    def seen(self, sysid, compid):
        """The links (sysid, compid) was heard on, as a mask; compid 0: any component."""
        keys = self.keys
        lo = (sysid << 8) + 1
        mask = 0
        i = 0
        while i < self.capacity:
            k = keys[i] - lo  # 0..255: this system, component k
            if 0 <= k < 256 and (compid == 0 or k == compid):
                mask |= self.links[i]
            i += 1
        return mask

    def _forward(self, rx, mask):
        """The frame as it came, rebuilt in self.frame, written to every link in mask."""
        n = self._copy(rx.buf, id_info(rx.infos, rx.msgid) & 0xFF)
        if rx.signed:
            copy(self.frame, rx.signature, n, SIGNATURE_LEN)
            n += SIGNATURE_LEN
        self._send(mask, n)

    def _copy(self, buf, extra):
        """Header and payload as they came; the parser widened the payload over the CRC,
        so the CRC is computed again (the same) -> the frame's length, unsigned."""
        frame = self.frame
        n = (HEADER_V2 if buf[0] == STX_V2 else HEADER_V1) + buf[1]
        copy(frame, buf, 0, n)
        frame[n] = extra  # CRC_EXTRA where the CRC goes, as the parser checks it
        crc = crc16(frame, 1, n + 1, 0xFFFF)
        frame[n] = crc & 0xFF
        frame[n + 1] = crc >> 8
        return n + 2

    def _send(self, mask, n):
        links = self.ep.links
        sent = 0
        i = 0
        while mask and i < len(links):
            if mask & 1 and links[i].forward(self.frame, n):
                sent += 1
            elif mask & 1:
                self.not_sent = (self.not_sent + 1) & 0x1FFFFFFF
            mask >>= 1
            i += 1
        self.forwarded = (self.forwarded + sent) & 0x1FFFFFFF

    # --- the local rule (endpoint.for_us) and the table's upkeep ------------------------
    def unseen(self, compid):
        """Is compid a component of our system heard on no link?"""
        return self.seen(self.ep.sysid, compid) == 0

    def forget(self, sysid):
        """Forget every route of a system."""
        keys = self.keys
        lo = (sysid << 8) + 1
        i = 0
        while i < self.capacity:
            if 0 <= keys[i] - lo < 256:
                keys[i] = 0
                self.links[i] = 0
            i += 1
        self.forgotten += 1

    def tick(self, now):
        if ticks_diff(now, self._sweep_at) < _SWEEP_MS:
            return
        self._sweep_at = now
        i = 0
        while i < self.capacity:
            if self.keys[i] and ticks_diff(now, self.heard[i]) >= self.timeout_ms:
                self.keys[i] = 0  # silent: forgotten
                self.links[i] = 0
            i += 1

    def routes(self):
        """[(sysid, compid, link mask, ms since heard)] (host tools, tests; allocates)."""
        now = self.ep.now
        return [((k - 1) >> 8, (k - 1) & 0xFF, self.links[i], ticks_diff(now, self.heard[i]))
                for i, k in enumerate(self.keys) if k]
