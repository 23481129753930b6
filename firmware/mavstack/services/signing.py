"""MAVLink 2 message signing (SETUP_SIGNING #256 and the 13-byte frame signature).

With a secret key set, every frame that arrives must carry a valid signature and a
timestamp newer than the last one seen from its stream (sender sysid, compid and the
signature's link id); others are dropped before any service sees them. Unsigned
frames pass only for the ids in SIGNING_ALLOW_UNSIGNED (HEARTBEAT by default) and
RADIO_STATUS, which radios inject without a key. Every frame sent is signed, with the
link's index as link id; links that negotiate their version speak MAVLink 2 from then on
(links fixed to MAVLink 1 stay unsigned). An all-zero key turns signing off, and with it off
nothing in the parser or encoder changes.

Board settings:
    SIGNING_SETUP_LINKS     None: SETUP_SIGNING accepted on any link; else a tuple of
                            link indices (the links a key may be given on, e.g. USB)
    SIGNING_ALLOW_UNSIGNED  message ids accepted unsigned, default (0,) (HEARTBEAT)
    SIGNING_SAVE_MS         how often the timestamp is saved while signing (60000)

The key persists in storage file "signing_key": key (32), timestamp (8, little-endian),
CRC-16 of both (2). A corrupt file leaves signing off and says so in a STATUSTEXT.
List "signing" before "status" in SERVICES: then the boot HEARTBEAT is signed too.

Timestamps (units of 10 us since 2015-01-01) are kept as 6 little-endian bytes and
compared as two 24-bit halves, so that 32-bit ports need no long ints per frame. The
timestamp sent rises by one per frame and follows the clock: the status service's
time of day when known, else the stored timestamp plus uptime. After a restart it
resumes a whole save interval ahead of the stored one, so it never goes backwards.

Counters: accepted, bad_signature, replayed, unsigned (frames dropped per reason).
"""
import struct

from ..compat import const, ticks_diff
from ..kernels import copy
from ..parser import HEADER_V2, SIGNATURE_LEN
from ..storage import checksum
from .sha256 import Signature
from .statustext import NOTICE, WARNING

_MSG_RADIO_STATUS = const(109)
_MSG_SETUP_SIGNING = const(256)
_FILE = "signing_key"
_FILE_LEN = const(42)
_STREAMS = const(16)  # (sysid, compid, link id) streams whose last timestamp is kept
_NEW_STREAM_SLACK = const(6000000)  # a new stream may start up to a minute behind us
_LOW = const(0xFFFFFF)
_CLOCK_MS = const(1000)  # follow uptime this often
_SYNC_MS = const(10000)  # re-read the time of day this often
_EPOCH_2015_US = 1420070400000000


def _lo(b, o):
    return b[o] | b[o + 1] << 8 | b[o + 2] << 16


def _hi(b, o):
    return b[o + 3] | b[o + 4] << 8 | b[o + 5] << 16


def _put(b, o, hi, lo):
    b[o] = lo & 0xFF
    b[o + 1] = (lo >> 8) & 0xFF
    b[o + 2] = lo >> 16
    b[o + 3] = hi & 0xFF
    b[o + 4] = (hi >> 8) & 0xFF
    b[o + 5] = (hi >> 16) & 0xFF


