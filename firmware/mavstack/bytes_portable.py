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
After the second and the third answers buf[0:SLOTS] is scratch, its bytes unspecified.
"""
from .compat import const

SLOTS = const(280)
FIELDS = const(312)
IDS = const(316)


# The CRC a byte at a time by table (crc16 of each byte value from 0): a constant
# tuple, which a frozen module keeps in flash.
_TABLE = (
    0x0000, 0x1189, 0x2312, 0x329B, 0x4624, 0x57AD, 0x6536, 0x74BF,
    0x8C48, 0x9DC1, 0xAF5A, 0xBED3, 0xCA6C, 0xDBE5, 0xE97E, 0xF8F7,
    0x1081, 0x0108, 0x3393, 0x221A, 0x56A5, 0x472C, 0x75B7, 0x643E,
    0x9CC9, 0x8D40, 0xBFDB, 0xAE52, 0xDAED, 0xCB64, 0xF9FF, 0xE876,
    0x2102, 0x308B, 0x0210, 0x1399, 0x6726, 0x76AF, 0x4434, 0x55BD,
    0xAD4A, 0xBCC3, 0x8E58, 0x9FD1, 0xEB6E, 0xFAE7, 0xC87C, 0xD9F5,
    0x3183, 0x200A, 0x1291, 0x0318, 0x77A7, 0x662E, 0x54B5, 0x453C,
    0xBDCB, 0xAC42, 0x9ED9, 0x8F50, 0xFBEF, 0xEA66, 0xD8FD, 0xC974,
    0x4204, 0x538D, 0x6116, 0x709F, 0x0420, 0x15A9, 0x2732, 0x36BB,
    0xCE4C, 0xDFC5, 0xED5E, 0xFCD7, 0x8868, 0x99E1, 0xAB7A, 0xBAF3,
    0x5285, 0x430C, 0x7197, 0x601E, 0x14A1, 0x0528, 0x37B3, 0x263A,
    0xDECD, 0xCF44, 0xFDDF, 0xEC56, 0x98E9, 0x8960, 0xBBFB, 0xAA72,
    0x6306, 0x728F, 0x4014, 0x519D, 0x2522, 0x34AB, 0x0630, 0x17B9,
    0xEF4E, 0xFEC7, 0xCC5C, 0xDDD5, 0xA96A, 0xB8E3, 0x8A78, 0x9BF1,
    0x7387, 0x620E, 0x5095, 0x411C, 0x35A3, 0x242A, 0x16B1, 0x0738,
    0xFFCF, 0xEE46, 0xDCDD, 0xCD54, 0xB9EB, 0xA862, 0x9AF9, 0x8B70,
    0x8408, 0x9581, 0xA71A, 0xB693, 0xC22C, 0xD3A5, 0xE13E, 0xF0B7,
    0x0840, 0x19C9, 0x2B52, 0x3ADB, 0x4E64, 0x5FED, 0x6D76, 0x7CFF,
    0x9489, 0x8500, 0xB79B, 0xA612, 0xD2AD, 0xC324, 0xF1BF, 0xE036,
    0x18C1, 0x0948, 0x3BD3, 0x2A5A, 0x5EE5, 0x4F6C, 0x7DF7, 0x6C7E,
    0xA50A, 0xB483, 0x8618, 0x9791, 0xE32E, 0xF2A7, 0xC03C, 0xD1B5,
    0x2942, 0x38CB, 0x0A50, 0x1BD9, 0x6F66, 0x7EEF, 0x4C74, 0x5DFD,
    0xB58B, 0xA402, 0x9699, 0x8710, 0xF3AF, 0xE226, 0xD0BD, 0xC134,
    0x39C3, 0x284A, 0x1AD1, 0x0B58, 0x7FE7, 0x6E6E, 0x5CF5, 0x4D7C,
    0xC60C, 0xD785, 0xE51E, 0xF497, 0x8028, 0x91A1, 0xA33A, 0xB2B3,
    0x4A44, 0x5BCD, 0x6956, 0x78DF, 0x0C60, 0x1DE9, 0x2F72, 0x3EFB,
    0xD68D, 0xC704, 0xF59F, 0xE416, 0x90A9, 0x8120, 0xB3BB, 0xA232,
    0x5AC5, 0x4B4C, 0x79D7, 0x685E, 0x1CE1, 0x0D68, 0x3FF3, 0x2E7A,
    0xE70E, 0xF687, 0xC41C, 0xD595, 0xA12A, 0xB0A3, 0x8238, 0x93B1,
    0x6B46, 0x7ACF, 0x4854, 0x59DD, 0x2D62, 0x3CEB, 0x0E70, 0x1FF9,
    0xF78F, 0xE606, 0xD49D, 0xC514, 0xB1AB, 0xA022, 0x92B9, 0x8330,
    0x7BC7, 0x6A4E, 0x58D5, 0x495C, 0x3DE3, 0x2C6A, 0x1EF1, 0x0F78,
)


def crc16(buf, start, end, crc):
    t = _TABLE
    while start < end:
        crc = (crc >> 8) ^ t[(buf[start] ^ crc) & 0xFF]
        start += 1
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
    crc = (crc >> 8) ^ _TABLE[(t ^ crc) & 0xFF]
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
