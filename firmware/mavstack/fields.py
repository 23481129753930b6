"""Allocation-free reads of little-endian fields from a payload view, and coordinates
converted in place between MISSION_ITEM's float32 degrees (metres in local frames) and
MISSION_ITEM_INT's int32 1e7 degrees (1e4 metres), exactly, with small ints only.
Text fields as str, for the rare paths that need them, without ever raising.

struct.unpack_from builds a tuple (and floats are heap objects on MicroPython), so
per-frame handlers read integers byte by byte and test floats by their bits.
Reference: docs/core.md.
"""


def u8(p, o):
    return p[o]


def u16(p, o):
    return p[o] | p[o + 1] << 8


def i16(p, o):
    v = p[o] | p[o + 1] << 8
    return v - 0x10000 if v & 0x8000 else v


def u32(p, o):
    return p[o] | p[o + 1] << 8 | p[o + 2] << 16 | p[o + 3] << 24


def i32(p, o):
    # From the signed high half: a value within +-2^30 never passes through a larger int.
    return i16(p, o + 2) << 16 | p[o] | p[o + 1] << 8


def f32_is_nan(p, o):
    return (p[o + 3] & 0x7F) == 0x7F and (p[o + 2] & 0x80) and ((p[o + 2] & 0x7F) or p[o + 1] or p[o])


def cstr_len(p, o, n):
    """Length of a NUL-padded char[n] field (no NUL needed when it fills n)."""
    for i in range(n):
        if p[o + i] == 0:
            return i
    return n


def cstr_text(p, o, n):
    """The NUL-padded char[n] field at p[o] as str, never raising: each ill-formed UTF-8
    sequence in it (its longest valid start, or one byte) becomes one U+FFFD, as CPython's
    errors="replace" does (MicroPython's decode ignores errors, and raises). Allocates."""
    end = o + cstr_len(p, o, n)
    out = bytearray()
    i = run = o  # p[run:i]: well-formed so far
    while i < end:
        b = p[i]
        want = 1 if b < 0x80 else 0 if b < 0xC2 or b > 0xF4 else 2 if b < 0xE0 else 3 if b < 0xF0 else 4
        lo = 0xA0 if b == 0xE0 else 0x90 if b == 0xF0 else 0x80  # no overlong forms
        hi = 0x9F if b == 0xED else 0x8F if b == 0xF4 else 0xBF  # no surrogates, none past U+10FFFF
        k = 1
        while k < want and i + k < end and lo <= p[i + k] <= hi:
            k += 1
            lo = 0x80
            hi = 0xBF
        if k != want:
            out += p[run:i]
            out += b"\xef\xbf\xbd"
            run = i + k
        i += k
    out += p[run:end]
    return str(out, "utf-8")


def f32_to_int(p, o):
    """A float32 field rounded to the nearest int, computed from its bits.

    Command parameters are floats even when they carry integers (ids, flags);
    this reads them without creating a float. NaN and infinities read as 0;
    magnitudes of 2^30 and more saturate at 2^30 - 1, the largest small int (a larger
    int is a heap object on a 32-bit board: docs/design.md).
    """
    hi = p[o + 2] | p[o + 3] << 8  # sign, exponent, top of the mantissa: in 16-bit halves
    e = (hi >> 7) & 0xFF  # (small ints: docs/design.md)
    if e == 0xFF or e < 126:
        return 0
    if e > 156:  # |f| >= 2^30
        v = 0x3FFFFFFF
    else:
        m = (hi & 0x7F | 0x80) << 16 | p[o + 1] << 8 | p[o]
        shift = e - 150
        v = m << shift if shift >= 0 else (m + (1 << (-shift - 1))) >> -shift
    return -v if hi & 0x8000 else v


def i32_cmp(p, o, hi, lo):
    """Compare the int32 at p[o] with hi * 65536 + lo (hi signed, lo 0..0xFFFF) -> -1, 0, 1.

    By 16-bit halves, signed high half first: coordinates in 1e7 degrees reach 1.8e9,
    past the small ints (docs/design.md).
    """
    h = p[o + 2] | p[o + 3] << 8
    if h & 0x8000:
        h -= 0x10000
    if h == hi:
        h = p[o] | p[o + 1] << 8
        hi = lo
    return (h > hi) - (h < hi)


def f32_to_small(p, o):
    """f32_to_int saturated at +-(2^30 - 1), read by 16-bit halves: always a small int on
    a 32-bit port, for fields where every huge value means the same (indices, counts)."""
    hi = p[o + 2] | p[o + 3] << 8
    e = (hi >> 7) & 0xFF
    if e == 0xFF or e < 126:
        return 0
    if e > 156:  # |f| >= 2^30
        v = 0x3FFFFFFF
    else:
        v = (hi & 0x7F | 0x80) << 16 | p[o + 1] << 8 | p[o]
        e -= 150
        v = v << e if e >= 0 else (v + (1 << (-e - 1))) >> -e
    return -v if hi & 0x8000 else v


# --- coordinates (missions, geography, servos) ----------------------------------
LOCAL_FRAMES = b"\x01\x04\x07\x08\x09\x0c\x14\x15"  # x, y in metres (* 1e4 in MISSION_ITEM_INT)


def unset(buf, o):
    """The int32 at buf[o] is INT32_MAX: x or y not given ("where the vehicle is")."""
    return buf[o] == 0xFF and buf[o + 1] == 0xFF and buf[o + 2] == 0xFF and buf[o + 3] == 0x7F


# --- MISSION_ITEM's float32 degrees <-> MISSION_ITEM_INT's int32 ---------------------
# Exact, and with small ints only: a float32 is m * 2**(e-150) (m < 2**24), so
# f * 10**k = m * 5**k / 2**(150-e-k), where m * 5**k < 2**41 is held as two ints.
# The other way is long division, 4 bits and then 1 bit at a time.
_acc = [0, 0]  # the scratch of the conversions: a wide number as two small ints


