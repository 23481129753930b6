"""MAVLink 2 message signing (SETUP_SIGNING #256 and the 13-byte frame signature).

With a secret key set, every frame that arrives must carry a valid signature and a
timestamp newer than the last one from its stream, or be one of the few ids allowed
unsigned; every frame sent is signed. An all-zero key turns signing off, and with it off
nothing in the parser or encoder changes. Timestamps are 6 little-endian bytes, never an
int. What is stored (storage file "signing_key") is a promise: no timestamp above it was
accepted or sent, so no frame from before a restart is accepted after it. Verifying,
signing and the clock allocate nothing.
Reference (settings, the key, restarts, frames from the future): docs/services/signing.md.
"""
from ..compat import const, ticks_add, ticks_diff, to_grid
from ..kernels import copy
from ..parser import HEADER_V2, SIGNATURE_LEN
from ..storage import save_sealed, sealed
from ..kernels.sha256 import Signature
from ..statustext import NOTICE, WARNING

_MSG_RADIO_STATUS = const(109)
_MSG_SETUP_SIGNING = const(256)
_FILE = "signing_key"
_FILE_LEN = const(42)
_STREAMS = const(16)  # (sysid, compid, link id) streams whose last timestamp is kept
_NEW_STREAM_SLACK = const(6000000)  # a new stream may start up to a minute behind us
_CLOCK_MS = const(1000)  # follow uptime this often
_SYNC_MS = const(10000)  # re-read the time of day this often
_AHEAD_LIMIT_MS = const(300000)  # SIGNING_MAX_AHEAD_MS at most (as units, below 2^29)
_EPOCH_2015 = b"\x00\x80\xbf\xe7\x8b\x0b\x05\x00"  # 1420070400000000 us, little-endian


class _LinkSigner:
    """The parser and encoder hooks of one link."""

    def __init__(self, service, link):
        self.service = service
        self.rx = link.rx
        self.link_id = link.index & 0xFF

    def verify(self, buf, plen, signed):
        return self.service.check(self.rx, buf, plen, signed)

    def sign(self, buf, end):
        return self.service.sign(buf, end, self.link_id)


