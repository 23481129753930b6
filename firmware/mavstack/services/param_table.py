"""A parameter table: names, types, ranges and values in a few flat buffers.

Declared once, as a tuple of rows (see services/params.py for the format). Each
value takes 4 bytes, in the form it travels in PARAM_VALUE's param_value: integers
bytewise (little-endian in the low bytes, the rest zero, like the C union), floats
as IEEE754 bits. Names are found through a crc16 of the id's bytes and one compare,
so a lookup from a received frame allocates nothing. Ranges are kept as ordered
integer keys (float bits mapped to sortable ints), so checks need no float objects.

The file image (pack/unpack) stores values by name, so that a firmware with
parameters added or removed keeps the values of those that remain.
"""
import struct

from ..compat import const
from ..fields import u16, i16, u32, i32, f32_is_nan
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
REBOOT = const(2)  # takes effect after a reboot

ID_LEN = const(16)
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


def _not_finite(src, o):
    return (src[o + 3] & 0x7F) == 0x7F and src[o + 2] & 0x80


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
    size = 1 if t <= INT8 else 2 if t <= INT16 else 4
    for k in range(4):
        buf[o + k] = (v >> (8 * k)) & 0xFF if k < size else 0


class ParamTable:
    def __init__(self, table, c_cast=False):
        n = len(table)
        if n > 0xFFFF:
            raise ValueError("too many parameters")
        self.count = n
        self.c_cast = c_cast
        self.changed = False  # set by store(): the last store changed the value
        self._names = bytearray(ID_LEN * n)  # NUL-padded, no NUL when 16 long
        self._lens = bytearray(n)
        self._types = bytearray(n)
        self._flags = bytearray(n)
        self._values = bytearray(4 * n)
        self._defaults = bytearray(4 * n)
        # C-cast: integers travel as floats, so the wire copy differs from the values.
        self._wire = bytearray(4 * n) if c_cast else self._values
        self._min = [0] * n  # ranges as keys: ints, or floats ordered by _f32_key
        self._max = [0] * n
        self._by_hash = {}  # crc16 of a name -> first index with that hash
        self._next = [-1] * n  # -> next index with the same hash
        self._scratch = bytearray(4)
        for i in range(n):
            self._declare(i, table[i])
        self.adopt(self._defaults)

    def _declare(self, i, row):
        name, t, default = row[0], row[1], row[2]
        lo = row[3] if len(row) > 3 else None
        hi = row[4] if len(row) > 4 else None
        raw = name.encode()
        if not 0 < len(raw) <= ID_LEN or any(c <= 0x20 or c > 0x7E for c in raw):
            raise ValueError("param name must be 1..16 printable ASCII chars: %r" % name)
        if t in (UINT64, INT64, REAL64):
            raise ValueError("%s: 64-bit params do not fit PARAM_VALUE's 4 bytes" % name)
        if t != REAL32 and t not in _INT_RANGE:
            raise ValueError("%s: unknown MAV_PARAM_TYPE %r" % (name, t))
        if self.find(raw, 0, len(raw)) >= 0:
            raise ValueError("param declared twice: " + name)
        o = ID_LEN * i
        for k in range(len(raw)):
            self._names[o + k] = raw[k]
        self._lens[i] = len(raw)
        self._types[i] = t
        self._flags[i] = row[5] if len(row) > 5 else 0
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
            if self._min[i] > self._max[i] or not self.valid(i, self._defaults, 4 * i):
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

    def find(self, src, o, n):
        """Index of the parameter named src[o:o+n], else -1 (allocates nothing)."""
        if n == 0:
            return -1
        i = self._by_hash.get(crc16(src, o, o + n, 0xFFFF), -1)
        names = self._names
        while i >= 0:
            if self._lens[i] == n:
                base = ID_LEN * i
                k = 0
                while k < n and names[base + k] == src[o + k]:
                    k += 1
                if k == n:
                    return i
            i = self._next[i]
        return -1

    def _key(self, i, src, o, cast):
        """src[o:o+4] as an ordered key for parameter i (None: not a whole number).

        cast: the bytes are a float holding the value (C-cast, command parameters);
        else they are in the parameter's own encoding.
        """
        t = self._types[i]
        if t == REAL32:
            return _f32_key(u32(src, o))
        if cast:
            return _f32_whole(u32(src, o))
        return _get_int(src, o, t)

    def valid(self, i, src, o):
        """src[o:o+4], in the parameter's own encoding, is a value it may take."""
        if self._types[i] == REAL32 and _not_finite(src, o):
            return False
        return self._min[i] <= self._key(i, src, o, False) <= self._max[i]

    def accept(self, i, src, o, cast):
        """Store src[o:o+4] into parameter i if it is a value it may take -> None,
        else why not. self.changed tells whether the value changed."""
        self.changed = False
        if (self._types[i] == REAL32 or cast) and _not_finite(src, o):
            return "NaN" if f32_is_nan(src, o) else "not finite"
        k = self._key(i, src, o, cast)
        if k is None:
            return "not a whole number"
        if not self._min[i] <= k <= self._max[i]:
            return "out of range %s..%s" % (self._show(i, self._min[i]), self._show(i, self._max[i]))
        self._store(i, k)
        return None

    def _store(self, i, k):
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
        self.changed = u32(values, vo) != old
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

    def adopt(self, values):
        """Take a whole set of checked values -> indexes of those that changed."""
        changed = []
        for i in range(self.count):
            vo = 4 * i
            if u32(values, vo) != u32(self._values, vo) or self._wire is not self._values:
                self._store(i, self._key(i, values, vo, False))
                if self.changed:
                    changed.append(i)
        return changed

    # --- for the application ---------------------------------------------------------
    def index(self, name):
        """Index of a parameter by name (look it up once); KeyError if not declared."""
        raw = name.encode()
        i = self.find(raw, 0, len(raw))
        if i < 0:
            raise KeyError(name)
        return i

    def name(self, i):
        o = ID_LEN * i
        return bytes(self._names[o : o + self._lens[i]]).decode()

    def type(self, i):
        return self._types[i]

    def flags(self, i):
        return self._flags[i]

    def value(self, i):
        """Parameter i's value: an int, or a float (a new object on MicroPython)."""
        t = self._types[i]
        if t == REAL32:
            return struct.unpack_from("<f", self._values, 4 * i)[0]
        return _get_int(self._values, 4 * i, t)

    def get(self, name):
        return self.value(self.index(name))

    def put(self, i, value):
        """Parameter i := value (read-only ones too) -> changed; ValueError if it may not."""
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
        why = self.accept(i, b, 0, False)
        if why is not None:
            raise ValueError("%s: %s" % (self.name(i), why))
        return self.changed

    # --- file image --------------------------------------------------------------------
    def pack(self):
        """The values as a file: header, (name, type, value) records, crc16."""
        size = _HEADER + 2
        for i in range(self.count):
            size += 6 + self._lens[i]
        data = bytearray(size)
        data[0:4] = _MAGIC
        data[4] = _FILE_VERSION
        struct.pack_into("<H", data, 6, self.count)
        o = _HEADER
        for i in range(self.count):
            n = self._lens[i]
            data[o] = n
            for k in range(n):
                data[o + 1 + k] = self._names[ID_LEN * i + k]
            o += 1 + n
            data[o] = self._types[i]
            for k in range(4):
                data[o + 1 + k] = self._values[4 * i + k]
            o += 5
        struct.pack_into("<H", data, o, crc16(data, 0, o, 0xFFFF))
        return data

    def unpack(self, data):
        """Values from a file (defaults where it has none) and how many of its records
        no longer fit (type changed, out of range); (None, 0) if it is corrupt."""
        values = bytearray(self._defaults)
        end = len(data) - 2
        if end < _HEADER or data[0:4] != _MAGIC or data[4] != _FILE_VERSION:
            return None, 0
        if crc16(data, 0, end, 0xFFFF) != u16(data, end):
            return None, 0
        o = _HEADER
        bad = 0
        for _ in range(u16(data, 6)):
            n = data[o] if o < end else 0
            if n == 0 or n > ID_LEN or o + 1 + n + 5 > end:
                return None, 0
            i = self.find(data, o + 1, n)
            o += 1 + n
            if i >= 0:
                if data[o] == self._types[i] and self.valid(i, data, o + 1):
                    for k in range(4):
                        values[4 * i + k] = data[o + 1 + k]
                else:
                    bad += 1
            o += 5
        if o != end:
            return None, 0
        return values, bad
