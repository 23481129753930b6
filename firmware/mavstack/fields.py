"""Allocation-free reads of little-endian fields from a payload view.

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


def f32_bits(p, o):
    return u32(p, o)


def cstr_len(p, o, n):
    """Length of a NUL-padded char[n] field (no NUL needed when it fills n)."""
    for i in range(n):
        if p[o + i] == 0:
            return i
    return n


def f32_to_int(p, o):
    """A float32 field rounded to the nearest int, computed from its bits.

    Command parameters are floats even when they carry integers (ids, flags);
    this reads them without creating a float. NaN and infinities read as 0;
    magnitudes beyond int32 saturate.
    """
    hi = p[o + 2] | p[o + 3] << 8  # sign, exponent, top of the mantissa: in 16-bit halves
    e = (hi >> 7) & 0xFF  # (small ints: docs/design.md)
    if e == 0xFF or e < 126:
        return 0
    if e > 157:
        v = 0x7FFFFFFF
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
