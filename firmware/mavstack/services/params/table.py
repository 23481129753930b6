"""A parameter table: names, types, ranges and values in a few flat buffers.

Declared once, as a tuple of rows (see services/params.py for the format). Each
value takes 4 bytes, in the form it travels in PARAM_VALUE's param_value: integers
bytewise (little-endian in the low bytes, the rest zero, like the C union), floats
as IEEE754 bits. Names are found through a crc16 of the id's bytes and one compare,
so a lookup from a received frame allocates nothing.

32-bit clean: on a 32-bit MicroPython an int of 2**30 or more (or below -2**30) is a
heap object, and uint32/int32 values, float bits and the ranges reach that far. So
no such value is ever a Python int here: checks work on 4-byte *keys*, the value
mapped to an unsigned 32-bit number that orders like the value (the sign bit flipped
for signed integers; for floats, positives get the top bit set and negatives are
inverted), compared 16 bits at a time. Conversions between floats and integers
(C-cast encoding, command parameters) are done on the bytes, in 16-bit halves.

The file image (pack/unpack) stores values by name, so that a firmware with
parameters added or removed keeps the values of those that remain. It is built in
and read from one buffer made at start-up, the packed table's size.
"""
import struct

from ...compat import const
from ...fields import u16, i16, u32, i32, f32_is_nan
from ...kernels import crc16

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
# The integer types up to INT32 are signed when even, unsigned when odd.

# flags
READ_ONLY = const(1)  # the application sets it; ground stations only read it
REBOOT = const(2)  # takes effect after a reboot

ID_LEN = const(16)
_MAGIC = b"MSPR"
_FILE_VERSION = const(1)
_HEADER = const(8)  # magic, version, reserved, count (u16)

# What a value is as a key (_key, _cast_key): fine, or why it has none.
_FRACTION = const(2)  # a float with a fraction where an integer is wanted
_OUTSIDE = const(3)  # beyond the 32-bit type: out of range whatever the limits
_NEG = const(1)  # _whole: a negative magnitude (internal)

_INT_RANGE = {  # declaration and application checks only (start-up, put)
    UINT8: (0, 0xFF),
    INT8: (-0x80, 0x7F),
    UINT16: (0, 0xFFFF),
    INT16: (-0x8000, 0x7FFF),
    UINT32: (0, 0xFFFFFFFF),
    INT32: (-0x80000000, 0x7FFFFFFF),
}


# --- 32-bit numbers as 4 little-endian bytes ------------------------------------------

def _put_halves(b, hi, lo):
    b[0] = lo & 0xFF
    b[1] = lo >> 8
    b[2] = hi & 0xFF
    b[3] = hi >> 8


def _cmp(a, ao, b, bo):
    """a[ao:ao+4] - b[bo:bo+4] as unsigned 32-bit numbers, by sign only."""
    d = (a[ao + 3] << 8 | a[ao + 2]) - (b[bo + 3] << 8 | b[bo + 2])
    if d == 0:
        d = (a[ao + 1] << 8 | a[ao]) - (b[bo + 1] << 8 | b[bo])
    return d


def _copy4(dst, do, src, so):
    """dst[do:do+4] := src[so:so+4]."""
    dst[do] = src[so]
    dst[do + 1] = src[so + 1]
    dst[do + 2] = src[so + 2]
    dst[do + 3] = src[so + 3]


def _move(dst, do, src, so, n):
    """dst[do:do+n] := src[so:so+n], at offsets of any size (kernels.copy packs its
    offsets into 10 bits)."""
    n += so
    while so < n:
        dst[do] = src[so]
        do += 1
        so += 1


def _from_2_31(k):
    """k := 2**31 - k, for k <= 2**31. Its own inverse: it turns the magnitude of a
    negative int into the int's key and back."""
    hi = k[3] << 8 | k[2]
    lo = k[1] << 8 | k[0]
    if lo:
        hi += 1
        lo = 0x10000 - lo
    _put_halves(k, 0x8000 - hi, lo)


# --- keys -----------------------------------------------------------------------------

def _size(t):
    return 1 if t <= INT8 else 2 if t <= INT16 else 4


