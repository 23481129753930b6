"""How parameter values travel (PARAM_ENCODING): a value's 4 bytes, and each link's encoding.

A value is kept as it travels in PARAM_VALUE's param_value: integers bytewise (their
low bytes, the rest zero), floats as IEEE754 bits; C-cast carries an integer as the
float32 of it. Checks work on the value's *key*, an unsigned 32-bit number that orders
like the value, compared 16 bits at a time; conversions go through the bytes in 16-bit
halves, so no value becomes a Python int of 2^30 or more (docs/design.md, "32-bit
clean") and nothing is allocated; only get_int and put_int (start-up, the application,
messages) make Python ints.

LinkEncodings, a part of Params, says which encoding each link's PARAM_VALUEs travel in:
one for all, or under "auto" C-cast where the link's ground station assumes ArduPilot's
conventions (the status service's status/conventions.py), bytewise elsewhere.

Reference: docs/services/params.md
"""
from ...compat import const
from ...fields import u16, i16, u32, i32
from ...kernels import copy

# MAV_PARAM_TYPE (table.py has them all); the integer types up to INT32 are signed
# when even, unsigned when odd.
_UINT8 = const(1)
_INT8 = const(2)
_UINT16 = const(3)
_INT16 = const(4)
_UINT32 = const(5)
_REAL32 = const(9)

_ID_LEN = const(16)  # param_id: NUL-padded, no NUL when 16 long

_CAP_PARAM_ENCODE_BYTEWISE = const(16)
_CAP_PARAM_ENCODE_C_CAST = const(131072)
_ARDUPILOT = const(1)  # a link's convention (status/conventions.py)
_PX4 = const(2)

# What a value is as a key (key()): 0 (fine), or why it has none.
FRACTION = const(2)  # a float with a fraction where an integer is wanted
_OUTSIDE = const(3)  # beyond the 32-bit type: out of range whatever the limits
_NEG = const(1)  # _whole: a negative magnitude (internal)


# --- 4 little-endian bytes --------------------------------------------------------------

def _put_halves(b, hi, lo):
    b[0] = lo & 0xFF
    b[1] = lo >> 8
    b[2] = hi & 0xFF
    b[3] = hi >> 8


def cmp4(a, ao, b, bo):
    """a[ao:ao+4] - b[bo:bo+4] as unsigned 32-bit numbers, by sign only."""
    d = (a[ao + 3] << 8 | a[ao + 2]) - (b[bo + 3] << 8 | b[bo + 2])
    if d == 0:
        d = (a[ao + 1] << 8 | a[ao]) - (b[bo + 1] << 8 | b[bo])
    return d


def copy4(dst, do, src, so):
    """dst[do:do+4] := src[so:so+4]."""
    dst[do] = src[so]
    dst[do + 1] = src[so + 1]
    dst[do + 2] = src[so + 2]
    dst[do + 3] = src[so + 3]


def move(dst, do, src, so, n):
    """dst[do:do+n] := src[so:so+n], at offsets of any size (kernels.copy packs its
    offsets into 10 bits)."""
    n += so
    while so < n:
        dst[do] = src[so]
        do += 1
        so += 1


