"""A parameter table as one bytes block, read in place: what ParamTable works from.

compile() checks a table of rows (name, type, default, min, max, flags) and lays it out
as names, lengths, types, flags, defaults and limits (as keys), and a crc16 hash index.
A board may declare its PARAMS as such a block, made by host_tools/paramgen.py: frozen
into the firmware, the block stays in flash and costs the heap nothing; a table of rows
is compiled at start-up instead. Layout: docs/services/params.md.
"""
import struct

from ...compat import const
from ...kernels import crc16
from ...fields import u16
from .encoding import key, put_int, cmp4, copy4, put16, not_finite

UINT32 = const(5)
INT32 = const(6)
REAL32 = const(9)

MAGIC = b"MSPT"
VERSION = const(1)
HEADER = const(8)  # magic, version, log2 of the hash buckets, count (u16)
ID_LEN = const(16)

INT_RANGE = {  # declaration and application checks only (start-up, put)
    1: (0, 0xFF),  # UINT8
    2: (-0x80, 0x7F),  # INT8
    3: (0, 0xFFFF),  # UINT16
    4: (-0x8000, 0x7FFF),  # INT16
    UINT32: (0, 0xFFFFFFFF),
    INT32: (-0x80000000, 0x7FFFFFFF),
}


def _bits(n):
    """log2 of the hash index's size for n parameters: a power of two, at least n."""
    b = 0
    while 1 << b < n:
        b += 1
    return b


def parts(n, nb):
    """Where each part of a block of n parameters starts: names, lens, types, flags,
    defaults, lo, hi, buckets (u16: index + 1), chain (u16: next index + 1), end."""
    o = [HEADER]
    for size in (ID_LEN * n, n, n, n, 4 * n, 4 * n, 4 * n, 2 * nb, 2 * n):
        o.append(o[-1] + size)
    return o


def count(block):
    """-> (parameters, buckets) of a block; ValueError if it is not one this reads."""
    if len(block) < HEADER or bytes(block[0:4]) != MAGIC or block[4] != VERSION:
        raise ValueError("not a parameter block of version %d" % VERSION)
    n, nb = u16(block, 6), 1 << block[5]
    if len(block) != parts(n, nb)[-1]:
        raise ValueError("parameter block of the wrong length")
    return n, nb


def compile(table):
    """The block of a table of rows -> bytearray; ValueError on a bad declaration."""
    n = len(table)
    if n > 0xFFFF:
        raise ValueError("too many parameters")
    bits = _bits(n)
    o = parts(n, 1 << bits)
    b = bytearray(o[-1])
    b[0:4] = MAGIC
    b[4] = VERSION
    b[5] = bits
    put16(b, 6, n)
    seen = {}
    for i in range(n):
        _declare(b, o, n, i, table[i], seen)
    return b


def _declare(b, o, n, i, row, seen):
    name, t, default = row[0], row[1], row[2]
    raw = name.encode()
    if not 0 < len(raw) <= ID_LEN or any(c <= 0x20 or c > 0x7E for c in raw):
        raise ValueError("param name must be 1..16 printable ASCII chars: %r" % name)
    if t in (7, 8, 10):  # UINT64, INT64, REAL64
        raise ValueError("%s: 64-bit params do not fit PARAM_VALUE's 4 bytes" % name)
    if t != REAL32 and t not in INT_RANGE:
        raise ValueError("%s: unknown MAV_PARAM_TYPE %r" % (name, t))
    if name in seen:
        raise ValueError("param declared twice: " + name)
    seen[name] = i
    b[o[0] + ID_LEN * i : o[0] + ID_LEN * i + len(raw)] = raw
    b[o[1] + i] = len(raw)
    b[o[2] + i] = t
    b[o[3] + i] = row[5] if len(row) > 5 else 0
    _hash(b, o, n, i, crc16(raw, 0, len(raw), 0xFFFF))
    lo = row[3] if len(row) > 3 else None
    hi = row[4] if len(row) > 4 else None
    scratch = bytearray(4)
    if t == REAL32:
        lo = -3.4028234e38 if lo is None else lo
        hi = 3.4028234e38 if hi is None else hi
        for v, at in ((lo, o[5]), (hi, o[6]), (default, o[4])):
            struct.pack_into("<f", scratch, 0, v)
            _put_key(b, at + 4 * i, t, scratch, at == o[4])
        ok = not not_finite(b, o[4] + 4 * i)
    else:
        tlo, thi = INT_RANGE[t]
        lo = tlo if lo is None else int(lo)
        hi = thi if hi is None else int(hi)
        if not tlo <= lo <= hi <= thi:
            raise ValueError("%s: min..max outside the type's range" % name)
        if default != int(default):
            raise ValueError("%s: default is not a whole number" % name)
        if not lo <= default <= hi:
            raise ValueError("%s: default outside min..max" % name)
        for v, at in ((lo, o[5]), (hi, o[6]), (int(default), o[4])):
            put_int(scratch, 0, t, v)
            _put_key(b, at + 4 * i, t, scratch, at == o[4])
        ok = True
    if not ok or not _inside(b, o, i, t):
        raise ValueError("%s: default outside min..max" % name)


def _put_key(b, at, t, value, raw):
    """b[at:at+4] := value (4 bytes of type t) as it is (raw: a default), else its key."""
    if raw:
        copy4(b, at, value, 0)
        return
    k = bytearray(4)
    key(t, value, 0, False, k)
    copy4(b, at, k, 0)


def _inside(b, o, i, t):
    k = bytearray(4)
    key(t, b, o[4] + 4 * i, False, k)
    lo, hi = o[5] + 4 * i, o[6] + 4 * i
    return cmp4(b, lo, b, hi) <= 0 and cmp4(k, 0, b, lo) >= 0 and cmp4(k, 0, b, hi) <= 0


def _hash(b, o, n, i, h):
    """Parameter i at the head of its bucket's chain (a later one is found first)."""
    nb = (o[8] - o[7]) // 2
    at = o[7] + 2 * (h & (nb - 1))
    put16(b, o[8] + 2 * i, u16(b, at))
    put16(b, at, i + 1)