def _int_key(t, src, o, k):
    """k := the key of the type-t integer in src[o:] (its low bytes; the rest ignored)."""
    size = _size(t)
    # Signed: sign-extended to 32 bits, then the sign bit flipped.
    fill = 0xFF if not t & 1 and src[o + size - 1] & 0x80 else 0
    for j in range(4):
        k[j] = src[o + j] if j < size else fill
    if not t & 1:
        k[3] ^= 0x80


def _int_unkey(t, k, dst):
    """dst[0:4] := the type-t integer (low bytes, the rest zero) whose key is k."""
    size = _size(t)
    for j in range(4):
        dst[j] = k[j] if j < size else 0
    if size == 4 and not t & 1:
        dst[3] ^= 0x80


def _f32_key(src, o, k):
    """k := the key of the float32 bits src[o:o+4]; -0.0 gets 0.0's (and is stored as 0.0)."""
    b3 = src[o + 3]
    x = 0xFF if b3 & 0x80 and (b3 & 0x7F | src[o + 2] | src[o + 1] | src[o]) else 0
    for j in range(4):
        k[j] = src[o + j] ^ x
    if not x:
        k[3] |= 0x80


def _f32_unkey(k, dst):
    x = 0 if k[3] & 0x80 else 0xFF
    for j in range(4):
        dst[j] = k[j] ^ x
    if not x:
        dst[3] &= 0x7F


def _not_finite(src, o):
    return (src[o + 3] & 0x7F) == 0x7F and src[o + 2] & 0x80


def _scaled(k, m, s):
    """k := m * 2**s as a 32-bit magnitude (m: a float32's 24-bit significand) -> 0,
    _FRACTION or _OUTSIDE (2**32 or more). Never makes an int past 2**24."""
    if s > 8:
        return _OUTSIDE
    if s >= 0:
        _put_halves(k, m >> (16 - s), (m & (0xFFFF >> s)) << s)
        return 0
    if s < -23 or m & ((1 << -s) - 1):
        return _FRACTION
    m >>= -s
    _put_halves(k, m >> 16, m & 0xFFFF)
    return 0


def _whole(src, o, k):
    """k := |the integer float32 src[o:o+4] holds| -> 0, _NEG (nonzero, negative),
    _FRACTION or _OUTSIDE. NaN and infinities are the caller's to refuse first."""
    e = (src[o + 3] & 0x7F) << 1 | src[o + 2] >> 7
    m = (src[o + 2] & 0x7F) << 16 | src[o + 1] << 8 | src[o]
    if e == 0:  # zero, or a subnormal (a fraction)
        _put_halves(k, 0, 0)
        return _FRACTION if m else 0
    r = _scaled(k, m | 0x800000, e - 150)
    return _NEG if r == 0 and src[o + 3] & 0x80 else r


def _cast_key(t, src, o, k):
    """k := the key of the integer float32 src[o:o+4] holds, for integer type t ->
    0, _FRACTION or _OUTSIDE (the 32-bit type cannot hold it)."""
    r = _whole(src, o, k)
    if r > _NEG:
        return r
    if t & 1:  # unsigned
        return _OUTSIDE if r == _NEG else 0
    if r == _NEG:  # -2**31 at most
        if k[3] > 0x80 or (k[3] == 0x80 and k[2] | k[1] | k[0]):
            return _OUTSIDE
        _from_2_31(k)
    elif k[3] & 0x80:  # 2**31 - 1 at most
        return _OUTSIDE
    else:
        k[3] |= 0x80
    return 0


# --- integers to float32 bits (C-cast encoding) --------------------------------------

def _bitlen(x):
    n = 0
    while x:
        x >>= 1
        n += 1
    return n


def _bits32(m):
    """How many bits the 32-bit number m[0:4] has."""
    hi = m[3] << 8 | m[2]
    return _bitlen(hi) + 16 if hi else _bitlen(m[1] << 8 | m[0])