def put16(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = v >> 8


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
    return 1 if t <= _INT8 else 2 if t <= _INT16 else 4


def key(t, src, o, cast, k):
    """k := the type-t value src[o:o+4] as a key -> 0, else FRACTION or _OUTSIDE.

    cast: the bytes are a float holding the value (C-cast, command parameters); else
    they are in the type's own encoding.
    """
    if t == _REAL32:
        _f32_key(src, o, k)
        return 0
    if cast:
        return _cast_key(t, src, o, k)
    _int_key(t, src, o, k)
    return 0


def unkey(t, k, dst):
    """dst[0:4] := the type-t value whose key is k, in the type's own encoding."""
    if t == _REAL32:
        _f32_unkey(k, dst)
    else:
        _int_unkey(t, k, dst)


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


def not_finite(src, o):
    """The float32 bits src[o:o+4] are a NaN or an infinity."""
    return (src[o + 3] & 0x7F) == 0x7F and src[o + 2] & 0x80


def _scaled(k, m, s):
    """k := m * 2**s as a 32-bit magnitude (m: a float32's 24-bit significand) -> 0,
    FRACTION or _OUTSIDE (2**32 or more). Never makes an int past 2**24."""
    if s > 8:
        return _OUTSIDE
    if s >= 0:
        _put_halves(k, m >> (16 - s), (m & (0xFFFF >> s)) << s)
        return 0
    if s < -23 or m & ((1 << -s) - 1):
        return FRACTION
    m >>= -s
    _put_halves(k, m >> 16, m & 0xFFFF)
    return 0


def _whole(src, o, k):
    """k := |the integer float32 src[o:o+4] holds| -> 0, _NEG (nonzero, negative),
    FRACTION or _OUTSIDE. NaN and infinities are the caller's to refuse first."""
    e = (src[o + 3] & 0x7F) << 1 | src[o + 2] >> 7
    m = (src[o + 2] & 0x7F) << 16 | src[o + 1] << 8 | src[o]
    if e == 0:  # zero, or a subnormal (a fraction)
        _put_halves(k, 0, 0)
        return FRACTION if m else 0
    r = _scaled(k, m | 0x800000, e - 150)
    return _NEG if r == 0 and src[o + 3] & 0x80 else r


def _cast_key(t, src, o, k):
    """k := the key of the integer float32 src[o:o+4] holds, for integer type t ->
    0, FRACTION or _OUTSIDE (the 32-bit type cannot hold it)."""
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


def cast_unkey(t, k, dst, o):
    """dst[o:o+4] := the C-cast float32 bits of the type-t integer whose key is k
    (k is used up: it is left holding the magnitude)."""
    if t & 1:  # unsigned: the key is the value
        _int_f32(dst, o, k)
    elif k[3] & 0x80:  # signed: the key is the value + 2**31
        k[3] &= 0x7F
        _int_f32(dst, o, k)
    else:
        _from_2_31(k)
        _int_f32(dst, o, k)
        dst[o + 3] |= 0x80


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

def get_int(buf, o, t):
    if t == _UINT8:
        return buf[o]
    if t == _INT8:
        v = buf[o]
        return v - 0x100 if v & 0x80 else v
    if t == _UINT16:
        return u16(buf, o)
    if t == _INT16:
        return i16(buf, o)
    if t == _UINT32:
        return u32(buf, o)
    return i32(buf, o)


def put_int(buf, o, t, v):
    size = _size(t)
    for k in range(4):
        buf[o + k] = (v >> (8 * k)) & 0xFF if k < size else 0


# --- each link's encoding ------------------------------------------------------------

class LinkEncodings:
    """The encoding of each link's PARAM_VALUEs and the type rules of PARAM_SET, for Params
    (which has self.ep, the table, self.c_cast, self.auto and self.conventions: the status
    service's, or None)."""

    def _watch(self, ep):
        """Say the encoding in the capability bits ("auto" says bytewise) and find the
        conventions each link's ground station assumes."""
        cast = self.c_cast and not self.auto
        ep.capabilities |= _CAP_PARAM_ENCODE_C_CAST if cast else _CAP_PARAM_ENCODE_BYTEWISE
        status = ep.services.get("status")
        self.conventions = status.conventions if status is not None else None

    def cast_link(self, link):
        """Do link's PARAM_VALUEs carry integers C-cast? Fixed by PARAM_ENCODING, or under
        "auto" where its ground station assumes ArduPilot's conventions."""
        if not self.auto:
            return self.c_cast
        return self.conventions is not None and self.conventions.of(link) == _ARDUPILOT

    def _px4_link(self, link):
        return self.conventions is not None and self.conventions.of(link) == _PX4

    def _fill(self, buf, off, i, cast):
        """PARAM_VALUE for parameter i into buf[off:], its value C-cast if cast."""
        copy(buf, self._wire if cast else self._values, i << 12 | off, 4)  # (offsets: kernels)
        put16(buf, off + 4, self.count)
        put16(buf, off + 6, i)
        copy(buf, self._names, i << 14 | (off + 8), _ID_LEN)
        buf[off + 24] = self._types[i]

    def _cast_in(self, link, i, p):
        """Whether PARAM_SET p holds parameter i's value as a float (C-cast) rather than
        in its type's bytes: typed REAL32 for an integer it does (the number it holds,
        as ArduPilot reads it; the link's encoding stays as it is), else as the link's."""
        if p[22] != _REAL32 or self._types[i] == _REAL32:
            return self.cast_link(link)
        return True

    def _type_refused(self, link, i, p):
        """None if PARAM_SET p's value can be read for parameter i, else why not: another
        integer type's bytes would be misread; and a float for an integer from a station
        in PX4's convention is refused as PX4 does (nothing stored), not taken as a cast."""
        t = self._types[i]
        if p[22] == t or (p[22] == _REAL32 and not self._px4_link(link)):
            return None
        return _type_why(p[22], t)


def _type_why(got, want):
    try:
        return "type %d, expected %d" % (got, want)
    except MemoryError:  # the heap is locked
        return "wrong type"