class Signing:
    NAME = "signing"

    # Per-frame methods are split small (docs/design.md).
    def __init__(self, setup_links=None, allow_unsigned=(0,), save_ms=60000, max_ahead_ms=60000):
        self.setup_links = setup_links
        self.allow_unsigned = tuple(allow_unsigned) + (_MSG_RADIO_STATUS,)
        # The stored promise is renewed this often: a save interval of 0 (never) would
        # leave nothing to tell, after a restart, what was accepted before it.
        self.save_ms = max(save_ms, 1000)
        self._ahead = min(max_ahead_ms, _AHEAD_LIMIT_MS) * 100  # in timestamp units
        self.key = bytearray(32)
        self.enabled = False
        self.ts = bytearray(6)  # our timestamp, last one sent
        self._floor = bytearray(6)  # a new stream must start above it: the stored promise at boot
        self._promise = bytearray(6)  # no timestamp above it accepted or sent (as stored)
        self._due = bytearray(6)  # save again once our timestamp passes this
        self._timed = False  # the clock is the time of day
        self._sig = Signature()
        self._keys = [-1] * _STREAMS  # sysid << 16 | compid << 8 | link id
        self._stamps = bytearray(6 * _STREAMS)  # their last timestamps
        self._next = 0
        self._clk = bytearray(6)  # the clock (stored timestamp + uptime, or time of day) at _clk_at
        self._tmp = bytearray(8)  # scratch: a new stream's limit, the time of day
        self._file = bytearray(_FILE_LEN)
        self._clk_at = 0
        self._synced_at = 0
        self._hooks = []
        self._warning = None  # a STATUSTEXT from start-up, sent once services are up
        self.accepted = 0
        self.bad_signature = 0
        self.replayed = 0
        self.future = 0
        self.unsigned = 0

    def attach(self, ep):
        self.ep = ep
        now = ep.now
        self._clk_at = now
        self._synced_at = ticks_add(now, -_SYNC_MS)  # the first clock step reads the time of day
        for link in ep.links:
            h = _LinkSigner(self, link)
            # Bound methods made once, so switching signing on and off allocates nothing more.
            self._hooks.append((link, h.verify, h.sign))
        ep.on(_MSG_SETUP_SIGNING, self._on_setup)
        self._load()
        if getattr(ep, "storage", None) is not None:
            ep.storage.reserve(_FILE, _FILE_LEN)  # the first save allocates nothing

    # --- per frame ---------------------------------------------------------------------
    def check(self, rx, buf, plen, signed):
        if not signed:
            return self._unsigned(rx)
        plen += HEADER_V2 + 2  # now the offset of the link id, then timestamp, then signature
        if not self._sig.matches(self.key, buf, plen + 7):
            self.bad_signature += 1
            return False
        if self._timed and self._too_far(buf, plen):
            self.future += 1
            return False
        if not self._fresh(rx, buf, plen):
            self.replayed += 1
            return False
        self.accepted += 1
        return True

    def _unsigned(self, rx):
        if rx.msgid in self.allow_unsigned:
            return True
        self.unsigned += 1
        return False

    def _fresh(self, rx, buf, s):
        # Is the timestamp at buf[s+1:s+7] newer than the last from its stream (link id at
        # buf[s])? If so it is the stream's last, and ours if it is ahead of ours.
        key = rx.sysid << 16 | rx.compid << 8 | buf[s]
        i = _find(self._keys, key)
        if i < 0:
            i = self._new_stream(key, buf, s)
            if i < 0:
                return False
        elif not _later(buf, s + 1, self._stamps, i):
            return False
        self._keep(buf, s, i)
        return True

    def _too_far(self, buf, s):
        # Is the timestamp at buf[s+1:s+7] more than the allowed minute ahead of ours?
        t = self._tmp
        _plus(t, self.ts, 0, self._ahead)
        return _later(buf, s + 1, t, 0)

    def _new_stream(self, key, buf, s):
        # A stream not seen (or forgotten) -> its offset in _stamps, or -1 if its
        # timestamp is not above the floor (what the stored promise covered at boot) or
        # more than _NEW_STREAM_SLACK behind ours: an old frame replayed.
        if not _later(buf, s + 1, self._floor, 0):
            return -1
        t = self._tmp
        _plus(t, buf, s + 1, _NEW_STREAM_SLACK)
        if _later(self.ts, 0, t, 0):
            return -1
        i = self._next
        self._next = (i + 1) % _STREAMS
        self._keys[i] = key
        return 6 * i

    def _keep(self, buf, s, i):
        s += 1
        copy(self._stamps, buf, i | s << 10, 6)
        if _later(buf, s, self.ts, 0):
            copy(self.ts, buf, s << 10, 6)
            if _later(buf, s, self._promise, 0):
                self._renew()  # (rare) stored before the frame goes any further

    def sign(self, buf, end, link_id):
        ts = self.ts
        _plus(ts, ts, 0, 1)
        buf[end] = link_id
        copy(buf, ts, end + 1, 6)
        self._sig.sign(self.key, buf, end + 7)
        return SIGNATURE_LEN

    # --- clock -------------------------------------------------------------------------
    def tick(self, now):
        if self._warning is not None:
            self.ep.statustext(WARNING, self._warning)
            self._warning = None
        if not self.enabled:
            return to_grid(now, _CLOCK_MS)
        dt = ticks_diff(now, self._clk_at)
        if dt < _CLOCK_MS >> 1:  # (on the loop's grid: a second, give or take)
            return to_grid(now, _CLOCK_MS)
        self._clk_at = now
        _advance(self._clk, dt)
        if ticks_diff(now, self._synced_at) >= _SYNC_MS:
            self._synced_at = now
            self._sync()
        if _later(self._clk, 0, self.ts, 0):
            copy(self.ts, self._clk, 0, 6)
        if _later(self.ts, 0, self._due, 0):
            self._renew()
        return to_grid(now, _CLOCK_MS)

    def _sync(self):
        # The clock becomes the time of day, when that is known.
        t = self._tmp
        self.ep.clock.stamp_unix(t, 0)  # unix us as bytes, zero while unknown
        if _since_2015(t):
            copy(self._clk, t, 0, 6)
            self._timed = True

    # --- the stored promise ------------------------------------------------------------
    def _renew(self):
        """Store a promise a save interval ahead of need. (Rare: once an interval, or
        when a frame is ahead of it.)"""
        self._plan()
        self._save()

    def _plan(self):
        # due = ts + interval, promise = due + interval
        copy(self._due, self.ts, 0, 6)
        _advance(self._due, self.save_ms)
        copy(self._promise, self._due, 0, 6)
        _advance(self._promise, self.save_ms)

    def stop(self):
        """The vehicle is about to reboot or shut down: store our timestamp itself, so
        that after the restart a ground station going on from where it was is newer.
        Called when the command is accepted (a board's shutdown() may cut the power) and
        again by main.py at the end; in between, a frame accepted above it is stored as
        ever, and the few frames sent need no new promise (due an interval on)."""
        if not self.enabled:
            return
        copy(self._promise, self.ts, 0, 6)
        copy(self._due, self.ts, 0, 6)
        _advance(self._due, self.save_ms)
        self._save()

    # --- key ---------------------------------------------------------------------------
    def _on_setup(self, link, p):
        # initial_timestamp (u64), target_system, target_component, secret_key[32]
        if not self.ep.for_us(p[8], p[9]):
            return
        if self.setup_links is not None and link.index not in self.setup_links:
            return
        if not self.ep.allows(link):
            return
        t = bytearray(6)
        copy(t, p, 0, 6)  # timestamps are 48-bit: the low 6 bytes of the u64
        self._use_key(p[10:42], t)
        self._renew()
        self.ep.statustext(NOTICE, b"Signing on" if self.enabled else b"Signing off")

    def set_key(self, key, timestamp=0):
        """Use this 32-byte key (all zeros: signing off), timestamp at least as given."""
        t = bytearray(6)
        for i in range(6):
            t[i] = (timestamp >> (8 * i)) & 0xFF
        self._use_key(key, t)

    def _use_key(self, key, t):
        # t: the lowest timestamp to go on from, 6 bytes.
        copy(self.key, key, 0, 32)
        if _later(t, 0, self.ts, 0):
            copy(self.ts, t, 0, 6)
        copy(self._clk, self.ts, 0, 6)
        self._clk_at = self.ep.now
        self._sync()
        if _later(self._clk, 0, self.ts, 0):
            copy(self.ts, self._clk, 0, 6)
        self._plan()  # stored by the caller when storage should know (_renew)
        for i in range(_STREAMS):
            self._keys[i] = -1
        self.enabled = any(self.key)
        for link, verify, sign in self._hooks:
            link.rx.verify = verify if self.enabled else None
            link.tx.sign = sign if self.enabled else None
            if self.enabled and link.negotiate:
                # Only MAVLink 2 frames carry signatures: no unsigned MAVLink 1 start.
                link.tx.version = 2

    def _load(self):
        storage = getattr(self.ep, "storage", None)
        if storage is None or not storage.exists(_FILE):
            return
        try:
            with storage.open(_FILE) as f:
                data = f.read()
        except OSError:
            data = b""
        if not sealed(data, _FILE_LEN):
            self._warning = b"Signing key corrupt: signing off"
            return
        # The stored promise: nothing above it was accepted or sent before the restart.
        # Our timestamp goes on from there, and a new stream must start above it.
        t = bytearray(data[32:38])
        copy(self._floor, t, 0, 6)
        self._use_key(data[:32], t)
        copy(self._promise, t, 0, 6)  # what storage holds; renewed once ts passes it
        copy(self._due, t, 0, 6)

    def _save(self):
        try:
            self._write()
        except OSError:
            self.ep.statustext(WARNING, b"Signing key not saved")

    def _write(self):
        storage = getattr(self.ep, "storage", None)
        if storage is None:
            return
        data = self._file  # key (32), the promise (8, the top two bytes zero), CRC
        copy(data, self.key, 0, 32)
        copy(data, self._promise, 32, 6)
        save_sealed(storage, _FILE, data)