def fix(rec, o, local):
    """In place: the float32 at rec[o] (degrees; metres where local) -> the int32 of
    MISSION_ITEM_INT (* 1e7; * 1e4 where local), nearest, halves away from zero.
    False, and 0 written, for NaN, infinities and values beyond int32."""
    e = (rec[o + 3] & 0x7F) << 1 | rec[o + 2] >> 7
    # |f| >= 2**(e-127): beyond 2**31 / 10**k it cannot fit an int32 (NaN, inf: e 255).
    if e > (144 if local else 134):
        return _put_i32(rec, o, False)
    # m * 5**k = H * 2**24 + L into _acc, by 12-bit pieces of m (5**7 < 2**17).
    m = (rec[o + 2] & 0x7F | (0x80 if e else 0)) << 16 | rec[o + 1] << 8 | rec[o]
    a = (m >> 12) * (625 if local else 78125)  # < 2**12 * 5**7 < 2**29
    m = (m & 0xFFF) * (625 if local else 78125) + ((a & 0xFFF) << 12)  # < 2**30
    _acc[0] = (a >> 12) + (m >> 24)
    _acc[1] = m & 0xFFFFFF
    _shift((149 if e == 0 else 150 - e) - (4 if local else 7))  # e 0: subnormal
    return _put_i32(rec, o, _acc[0] <= 0x7FFF)  # beyond int32: 0


def _shift(s):
    """_acc = (H, L) -> v = round((H * 2**24 + L) / 2**s), halves up, as (v >> 16, v & 0xFFFF)."""
    if s > 41:  # H * 2**24 + L < 2**41: below one half
        _acc[0] = _acc[1] = 0
        return
    h = _acc[0]
    low = _acc[1]
    if s <= 24:
        low += 1 << (s - 1)
    else:
        h += 1 << (s - 25)
    h += low >> 24
    low &= 0xFFFFFF
    _acc[0] = _bits16(h, low, s + 16)
    _acc[1] = _bits16(h, low, s)


def _bits16(h, low, t):
    """Bits t .. t+15 of h * 2**24 + low (h < 2**18, low < 2**24)."""
    if t >= 24:
        return (h >> (t - 24)) & 0xFFFF
    v = low >> t
    if t > 8:  # h's lowest t - 8 bits land below bit 16
        v |= (h & ((1 << (t - 8)) - 1)) << (24 - t)
    return v & 0xFFFF


def _put_i32(buf, o, ok):
    """buf[o:o+4] <- the magnitude in _acc (high half, low half) as an int32, negated if
    buf[o+3] has its sign bit set (the float's, or the int's); 0 if not ok -> ok."""
    hi = _acc[0] if ok else 0
    lo = _acc[1] if ok else 0
    if ok and buf[o + 3] & 0x80:  # two's complement by halves: the carry of -lo goes into ~hi
        lo = -lo & 0xFFFF
        hi = (~hi + (lo == 0)) & 0xFFFF
    buf[o] = lo & 0xFF
    buf[o + 1] = lo >> 8
    buf[o + 2] = hi & 0xFF
    buf[o + 3] = hi >> 8
    return ok


def unfix(buf, o, local):
    """In place: the int32 at buf[o] -> the float32 nearest to it / 1e7 (/ 1e4 where
    local), ties to even (its bits); INT32_MAX (unset) -> NaN, as the seed says it."""
    if unset(buf, o):
        buf[o] = buf[o + 1] = 0
        buf[o + 2] = 0xC0
        buf[o + 3] = 0x7F
        return
    neg = buf[o + 3] & 0x80
    if neg:  # the magnitude first, in place, by halves (2**31 too: 0x8000, 0)
        _acc[0] = buf[o + 2] | buf[o + 3] << 8
        _acc[1] = buf[o] | buf[o + 1] << 8
        _put_i32(buf, o, True)
    if not (buf[o] or buf[o + 1] or buf[o + 2] or buf[o + 3]):
        return  # 0: the bits of 0.0 are already there
    d = 10000 if local else 10000000
    _acc[0] = _acc[1] = 0
    _div16(buf[o + 2] | buf[o + 3] << 8, d)
    _div16(buf[o] | buf[o + 1] << 8, d)
    d = 150 - _frac(d)  # the biased exponent; the 24-bit significand is in _acc[0]
    q = _acc[0]
    buf[o] = q & 0xFF
    buf[o + 1] = (q >> 8) & 0xFF
    buf[o + 2] = (d & 1) << 7 | (q >> 16) & 0x7F
    buf[o + 3] = neg | d >> 1


def _div16(x, d):
    """Long division: (quotient, remainder) by d in _acc, continued by the 16 bits of x,
    4 at a time (the remainder is below d, so remainder * 16 stays small)."""
    n = 12
    while n >= 0:
        r = _acc[1] << 4 | (x >> n) & 0xF
        _acc[0] = _acc[0] << 4 | r // d
        _acc[1] = r % d
        n -= 4


def _frac(d):
    """Binary digits of remainder / d appended to the quotient until it has 24
    significant bits, then rounded to nearest, ties to even -> how many were appended.
    (The quotient is below 2**31 / 10**4 < 2**23 to begin with.)"""
    q = _acc[0]
    r = _acc[1]
    n = 0
    while q < 0x800000:
        q <<= 1
        r <<= 1
        if r >= d:
            r -= d
            q |= 1
        n += 1
    r <<= 1
    if r > d or (r == d and q & 1):
        q += 1
        if q == 0x1000000:
            q >>= 1
            n -= 1
    _acc[0] = q
    return n