def _as_int(b):
    return _hi(b, 0) << 24 | _lo(b, 0)


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

    def __init__(self, setup_links=None, allow_unsigned=(0,), save_ms=60000):
        self.setup_links = setup_links
        self.allow_unsigned = tuple(allow_unsigned) + (_MSG_RADIO_STATUS,)
        self.save_ms = save_ms
        self.key = bytearray(32)
        self.enabled = False
        self.ts = bytearray(6)  # our timestamp, last one sent
        self._sig = Signature()
        self._keys = [-1] * _STREAMS
        self._stamps = bytearray(6 * _STREAMS)
        self._next = 0
        self._clk_hi = 0  # clock (stored timestamp + uptime, or time of day) at _clk_at
        self._clk_lo = 0
        self._clk_at = 0
        self._synced_at = 0
        self._saved_at = 0
        self._hooks = []
        self._warning = None  # a STATUSTEXT from start-up, sent once services are up
        self.accepted = 0
        self.bad_signature = 0
        self.replayed = 0
        self.unsigned = 0

    def attach(self, ep):
        self.ep = ep
        now = ep.now
        self._clk_at = self._synced_at = self._saved_at = now
        for link in ep.links:
            h = _LinkSigner(self, link)
            # Bound methods made once, so switching signing on and off allocates nothing more.
            self._hooks.append((link, h.verify, h.sign))
        ep.on(_MSG_SETUP_SIGNING, self._on_setup)
        self._load()

    # --- per frame ---------------------------------------------------------------------
    def check(self, rx, buf, plen, signed):
        if not signed:
            if rx.msgid in self.allow_unsigned:
                return True
            self.unsigned += 1
            return False
        s = HEADER_V2 + plen + 2  # link id, then timestamp, then signature
        if not self._sig.matches(self.key, buf, s + 7):
            self.bad_signature += 1
            return False
        t = s + 1
        hi = _hi(buf, t)
        lo = _lo(buf, t)
        key = rx.sysid << 16 | rx.compid << 8 | buf[s]
        keys = self._keys
        stamps = self._stamps
        i = -1
        for k in range(_STREAMS):
            if keys[k] == key:
                i = k
                break
        if i >= 0:
            o = i * 6
            if not _newer(hi, lo, _hi(stamps, o), _lo(stamps, o)):
                self.replayed += 1
                return False
        else:
            lo2 = lo + _NEW_STREAM_SLACK
            if _newer(_hi(self.ts, 0), _lo(self.ts, 0), hi + (lo2 >> 24), lo2 & _LOW):
                self.replayed += 1
                return False
            i = self._next
            self._next = (i + 1) % _STREAMS
            keys[i] = key
        copy(stamps, buf, i * 6 | t << 10, 6)
        if _newer(hi, lo, _hi(self.ts, 0), _lo(self.ts, 0)):
            copy(self.ts, buf, t << 10, 6)
        self.accepted += 1
        return True

    def sign(self, buf, end, link_id):
        ts = self.ts
        for i in range(6):
            ts[i] = (ts[i] + 1) & 0xFF
            if ts[i]:
                break
        buf[end] = link_id
        copy(buf, ts, end + 1, 6)
        self._sig.compute(self.key, buf, end + 7, buf, end + 7)
        return SIGNATURE_LEN

    # --- clock -------------------------------------------------------------------------
    def tick(self, now):
        if self._warning is not None:
            self.ep.statustext(WARNING, self._warning)
            self._warning = None
        if not self.enabled:
            return
        dt = ticks_diff(now, self._clk_at)
        if dt < _CLOCK_MS:
            return
        lo = self._clk_lo + dt * 100
        self._clk_hi += lo >> 24
        self._clk_lo = lo & _LOW
        self._clk_at = now
        if ticks_diff(now, self._synced_at) >= _SYNC_MS:
            self._synced_at = now
            self._sync()
        if _newer(self._clk_hi, self._clk_lo, _hi(self.ts, 0), _lo(self.ts, 0)):
            _put(self.ts, 0, self._clk_hi, self._clk_lo)
        if self.save_ms and ticks_diff(now, self._saved_at) >= self.save_ms:
            self._saved_at = now
            self._save()

    def _sync(self):
        # Long ints on 32-bit ports: only every _SYNC_MS.
        status = self.ep.services.get("status")
        usec = status.unix_usec() if status is not None else 0
        if usec > _EPOCH_2015_US:
            v = (usec - _EPOCH_2015_US) // 10
            self._clk_hi = v >> 24
            self._clk_lo = v & _LOW

    # --- key ---------------------------------------------------------------------------
    def _on_setup(self, link, p):
        # initial_timestamp (u64), target_system, target_component, secret_key[32]
        if not self.ep.for_us(p[8], p[9]):
            return
        if self.setup_links is not None and link.index not in self.setup_links:
            return
        if not self.ep.allows(link):
            return
        initial = struct.unpack_from("<Q", p, 0)[0]
        self.set_key(p[10:42], initial)
        self._save()
        self.ep.statustext(NOTICE, b"Signing on" if self.enabled else b"Signing off")

    def set_key(self, key, timestamp=0):
        """Use this 32-byte key (all zeros: signing off), timestamp at least as given."""
        copy(self.key, key, 0, 32)
        if timestamp > _as_int(self.ts):
            _put(self.ts, 0, timestamp >> 24, timestamp & _LOW)
        self._clk_hi = _hi(self.ts, 0)
        self._clk_lo = _lo(self.ts, 0)
        self._clk_at = self.ep.now
        self._sync()
        if _newer(self._clk_hi, self._clk_lo, _hi(self.ts, 0), _lo(self.ts, 0)):
            _put(self.ts, 0, self._clk_hi, self._clk_lo)
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
        if len(data) != _FILE_LEN or checksum(data[:40]) != data[40] | data[41] << 8:
            self._warning = b"Signing key corrupt: signing off"
            return
        stored = int.from_bytes(data[32:40], "little")
        # Frames may have gone out up to a save interval past the stored timestamp;
        # saved at once, so that a quick second restart starts past this one.
        self.set_key(data[:32], stored + self.save_ms * 100)
        self._save()

    def _save(self):
        storage = getattr(self.ep, "storage", None)
        if storage is None:
            return
        data = bytearray(_FILE_LEN)
        copy(data, self.key, 0, 32)
        copy(data, self.ts, 32, 6)
        crc = checksum(memoryview(data)[:40])
        data[40] = crc & 0xFF
        data[41] = crc >> 8
        try:
            with storage.open_new(_FILE) as f:
                f.write(data)
            storage.commit(_FILE)
        except OSError:
            self.ep.statustext(WARNING, b"Signing key not saved")


def _newer(hi, lo, hi2, lo2):
    return hi > hi2 or (hi == hi2 and lo > lo2)


def create(ep):
    return ep.add(Signing(
        setup_links=ep.setting("SIGNING_SETUP_LINKS"),
        allow_unsigned=ep.setting("SIGNING_ALLOW_UNSIGNED", (0,)),
        save_ms=ep.setting("SIGNING_SAVE_MS", 60000),
    ))