def _top24(m, n):
    """The top 24 bits of the n-bit number m[0:4], rounded to nearest, ties to even
    (C's int -> float conversion); 2**24 when rounding carries out."""
    hi = m[3] << 8 | m[2]
    lo = m[1] << 8 | m[0]
    if n <= 24:
        return (hi << 16 | lo) << (24 - n)
    s = n - 24  # 1..8 bits dropped, all from lo
    f = hi << (16 - s) | lo >> s
    return _round(f, lo, s)


def _round(f, lo, s):
    """f, the bits kept, rounded by the s bits dropped from lo."""
    dropped = lo & ((1 << s) - 1)
    half = 1 << (s - 1)
    if dropped > half or (dropped == half and f & 1):
        return f + 1
    return f


def _int_f32(dst, o, m):
    """dst[o:o+4] := float32 bits of the (non-negative) integer m[0:4]."""
    n = _bits32(m)
    f = _top24(m, n)
    if f >> 24:  # rounding carried: one bit longer
        f >>= 1
        n += 1
    e = n + 126 if f else 0
    dst[o] = f & 0xFF
    dst[o + 1] = (f >> 8) & 0xFF
    dst[o + 2] = (f >> 16) & 0x7F | (e & 1) << 7
    dst[o + 3] = e >> 1


# --- Python ints (declaration, application, messages: may allocate) -------------------

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
    size = _size(t)
    for k in range(4):
        buf[o + k] = (v >> (8 * k)) & 0xFF if k < size else 0


