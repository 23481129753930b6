"""Parameter protocol: a table of named values a ground station lists, reads and sets.

A board (or application) declares its parameters once, as a tuple of tuples:

    from mavstack.services.params import REAL32, UINT8, INT32, READ_ONLY, REBOOT
    PARAMS = (
        # name (<= 16 chars), type, default, min, max, flags   (min/max/flags optional)
        ("WP_SPEED", REAL32, 5.0, 0.5, 30.0),
        ("FS_GCS_ENABLE", UINT8, 1, 0, 2),
        ("SERIAL1_BAUD", INT32, 57600, 1200, 921600, REBOOT),
    )

Types are MAV_PARAM_TYPE values. param_value is a 4-byte field, so the 64-bit types
(UINT64, INT64, REAL64) cannot travel and are refused at start-up.

Values live in one preallocated buffer, 4 bytes a parameter, in the form they travel:
integers bytewise (little-endian, in the low bytes: MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
what QGroundControl and MAVSDK expect from a generic autopilot), floats as IEEE754 bits.
With PARAM_ENCODING = "c_cast" a second buffer holds integers converted to floats for the
wire. Sending a PARAM_VALUE copies bytes; names are found through a crc16 hash of the
id's bytes, so lists, reads and their pacing allocate nothing.

Lists are paced per link to half its capacity so telemetry and commands keep flowing.
Values persist in storage file "params" (PREFLIGHT_STORAGE, or autosave after
PARAM_AUTOSAVE_MS), stored by name so that firmware updates keep the values of
parameters that remain.
"""
import struct

from ..compat import const, ticks_diff
from ..fields import u16, i16, u32, i32, cstr_len, f32_is_nan
from ..kernels import crc16, copy

# MAV_PARAM_TYPE
UINT8 = const(1)
INT8 = const(2)
UINT16 = const(3)
INT16 = const(4)
UINT32 = const(5)
INT32 = const(6)
UINT64 = const(7)
INT64 = const(8)
REAL32 = const(9)
REAL64 = const(10)

# flags
READ_ONLY = const(1)  # the application sets it; ground stations only read it
REBOOT = const(2)  # takes effect after a reboot (a STATUSTEXT says so when it changes)

_MSG_PARAM_REQUEST_READ = const(20)
_MSG_PARAM_REQUEST_LIST = const(21)
_MSG_PARAM_VALUE = const(22)
_MSG_PARAM_SET = const(23)

_CMD_DO_SET_PARAMETER = const(180)
_CMD_PREFLIGHT_STORAGE = const(245)

_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_UNSUPPORTED = const(3)
_RESULT_FAILED = const(4)

_SEVERITY_ERROR = const(3)
_SEVERITY_WARNING = const(4)
_SEVERITY_NOTICE = const(5)
_SEVERITY_INFO = const(6)

_CAP_PARAM_ENCODE_BYTEWISE = const(16)
_CAP_PARAM_ENCODE_C_CAST = const(131072)

_ID_LEN = const(16)
# Pacing: credit in thousandths of a byte; a link earns bytes_per_s / 2 of them per ms.
_BURST = const(128000)  # at most ~3 frames banked
_MAX_DT_MS = const(100)
_MAX_PER_TICK = const(4)

_FILE = "params"
_MAGIC = b"MSPR"
_FILE_VERSION = const(1)
_HEADER = const(8)  # magic, version, reserved, count (u16)

_INT_RANGE = {
    UINT8: (0, 0xFF),
    INT8: (-0x80, 0x7F),
    UINT16: (0, 0xFFFF),
    INT16: (-0x8000, 0x7FFF),
    UINT32: (0, 0xFFFFFFFF),
    INT32: (-0x80000000, 0x7FFFFFFF),
}


def _f32_key(b):
    """Float32 bits -> an int that orders like the float (-0.0 and 0.0 are both 0)."""
    return -(b & 0x7FFFFFFF) if b & 0x80000000 else b


def _key_bits(k):
    return k if k >= 0 else (-k) | 0x80000000


def _f32_whole(b):
    """The integer a float32 holds exactly, from its bits; None when it has a fraction."""
    e = (b >> 23) & 0xFF
    m = b & 0x7FFFFF
    if e == 0:
        return 0 if m == 0 else None
    shift = e - 150
    m |= 0x800000
    if shift >= 0:
        # Beyond 2**40 no parameter's range reaches: report it as out of range.
        v = m << shift if e < 167 else (1 << 40) - 1
    else:
        if shift < -24 or m & ((1 << -shift) - 1):
            return None
        v = m >> -shift
    return -v if b & 0x80000000 else v