# --- 48-bit timestamps as 6 little-endian bytes ----------------------------------------
def _later(a, i, b, j):
    """Is the timestamp at a[i:i+6] later than the one at b[j:j+6]? (by 24-bit halves)"""
    x = a[i + 5] << 16 | a[i + 4] << 8 | a[i + 3]
    y = b[j + 5] << 16 | b[j + 4] << 8 | b[j + 3]
    if x != y:
        return x > y
    x = a[i + 2] << 16 | a[i + 1] << 8 | a[i]
    return x > (b[j + 2] << 16 | b[j + 1] << 8 | b[j])


def _plus(dst, src, o, n):
    """dst[0:6] = src[o:o+6] + n, for 0 <= n < 2^29 (dst may be src at o = 0)."""
    for i in range(6):
        n += src[o + i]
        dst[i] = n & 0xFF
        n >>= 8


def _advance(t, ms):
    """t[0:6] += ms milliseconds, in steps that keep every sum small."""
    while ms > 40000:
        _plus(t, t, 0, 4000000)
        ms -= 40000
    if ms > 0:
        _plus(t, t, 0, ms * 100)


def _find(keys, key):
    # -> the stream's offset in _stamps, or -1
    for i in range(_STREAMS):
        if keys[i] == key:
            return 6 * i
    return -1


def _since_2015(t):
    """t[0:8], unix time in us -> t[0:6], units of 10 us since 2015 (False: unknown or earlier)."""
    if not _minus_epoch(t):
        return False
    r = 0
    for i in range(7, -1, -1):  # long division by 10, top byte first
        r = r << 8 | t[i]
        t[i] = r // 10
        r %= 10
    return not (t[6] | t[7])


def _minus_epoch(t):
    b = 0
    for i in range(8):
        b = t[i] - _EPOCH_2015[i] - b
        t[i] = b & 0xFF
        b = (b >> 8) & 1  # borrow
    return not b


def create(ep):
    return ep.add(Signing(
        setup_links=ep.setting("SIGNING_SETUP_LINKS"),
        allow_unsigned=ep.setting("SIGNING_ALLOW_UNSIGNED", (0,)),
        save_ms=ep.setting("SIGNING_SAVE_MS", 60000),
        max_ahead_ms=ep.setting("SIGNING_MAX_AHEAD_MS", 60000),
    ))