class ParamTable:
    def __init__(self, table, c_cast=False):
        n = len(table)
        if n > 0xFFFF:
            raise ValueError("too many parameters")
        self.count = n
        self.c_cast = c_cast
        self.changed = False  # set by accept(): the value changed
        self._names = bytearray(ID_LEN * n)  # NUL-padded, no NUL when 16 long
        self._lens = bytearray(n)
        self._types = bytearray(n)
        self._flags = bytearray(n)
        self._values = bytearray(4 * n)
        self._defaults = bytearray(4 * n)
        # C-cast: integers travel as floats, so the wire copy differs from the values.
        self._wire = bytearray(4 * n) if c_cast else self._values
        self._lo = bytearray(4 * n)  # ranges, as keys
        self._hi = bytearray(4 * n)
        self._by_hash = {}  # crc16 of a name -> first index with that hash
        self._next = [-1] * n  # -> next index with the same hash
        self._k = bytearray(4)  # the key being checked
        self._scratch = bytearray(4)
        self._mark = bytearray(n)  # adopt(): which values changed
        self._loaded = bytearray(4 * n)  # unpack(): the values of a file
        self._bad = 0
        size = _HEADER + 2
        for i in range(n):
            self._declare(i, table[i])
            size += 6 + self._lens[i]
        self._image = bytearray(size)  # pack() writes the file here, _load reads it here
        self.adopt(self._defaults)

    def _declare(self, i, row):
        name, t, default = row[0], row[1], row[2]
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
        lo = row[3] if len(row) > 3 else None
        hi = row[4] if len(row) > 4 else None
        if t == REAL32:
            self._declare_f32(i, name, default, lo, hi)
        else:
            self._declare_int(i, name, default, lo, hi)

    def _declare_f32(self, i, name, default, lo, hi):
        b = self._scratch
        struct.pack_into("<f", b, 0, -3.4028234e38 if lo is None else lo)
        _f32_key(b, 0, self._k)
        _copy4(self._lo, 4 * i, self._k, 0)
        struct.pack_into("<f", b, 0, 3.4028234e38 if hi is None else hi)
        _f32_key(b, 0, self._k)
        _copy4(self._hi, 4 * i, self._k, 0)
        struct.pack_into("<f", self._defaults, 4 * i, default)
        if _cmp(self._lo, 4 * i, self._hi, 4 * i) > 0 or not self.valid(i, self._defaults, 4 * i):
            raise ValueError("%s: default outside min..max" % name)

    def _declare_int(self, i, name, default, lo, hi):
        t = self._types[i]
        tlo, thi = _INT_RANGE[t]
        lo = tlo if lo is None else int(lo)
        hi = thi if hi is None else int(hi)
        if not tlo <= lo <= hi <= thi:
            raise ValueError("%s: min..max outside the type's range" % name)
        if default != int(default):
            raise ValueError("%s: default is not a whole number" % name)
        if not lo <= default <= hi:
            raise ValueError("%s: default outside min..max" % name)
        b = self._scratch
        _put_int(b, 0, t, lo)
        _int_key(t, b, 0, self._k)
        _copy4(self._lo, 4 * i, self._k, 0)
        _put_int(b, 0, t, hi)
        _int_key(t, b, 0, self._k)
        _copy4(self._hi, 4 * i, self._k, 0)
        _put_int(self._defaults, 4 * i, t, int(default))

    def find(self, src, o, n):
        """Index of the parameter named src[o:o+n], else -1 (allocates nothing)."""
        if n == 0:
            return -1
        i = crc16(src, o, o + n, 0xFFFF)
        i = self._by_hash.get(i, -1)
        while i >= 0 and not self._named(i, src, o, n):
            i = self._next[i]
        return i

    def _named(self, i, src, o, n):
        if self._lens[i] != n:
            return False
        names = self._names
        d = ID_LEN * i - o  # names[k + d] is the name's byte for src[k]
        end = o + n
        while o < end and names[o + d] == src[o]:
            o += 1
        return o == end

    # --- checks (allocate nothing, whatever the value) --------------------------------
    def _key(self, i, src, o, cast):
        """self._k := src[o:o+4] as parameter i's key -> 0, else _FRACTION or _OUTSIDE.

        cast: the bytes are a float holding the value (C-cast, command parameters);
        else they are in the parameter's own encoding.
        """
        t = self._types[i]
        if t == REAL32:
            _f32_key(src, o, self._k)
            return 0
        if cast:
            return _cast_key(t, src, o, self._k)
        _int_key(t, src, o, self._k)
        return 0

    def _inside(self, i):
        """self._k is within parameter i's min..max."""
        o = 4 * i
        return _cmp(self._k, 0, self._lo, o) >= 0 and _cmp(self._k, 0, self._hi, o) <= 0

    def valid(self, i, src, o):
        """src[o:o+4], in the parameter's own encoding, is a value it may take."""
        if self._types[i] == REAL32 and _not_finite(src, o):
            return False
        self._key(i, src, o, False)
        return self._inside(i)

    def accept(self, i, src, o, cast):
        """Store src[o:o+4] into parameter i if it is a value it may take -> None,
        else why not. self.changed tells whether the value changed."""
        self.changed = False
        if (self._types[i] == REAL32 or cast) and _not_finite(src, o):
            return "NaN" if f32_is_nan(src, o) else "not finite"
        if self._key(i, src, o, cast) == 0 and self._inside(i):
            self._store(i)
            return None
        return self._why_not(i, src, o, cast)

    def _why_not(self, i, src, o, cast):
        """Why accept() refused a finite value (the rare path: it allocates, but not
        with the heap locked)."""
        if self._key(i, src, o, cast) == _FRACTION:
            return "not a whole number"
        try:
            return "out of range %s..%s" % (self._show(i, self._lo), self._show(i, self._hi))
        except MemoryError:  # the heap is locked (the emulated boards): without the limits
            return "out of range"

    def _store(self, i):
        """Parameter i := the value whose key is in self._k; sets self.changed."""
        t = self._types[i]
        v = self._scratch
        if t == REAL32:
            _f32_unkey(self._k, v)
        else:
            _int_unkey(t, self._k, v)
        self.changed = _cmp(self._values, 4 * i, v, 0) != 0
        _copy4(self._values, 4 * i, v, 0)
        if self.c_cast:
            self._cast(i, t)

    def _cast(self, i, t):
        """The C-cast wire copy of parameter i: floats as they are, integers converted."""
        o = 4 * i
        if t == REAL32:
            _copy4(self._wire, o, self._values, o)
            return
        m = self._k  # the key, turned into the magnitude
        if t & 1:  # unsigned: the key is the value
            _int_f32(self._wire, o, m)
        elif m[3] & 0x80:  # signed: the key is the value + 2**31
            m[3] &= 0x7F
            _int_f32(self._wire, o, m)
        else:
            _from_2_31(m)
            _int_f32(self._wire, o, m)
            self._wire[o + 3] |= 0x80

    def _show(self, i, keys):
        """Parameter i's limit in keys, for a message (allocates: refusals only)."""
        b = self._scratch
        _copy4(self._k, 0, keys, 4 * i)
        t = self._types[i]
        if t != REAL32:
            _int_unkey(t, self._k, b)
            return _get_int(b, 0, t)
        _f32_unkey(self._k, b)
        return "%g" % struct.unpack_from("<f", b, 0)[0]

    def adopt(self, values):
        """Take a whole set of checked values -> how many changed; self._mark[i] is 1
        for those."""
        n = 0
        for i in range(self.count):
            c = self._adopt(i, values)
            self._mark[i] = c
            n += c
        return n

    def _adopt(self, i, values):
        vo = 4 * i
        if not self.c_cast and _cmp(values, vo, self._values, vo) == 0:
            return 0
        self._key(i, values, vo, False)
        self._store(i)
        return 1 if self.changed else 0

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
        """Parameter i's value: an int, or a float (a new object on MicroPython, as is
        an int of 2**30 or more on a 32-bit board)."""
        t = self._types[i]
        if t == REAL32:
            return struct.unpack_from("<f", self._values, 4 * i)[0]
        return _get_int(self._values, 4 * i, t)

    def get(self, name):
        return self.value(self.index(name))

    def put(self, i, value):
        """Parameter i := value (read-only ones too) -> changed; ValueError if it may not."""
        b = self._scratch  # read into self._k before anything is stored
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
        """The values as a file: header, (name, type, value) records, crc16. Written
        whole into one buffer (the same each time: send it before the next pack)."""
        img = self._image
        _head(img, self.count)
        o = _HEADER
        for i in range(self.count):
            o = self._pack(img, o, i)
        _seal(img, o)
        return img

    def _pack(self, img, o, i):
        n = self._lens[i]
        img[o] = n
        _move(img, o + 1, self._names, ID_LEN * i, n)
        o += 1 + n
        img[o] = self._types[i]
        _copy4(img, o + 1, self._values, 4 * i)
        return o + 5

    def unpack(self, data, n=-1):
        """Values from a file image data[0:n] (n < 0: all of data) into self._loaded,
        defaults where it has none -> how many of its records no longer fit (type
        changed, out of range), or -1 if it is corrupt."""
        end = (len(data) if n < 0 else n) - 2
        if end < _HEADER or not _is_image(data):
            return -1
        if crc16(data, 0, end, 0xFFFF) != u16(data, end):
            return -1
        _move(self._loaded, 0, self._defaults, 0, len(self._loaded))
        return self._records(data, end)

    def _records(self, data, end):
        self._bad = 0
        o = _HEADER
        n = u16(data, 6)
        while n and o >= 0:
            o = self._unpack(data, o, end)
            n -= 1
        return self._bad if o == end else -1

    def _unpack(self, data, o, end):
        """Take the record at data[o:] -> where the next one starts, -1 if corrupt."""
        n = data[o] if o < end else 0
        if n == 0 or n > ID_LEN or o + 6 + n > end:
            return -1
        self._record(data, o + 1, n)
        return o + 6 + n

    def _record(self, data, o, n):
        """The value of a record whose name is data[o:o+n] (type and value follow)."""
        i = self.find(data, o, n)
        if i < 0:
            return
        o += n
        if data[o] == self._types[i] and self.valid(i, data, o + 1):
            _copy4(self._loaded, 4 * i, data, o + 1)
        else:
            self._bad += 1


def _put16(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = v >> 8


def _head(img, count):
    _move(img, 0, _MAGIC, 0, 4)
    img[4] = _FILE_VERSION
    img[5] = 0
    _put16(img, 6, count)


def _seal(img, end):
    """The crc16 of img[0:end] after it."""
    _put16(img, end, crc16(img, 0, end, 0xFFFF))


def _is_image(data):
    return (data[0] == _MAGIC[0] and data[1] == _MAGIC[1] and data[2] == _MAGIC[2]
            and data[3] == _MAGIC[3] and data[4] == _FILE_VERSION)