def _get_int(buf, o, t):
    if t == UINT8:
        return buf[o]
    if t == INT8:
        v = buf[o]
        return v - 0x100 if v & 0x80 else v
    if t == UINT16:
        return u16(buf, o)
    if t == INT16:
        return i16(buf, o)
    if t == UINT32:
        return u32(buf, o)
    return i32(buf, o)


def _put_int(buf, o, t, v):
    """v in the type's low bytes, little-endian; unused bytes zero (the C union's layout)."""
    size = 1 if t <= INT8 else 2 if t <= INT16 else 4
    for k in range(4):
        buf[o + k] = (v >> (8 * k)) & 0xFF if k < size else 0


class Params:
    NAME = "params"

    def __init__(self, table, encoding="bytewise", autosave_ms=0, sysid_param=None):
        n = len(table)
        if n > 0xFFFF:
            raise ValueError("too many parameters")
        if encoding not in ("bytewise", "c_cast"):
            raise ValueError("PARAM_ENCODING is 'bytewise' or 'c_cast'")
        self.count = n
        self.c_cast = encoding == "c_cast"
        self.autosave_ms = autosave_ms
        self._sysid_param = sysid_param
        self._names = bytearray(_ID_LEN * n)  # NUL-padded, no NUL when 16 long
        self._lens = bytearray(n)
        self._types = bytearray(n)
        self._flags = bytearray(n)
        self._values = bytearray(4 * n)
        self._defaults = bytearray(4 * n)
        # c_cast: integers travel as floats, so the wire copy differs from the values.
        self._wire = bytearray(4 * n) if self.c_cast else self._values
        self._min = [0] * n  # range as keys: ints, or floats ordered by _f32_key
        self._max = [0] * n
        self._by_hash = {}  # crc16 of name -> first index with that hash
        self._next = [-1] * n  # -> next index with the same hash
        self._scratch = bytearray(4)
        for i in range(n):
            self._declare(i, table[i])
        self._values[:] = self._defaults
        if self.c_cast:
            self._rewire()
        self.on_change = None  # on_change(name, value): set over MAVLink or by a reload
        self.dirty = False  # changed since the last save or load
        self._changed_at = 0
        self._changed = False
        self.ep = None
        # per link: wanted PARAM_VALUEs (one byte per parameter), their count, scan
        # position, pacing credit and the time it was last earned
        self._want = []
        self._pending = []
        self._cursor = []
        self._credit = []
        self._last = []

    # --- declaration -------------------------------------------------------------
    def _declare(self, i, decl):
        name, t, default = decl[0], decl[1], decl[2]
        lo = decl[3] if len(decl) > 3 else None
        hi = decl[4] if len(decl) > 4 else None
        flags = decl[5] if len(decl) > 5 else 0
        raw = name.encode()
        if not 0 < len(raw) <= _ID_LEN:
            raise ValueError("param name must be 1..16 chars: %r" % name)
        if t in (UINT64, INT64, REAL64):
            raise ValueError("%s: 64-bit params do not fit PARAM_VALUE's 4 bytes" % name)
        if t != REAL32 and t not in _INT_RANGE:
            raise ValueError("%s: unknown MAV_PARAM_TYPE %r" % (name, t))
        if self._find(raw, 0, len(raw)) >= 0:
            raise ValueError("param declared twice: " + name)
        o = _ID_LEN * i
        for k in range(len(raw)):
            self._names[o + k] = raw[k]
        self._lens[i] = len(raw)
        self._types[i] = t
        self._flags[i] = flags
        h = crc16(raw, 0, len(raw), 0xFFFF)
        self._next[i] = self._by_hash.get(h, -1)
        self._by_hash[h] = i
        if t == REAL32:
            b = self._scratch
            struct.pack_into("<f", b, 0, -3.4028234e38 if lo is None else lo)
            self._min[i] = _f32_key(u32(b, 0))
            struct.pack_into("<f", b, 0, 3.4028234e38 if hi is None else hi)
            self._max[i] = _f32_key(u32(b, 0))
            struct.pack_into("<f", self._defaults, 4 * i, default)
            if not self._valid(i, self._defaults, 4 * i):
                raise ValueError("%s: default outside min..max" % name)
        else:
            tlo, thi = _INT_RANGE[t]
            lo = tlo if lo is None else int(lo)
            hi = thi if hi is None else int(hi)
            if not tlo <= lo <= hi <= thi:
                raise ValueError("%s: min..max outside the type's range" % name)
            if default != int(default):
                raise ValueError("%s: default is not a whole number" % name)
            if not lo <= default <= hi:
                raise ValueError("%s: default outside min..max" % name)
            self._min[i] = lo
            self._max[i] = hi
            _put_int(self._defaults, 4 * i, t, int(default))
        if self._min[i] > self._max[i]:
            raise ValueError("%s: min > max" % name)

    # --- service -----------------------------------------------------------------
    def attach(self, ep):
        self.ep = ep
        ep.on(_MSG_PARAM_REQUEST_LIST, self._on_list)
        ep.on(_MSG_PARAM_REQUEST_READ, self._on_read)
        ep.on(_MSG_PARAM_SET, self._on_set)
        ep.capabilities |= _CAP_PARAM_ENCODE_C_CAST if self.c_cast else _CAP_PARAM_ENCODE_BYTEWISE
        ep.commands[_CMD_DO_SET_PARAMETER] = self._do_set_parameter
        # A service attached later that also answers PREFLIGHT_STORAGE (missions: param2)
        # wraps this entry the same way.
        self._storage_next = ep.commands.get(_CMD_PREFLIGHT_STORAGE)
        ep.commands[_CMD_PREFLIGHT_STORAGE] = self._preflight_storage
        for link in ep.links:
            self._link_state(link)
        self._load(True)
        if self._sysid_param:
            self._set(self.index(self._sysid_param), ep.sysid)
            self.dirty = False

    def _link_state(self, link):
        while len(self._want) <= link.index:
            self._want.append(bytearray(self.count))
            self._pending.append(0)
            self._cursor.append(0)
            self._credit.append(_BURST)
            self._last.append(self.ep.now)

    def tick(self, now):
        links = self.ep.links
        for link in links:
            li = link.index
            if li >= len(self._pending) or self._pending[li] == 0:
                continue
            self._pace(li, link, now)
        if self.dirty and self.autosave_ms and ticks_diff(now, self._changed_at) >= self.autosave_ms:
            self.save()

    def _pace(self, li, link, now):
        dt = ticks_diff(now, self._last[li])
        self._last[li] = now
        rate = link.bytes_per_s >> 1 if link.bytes_per_s else 0
        credit = self._credit[li]
        if rate == 0:
            credit = _BURST
        elif dt > 0:
            credit += (dt if dt < _MAX_DT_MS else _MAX_DT_MS) * rate
            if credit > _BURST:
                credit = _BURST
        want = self._want[li]
        n = self.count
        i = self._cursor[li]
        sent = 0
        while credit > 0 and sent < _MAX_PER_TICK and self._pending[li]:
            # Next wanted index at or after the cursor, wrapping: lists go out in order.
            for _ in range(n):
                if i >= n:
                    i = 0
                if want[i]:
                    break
                i += 1
            before = link.tx_bytes
            if not self._send(link, i):
                break  # the transport is full: retry on a later tick
            credit -= (link.tx_bytes - before) * 1000
            want[i] = 0
            self._pending[li] -= 1
            i += 1
            sent += 1
        self._cursor[li] = i
        self._credit[li] = credit

    def _send(self, link, i):
        """One PARAM_VALUE for parameter i, copied straight from the tables."""
        off = link.begin()
        buf = link.txbuf
        copy(buf, self._wire, off | (4 * i) << 10, 4)
        struct.pack_into("<HH", buf, off + 4, self.count, i)
        copy(buf, self._names, (off + 8) | (_ID_LEN * i) << 10, _ID_LEN)
        buf[off + 24] = self._types[i]
        return link.send(_MSG_PARAM_VALUE)

    def _reply(self, link, i):
        """Send at once (an answer), charged to the link's pacing credit."""
        li = link.index
        if li >= len(self._credit):
            self._link_state(link)
        before = link.tx_bytes
        self._send(link, i)
        credit = self._credit[li] - (link.tx_bytes - before) * 1000
        self._credit[li] = credit if credit > -_BURST else -_BURST

    def _announce(self, i, skip=None):
        """Queue parameter i on every link (but skip), paced like a list."""
        for link in self.ep.links:
            if link is skip:
                continue
            li = link.index
            if li >= len(self._want):
                self._link_state(link)
            want = self._want[li]
            if not want[i]:
                want[i] = 1
                self._pending[li] += 1

    # --- protocol ----------------------------------------------------------------
    def _on_list(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        li = link.index
        if li >= len(self._want):
            self._link_state(link)
        want = self._want[li]
        for i in range(self.count):
            want[i] = 1
        self._pending[li] = self.count
        self._cursor[li] = 0

    def _on_read(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        index = i16(p, 0)
        if index < 0:
            i = self._find(p, 4, cstr_len(p, 4, _ID_LEN))
            if i < 0:
                self._unknown(p, 4)
                return
        elif index < self.count:
            i = index
        else:
            self.ep.statustext(_SEVERITY_WARNING, b"param index unknown")
            return
        self._reply(link, i)

    def _on_set(self, link, p):
        if not self.ep.for_us(p[4], p[5]):
            return
        i = self._find(p, 6, cstr_len(p, 6, _ID_LEN))
        if i < 0:
            self._unknown(p, 6)
            return
        t = self._types[i]
        ptype = p[22]
        if not self.ep.allows(link):
            why = "not in control"
        elif self._flags[i] & READ_ONLY:
            why = "read-only"
        elif ptype != t and not (self.c_cast and ptype == REAL32):
            # Bytewise, the type says how to read the bytes: a mismatch would misread them.
            why = "type %d, expected %d" % (ptype, t)
        else:
            why = self._accept(i, p, 0, self.c_cast or t == REAL32)
        if why is not None:
            self._reply(link, i)
            self._refused(i, why)
            return
        self._reply(link, i)
        self._announce(i, link)
        self._after_change(i)

    def _do_set_parameter(self, cmd):
        """MAV_CMD_DO_SET_PARAMETER: param1 the parameter's index, param2 its value."""
        if cmd.nan(1) or cmd.nan(2):
            return _RESULT_DENIED
        i = cmd.int(1)
        if not 0 <= i < self.count:
            self.ep.statustext(_SEVERITY_WARNING, "param index %d unknown (%d params)" % (i, self.count))
            return _RESULT_DENIED
        if not self.ep.allows(cmd.link):
            why = "not in control"
        elif self._flags[i] & READ_ONLY:
            why = "read-only"
        else:
            # Command parameters are floats carrying the value itself (C-cast); param2 at byte 4.
            why = self._accept(i, cmd.payload, 4, True)
        if why is not None:
            self._refused(i, why)
            return _RESULT_DENIED
        self._announce(i)
        self._after_change(i)
        return _RESULT_ACCEPTED

    def _preflight_storage(self, cmd):
        result = _RESULT_ACCEPTED
        if not cmd.nan(1):
            result = self.persist(cmd.int(1), cmd.link)
        if self._storage_next is not None:
            other = self._storage_next(cmd)
            if other != _RESULT_ACCEPTED and result == _RESULT_ACCEPTED:
                result = other
        return result

    def persist(self, action, link=None):
        """PREFLIGHT_STORAGE param1: 0 reload, 1 save, 2/4 reset to defaults -> MAV_RESULT."""
        if action == 1:
            return _RESULT_ACCEPTED if self.save() else _RESULT_FAILED
        if action not in (0, 2, 4):
            # 3 resets sensor calibration only: there is none here.
            return _RESULT_UNSUPPORTED if action == 3 else _RESULT_DENIED
        if link is not None and not self.ep.allows(link):
            return _RESULT_DENIED
        if action == 0:
            return _RESULT_ACCEPTED if self._load(False) else _RESULT_FAILED
        self._adopt(bytearray(self._defaults), False)
        self.ep.statustext(_SEVERITY_NOTICE, "params reset to defaults")
        return _RESULT_ACCEPTED

    def _unknown(self, p, o):
        name = bytes(p[o : o + cstr_len(p, o, _ID_LEN)])
        self.ep.statustext(_SEVERITY_WARNING, "unknown param %s" % name.decode("ascii", "replace"))

    def _refused(self, i, why):
        self.ep.statustext(_SEVERITY_WARNING, "%s not set: %s" % (self.name(i), why))

    def _after_change(self, i):
        if not self._changed:
            return
        self.dirty = True
        self._changed_at = self.ep.now
        if self._flags[i] & REBOOT:
            self.ep.statustext(_SEVERITY_NOTICE, "%s applies after reboot" % self.name(i))
        if self.on_change is not None:
            self.on_change(self.name(i), self.value(i))

    # --- values ------------------------------------------------------------------
    def _find(self, src, o, n):
        """Index of the parameter named src[o:o+n], else -1 (no allocation)."""
        if n == 0:
            return -1
        i = self._by_hash.get(crc16(src, o, o + n, 0xFFFF), -1)
        names = self._names
        while i >= 0:
            if self._lens[i] == n:
                base = _ID_LEN * i
                k = 0
                while k < n and names[base + k] == src[o + k]:
                    k += 1
                if k == n:
                    return i
            i = self._next[i]
        return -1

    def _key(self, i, src, o, cast):
        """The value at src[o:o+4] as an ordered key for parameter i (None: not whole).

        cast: the bytes are a float holding the value (C-cast, command params); else
        they are in the parameter's own encoding.
        """
        t = self._types[i]
        if t == REAL32:
            return _f32_key(u32(src, o))
        if cast:
            return _f32_whole(u32(src, o))
        return _get_int(src, o, t)

    def _valid(self, i, src, o):
        if self._types[i] == REAL32 and (src[o + 3] & 0x7F) == 0x7F and src[o + 2] & 0x80:
            return False  # NaN or infinity
        k = self._key(i, src, o, False)
        return self._min[i] <= k <= self._max[i]

    def _accept(self, i, src, o, cast):
        """Store src[o:o+4] into parameter i if valid -> None, else the reason."""
        t = self._types[i]
        if t == REAL32 or cast:
            if f32_is_nan(src, o):
                return "NaN"
            if (src[o + 3] & 0x7F) == 0x7F and src[o + 2] & 0x80:
                return "not finite"
        k = self._key(i, src, o, cast)
        if k is None:
            return "not a whole number"
        if not self._min[i] <= k <= self._max[i]:
            return "out of range %s..%s" % (self._show(i, self._min[i]), self._show(i, self._max[i]))
        self._store(i, k)
        return None

    def _store(self, i, k):
        """Parameter i := key k (already checked); sets _changed."""
        t = self._types[i]
        vo = 4 * i
        values = self._values
        old = u32(values, vo)
        if t == REAL32:
            b = _key_bits(k)
            for j in range(4):
                values[vo + j] = (b >> (8 * j)) & 0xFF
        else:
            _put_int(values, vo, t, k)
        self._changed = u32(values, vo) != old
        if self.c_cast:
            if t == REAL32:
                copy(self._wire, values, vo | vo << 10, 4)
            else:
                struct.pack_into("<f", self._wire, vo, k)

    def _show(self, i, k):
        if self._types[i] != REAL32:
            return k
        b = self._scratch
        struct.pack_into("<I", b, 0, _key_bits(k))
        return "%g" % struct.unpack_from("<f", b, 0)[0]

    def _adopt(self, values, saved):
        """Take a whole set of values (reload, reset): announce and report what changed."""
        changed = []
        for i in range(self.count):
            vo = 4 * i
            if u32(values, vo) != u32(self._values, vo):
                self._store(i, self._key(i, values, vo, False))
                self._announce(i)
                changed.append(i)
        if changed:
            self.dirty = not saved
            self._changed_at = self.ep.now
            if self.on_change is not None:
                for i in changed:
                    self.on_change(self.name(i), self.value(i))

    # --- application API -----------------------------------------------------------
    def index(self, name):
        """Index of a parameter by name (once, at start-up); KeyError if not declared."""
        raw = name.encode()
        i = self._find(raw, 0, len(raw))
        if i < 0:
            raise KeyError(name)
        return i

    def name(self, i):
        o = _ID_LEN * i
        return bytes(self._names[o : o + self._lens[i]]).decode()

    def type(self, i):
        return self._types[i]

    def value(self, i):
        """Parameter i's value: an int, or a float (a new object on MicroPython)."""
        t = self._types[i]
        if t == REAL32:
            return struct.unpack_from("<f", self._values, 4 * i)[0]
        return _get_int(self._values, 4 * i, t)

    def get(self, name):
        return self.value(self.index(name))

    def set(self, name, value):
        """Set from the application (read-only ones too); announced on every link.

        ValueError when out of range or not representable. True if the value changed.
        """
        return self._set(self.index(name), value)

    def _set(self, i, value):
        b = self._scratch
        t = self._types[i]
        if t == REAL32:
            struct.pack_into("<f", b, 0, value)
        else:
            if value != int(value):
                raise ValueError("%s: not a whole number" % self.name(i))
            v = int(value)
            lo, hi = _INT_RANGE[t]
            if not lo <= v <= hi:
                raise ValueError("%s: %d does not fit its type" % (self.name(i), v))
            _put_int(b, 0, t, v)
        why = self._accept(i, b, 0, False)
        if why is not None:
            raise ValueError("%s: %s" % (self.name(i), why))
        if self._changed and self.ep is not None:
            self.dirty = True
            self._changed_at = self.ep.now
            self._announce(i)
        return self._changed

    # --- storage -------------------------------------------------------------------
    def save(self):
        """Write every value, by name, to storage "params" atomically -> success."""
        storage = getattr(self.ep, "storage", None)
        if storage is None:
            return False
        size = _HEADER
        for i in range(self.count):
            size += 6 + self._lens[i]
        data = bytearray(size + 2)
        data[0:4] = _MAGIC
        data[4] = _FILE_VERSION
        struct.pack_into("<H", data, 6, self.count)
        o = _HEADER
        for i in range(self.count):
            n = self._lens[i]
            data[o] = n
            for k in range(n):
                data[o + 1 + k] = self._names[_ID_LEN * i + k]
            o += 1 + n
            data[o] = self._types[i]
            for k in range(4):
                data[o + 1 + k] = self._values[4 * i + k]
            o += 5
        struct.pack_into("<H", data, o, crc16(data, 0, o, 0xFFFF))
        try:
            f = storage.open_new(_FILE)
            try:
                f.write(data)
            finally:
                f.close()
            storage.commit(_FILE)
        except OSError as e:
            self.ep.statustext(_SEVERITY_ERROR, "params not saved: %s" % e)
            return False
        self.dirty = False
        return True

    def _load(self, boot):
        """Read storage "params". At boot a missing or corrupt file means defaults;
        a reload keeps the values in force when the file is unusable -> success."""
        storage = getattr(self.ep, "storage", None)
        values = bytearray(self._defaults)
        data = None
        why = None
        if storage is None:
            why = "no storage"
        else:
            if boot:
                storage.discard_new(_FILE)  # a save cut short: the old file stands
            try:
                f = storage.open(_FILE)
                try:
                    data = f.read()
                finally:
                    f.close()
            except OSError:
                why = "none stored"
        bad = 0
        if data is not None:
            bad = self._parse(data, values)
            if bad < 0:
                why = "stored file corrupt"
        if why is not None:
            if boot:
                self._values[:] = self._defaults
                if self.c_cast:
                    self._rewire()
                sev = _SEVERITY_INFO if why == "none stored" else _SEVERITY_WARNING
                self.ep.statustext(sev, "params: %s, using defaults" % why)
            else:
                self.ep.statustext(_SEVERITY_WARNING, "params not reloaded: %s" % why)
            return False
        if boot:
            self._values[:] = values
            if self.c_cast:
                self._rewire()
        else:
            self._adopt(values, True)
        self.dirty = False
        if bad:
            self.ep.statustext(_SEVERITY_NOTICE, "params: %d stored values invalid, defaults used" % bad)
        return True

    def _parse(self, data, values):
        """Fill values from a stored file -> how many records were invalid, -1 if corrupt."""
        end = len(data) - 2
        if end < _HEADER or data[0:4] != _MAGIC or data[4] != _FILE_VERSION:
            return -1
        if crc16(data, 0, end, 0xFFFF) != u16(data, end):
            return -1
        count = u16(data, 6)
        o = _HEADER
        bad = 0
        for _ in range(count):
            if o >= end:
                return -1
            n = data[o]
            if n == 0 or n > _ID_LEN or o + 1 + n + 5 > end:
                return -1
            i = self._find(data, o + 1, n)
            o += 1 + n
            if i >= 0:
                # A changed type or a value now out of range keeps the default.
                if data[o] == self._types[i] and self._valid(i, data, o + 1):
                    for k in range(4):
                        values[4 * i + k] = data[o + 1 + k]
                else:
                    bad += 1
            o += 5
        return bad if o == end else -1

    def _rewire(self):
        for i in range(self.count):
            vo = 4 * i
            self._store(i, self._key(i, self._values, vo, False))


def create(ep):
    board = getattr(ep, "board", None)
    options = getattr(ep, "options", None) or {}

    def setting(name, default):
        # --set param_encoding=c_cast overrides the profile's PARAM_ENCODING
        value = options.get(name.lower())
        if value is None:
            return getattr(board, name, default)
        return int(value) if isinstance(default, int) else value

    params = Params(
        getattr(board, "PARAMS", ()),
        setting("PARAM_ENCODING", "bytewise"),
        setting("PARAM_AUTOSAVE_MS", 0),
        getattr(board, "PARAM_SYSID", None),
    )
    return ep.add(params)
