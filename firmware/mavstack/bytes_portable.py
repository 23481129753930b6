"""Byte kernels in plain Python: the fallback where viper is unavailable, and CPython.

Contract shared with bytes_viper:
  crc16(buf, start, end, crc)  X.25 (CRC-16/MCRF4XX) over buf[start:end], continuing crc
  find_stx(src, pos, end)      index of the first 0xFD/0xFE in src[pos:end], else end
  copy(dst, src, offsets, n)   dst[d:d+n] = src[s:s+n], offsets = d | s << 10 (d < 1024)
  zero(dst, start, end)        dst[start:end] = 0
  scan(src, pos, end, buf)     one whole frame at src[pos:end] into a parser's buffer (below)
Loops over indices rather than slices so that nothing is allocated on MicroPython.

scan is the parser's fast path: what it delivers, the bytewise state machine would
deliver the same way; anything else it leaves to that state machine. buf is the
parser's buffer: the frame at [0:SLOTS), then 8 sender slots of (in use, sysid, compid,
last seq) at [SLOTS:FIELDS), at FIELDS the version the parser's version, payload and
signed fields hold from the last frame scan delivered (0: unknown, Python's to clear),
then for each msgid < 256 (crc_extra, least length, full length) at IDS + 3 * msgid,
full length 0 for an id the dialect lacks. end < 0 means -end, and "careful": a valid
frame is copied but left to Python to deliver (a verify hook is set). Returns
  e << 2 | v1 << 1 | f a frame src[pos:e], unsigned, copied into buf, payload zero-
                       extended to its full length, its sender's sequence number stored
                       (in a slot already, no gap): Python sets the fields (version,
                       payload and signed too when f is 1) and delivers
  -1 - (k << 2)        src[pos:k] holds no start marker (k = end if none at all)
  -1 - (pos << 2 | 1)  the state machine takes it from pos: frame incomplete, id >= 256,
                       or rejected (impossible length or flags, unknown id, bad CRC)
  -1 - (e << 2 | 2)    a frame src[pos:e] copied into buf as on the wire (signed,
                       careful, new sender, or a sequence gap): Python delivers it
buf[0:SLOTS] is unspecified after the first two answers and the third.
"""
from .compat import const

SLOTS = const(280)
FIELDS = const(312)
IDS = const(316)


def crc16(buf, start, end, crc):
    for i in range(start, end):
        t = (buf[i] ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc


def find_stx(src, pos, end):
    while pos < end:
        b = src[pos]
        if b == 0xFD or b == 0xFE:
            return pos
        pos += 1
    return end


def copy(dst, src, offsets, n):
    # One index for both sides, and a while loop (a for-range loop keeps more on the
    # stack): the frame stays within the ~11 words MicroPython keeps off the heap.
    s = offsets >> 10
    n += s
    d = (offsets & 0x3FF) - s
    while s < n:
        dst[d + s] = src[s]
        s += 1


def zero(dst, start, end):
    for i in range(start, end):
        dst[i] = 0


def scan(src, pos, end, buf):
    # Small steps, each within the ~11 words of frame state MicroPython keeps off the heap.
    if end < 0:
        n = _check(src, pos, -end, buf)
        if n > 0:
            return -1 - ((pos + n) << 2 | 2)
        return n
    n = _check(src, pos, end, buf)
    if n <= 0:
        return n
    if buf[0] == 0xFD and buf[2] or not _settle(buf):
        return -1 - ((pos + n) << 2 | 2)
    return (pos + n) << 2 | _fields(buf)


def _fields(buf):
    v = 1 if buf[0] == 0xFE else 2
    if buf[FIELDS] == v:
        return 2 if v == 1 else 0
    buf[FIELDS] = v
    return 3 if v == 1 else 1


def _check(src, pos, end, buf):
    """The length of the valid frame at src[pos], copied into buf; else scan's answer."""
    k = find_stx(src, pos, end)
    if k > pos:
        return -1 - (k << 2)
    k = _frame_len(src, pos, end, buf)
    if k == 0 or end - pos < k:
        return -1 - (pos << 2 | 1)
    copy(buf, src, pos << 10, k)
    if _crc_ok(buf):
        return k
    return -1 - (pos << 2 | 1)


def _frame_len(src, pos, end, buf):
    """The length of the frame at src[pos] by its header, 0 if not acceptable or the
    header is not all in src[pos:end]."""
    if src[pos] == 0xFE:
        if end - pos < 6:
            return 0
        plen = src[pos + 1]
        t = IDS + src[pos + 5] * 3
        if buf[t + 2] == 0 or plen < buf[t + 1] or plen > buf[t + 2]:
            return 0
        return plen + 8
    if end - pos < 10:
        return 0
    plen = src[pos + 1]
    if src[pos + 2] > 1 or src[pos + 8] or src[pos + 9]:
        return 0
    t = IDS + src[pos + 7] * 3
    if buf[t + 2] == 0 or plen == 0 or plen > buf[t + 2]:
        return 0
    return plen + (25 if src[pos + 2] else 12)


def _crc_ok(buf):
    if buf[0] == 0xFE:
        e = 6 + buf[1]
        t = buf[IDS + 3 * buf[5]]  # crc_extra, by msgid
    else:
        e = 10 + buf[1]
        t = buf[IDS + 3 * buf[7]]
    crc = crc16(buf, 1, e, 0xFFFF)
    t = (t ^ crc) & 0xFF
    t = (t ^ (t << 4)) & 0xFF
    crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc == buf[e] | buf[e + 1] << 8


def _settle(buf):
    """Zero-extend the payload; count the sender's sequence number if it has a slot and
    no gap -> True, else False (Python counts it)."""
    h = 6 if buf[0] == 0xFE else 10
    i = buf[IDS + 3 * buf[5 if h == 6 else 7] + 2]  # the full length
    zero(buf, h + buf[1], h + i)
    h = 2 if h == 6 else 4  # now the offset of seq, then sysid, compid
    i = SLOTS
    while i < IDS:
        if buf[i] and buf[i + 1] == buf[h + 1] and buf[i + 2] == buf[h + 2]:
            break
        i += 4
    if i == IDS or (buf[h] - buf[i + 3] - 1) & 0xFF:
        return False
    buf[i + 3] = buf[h]
    return True
