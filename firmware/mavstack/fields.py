"""Allocation-free reads of little-endian fields from a payload view.

struct.unpack_from builds a tuple (and floats are heap objects on MicroPython), so
per-frame handlers read integers byte by byte and test floats by their bits.
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
    v = p[o] | p[o + 1] << 8 | p[o + 2] << 16 | p[o + 3] << 24
    return v - 0x100000000 if v & 0x80000000 else v


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
    b = p[o] | p[o + 1] << 8 | p[o + 2] << 16 | p[o + 3] << 24
    e = (b >> 23) & 0xFF
    if e == 0xFF or e < 126:
        return 0
    if e > 157:
        v = 0x7FFFFFFF
    else:
        m = (b & 0x7FFFFF) | 0x800000
        shift = e - 150
        v = m << shift if shift >= 0 else (m + (1 << (-shift - 1))) >> -shift
    return -v if b & 0x80000000 else v
