"""Byte kernels in plain Python: the fallback where viper is unavailable, and CPython.

The contract shared with bytes_viper:
  crc16(buf, start, end, crc)  X.25 (CRC-16/MCRF4XX) over buf[start:end], continuing crc
  seal_v2(buf, info, ids, msgid)  a MAVLink 2 frame around the payload at buf[10:]
  find_stx(src, pos, end)      index of the first 0xFD/0xFE in src[pos:end], else end
  copy(dst, src, offsets, n)   dst[d:d+n] = src[s:s+n], offsets = d | s << 10 (d < 1024)
  place(dst, d, src, n)        dst[d:d+n] = src[0:n], at any offset
  id_info(t, msgid)            a dialect's crc_extra | len1 << 8 | len2 << 16 for msgid from
                               its block t (dialects/table.py: InfoTable), 0 if it has none
  zero(dst, start, end)        dst[start:end] = 0
  scan(src, pos, end, buf, infos)  one whole frame at src[pos:end] into a parser's buffer
Loops over indices rather than slices so that nothing is allocated on MicroPython.
Reference (scan's buffer layout and answers): docs/core.md.
"""
from ..compat import const

SLOTS = const(280)
FIELDS = const(312)
BUF_LEN = const(316)


# The CRC a byte at a time by table: crc16 of each byte value from 0, low bytes then
# high bytes. A bytes constant, kept in flash when frozen (a tuple of these ints would
# not do: a frozen tuple's ints from 2**13 up are long-int objects, and each ^ on one
# allocates).
_TABLE = (
    b"\x00\x89\x12\x9b\x24\xad\x36\xbf\x48\xc1\x5a\xd3\x6c\xe5\x7e\xf7"
    b"\x81\x08\x93\x1a\xa5\x2c\xb7\x3e\xc9\x40\xdb\x52\xed\x64\xff\x76"
    b"\x02\x8b\x10\x99\x26\xaf\x34\xbd\x4a\xc3\x58\xd1\x6e\xe7\x7c\xf5"
    b"\x83\x0a\x91\x18\xa7\x2e\xb5\x3c\xcb\x42\xd9\x50\xef\x66\xfd\x74"
    b"\x04\x8d\x16\x9f\x20\xa9\x32\xbb\x4c\xc5\x5e\xd7\x68\xe1\x7a\xf3"
    b"\x85\x0c\x97\x1e\xa1\x28\xb3\x3a\xcd\x44\xdf\x56\xe9\x60\xfb\x72"
    b"\x06\x8f\x14\x9d\x22\xab\x30\xb9\x4e\xc7\x5c\xd5\x6a\xe3\x78\xf1"
    b"\x87\x0e\x95\x1c\xa3\x2a\xb1\x38\xcf\x46\xdd\x54\xeb\x62\xf9\x70"
    b"\x08\x81\x1a\x93\x2c\xa5\x3e\xb7\x40\xc9\x52\xdb\x64\xed\x76\xff"
    b"\x89\x00\x9b\x12\xad\x24\xbf\x36\xc1\x48\xd3\x5a\xe5\x6c\xf7\x7e"
    b"\x0a\x83\x18\x91\x2e\xa7\x3c\xb5\x42\xcb\x50\xd9\x66\xef\x74\xfd"
    b"\x8b\x02\x99\x10\xaf\x26\xbd\x34\xc3\x4a\xd1\x58\xe7\x6e\xf5\x7c"
    b"\x0c\x85\x1e\x97\x28\xa1\x3a\xb3\x44\xcd\x56\xdf\x60\xe9\x72\xfb"
    b"\x8d\x04\x9f\x16\xa9\x20\xbb\x32\xc5\x4c\xd7\x5e\xe1\x68\xf3\x7a"
    b"\x0e\x87\x1c\x95\x2a\xa3\x38\xb1\x46\xcf\x54\xdd\x62\xeb\x70\xf9"
    b"\x8f\x06\x9d\x14\xab\x22\xb9\x30\xc7\x4e\xd5\x5c\xe3\x6a\xf1\x78"
    b"\x00\x11\x23\x32\x46\x57\x65\x74\x8c\x9d\xaf\xbe\xca\xdb\xe9\xf8"
    b"\x10\x01\x33\x22\x56\x47\x75\x64\x9c\x8d\xbf\xae\xda\xcb\xf9\xe8"
    b"\x21\x30\x02\x13\x67\x76\x44\x55\xad\xbc\x8e\x9f\xeb\xfa\xc8\xd9"
    b"\x31\x20\x12\x03\x77\x66\x54\x45\xbd\xac\x9e\x8f\xfb\xea\xd8\xc9"
    b"\x42\x53\x61\x70\x04\x15\x27\x36\xce\xdf\xed\xfc\x88\x99\xab\xba"
    b"\x52\x43\x71\x60\x14\x05\x37\x26\xde\xcf\xfd\xec\x98\x89\xbb\xaa"
    b"\x63\x72\x40\x51\x25\x34\x06\x17\xef\xfe\xcc\xdd\xa9\xb8\x8a\x9b"
    b"\x73\x62\x50\x41\x35\x24\x16\x07\xff\xee\xdc\xcd\xb9\xa8\x9a\x8b"
    b"\x84\x95\xa7\xb6\xc2\xd3\xe1\xf0\x08\x19\x2b\x3a\x4e\x5f\x6d\x7c"
    b"\x94\x85\xb7\xa6\xd2\xc3\xf1\xe0\x18\x09\x3b\x2a\x5e\x4f\x7d\x6c"
    b"\xa5\xb4\x86\x97\xe3\xf2\xc0\xd1\x29\x38\x0a\x1b\x6f\x7e\x4c\x5d"
    b"\xb5\xa4\x96\x87\xf3\xe2\xd0\xc1\x39\x28\x1a\x0b\x7f\x6e\x5c\x4d"
    b"\xc6\xd7\xe5\xf4\x80\x91\xa3\xb2\x4a\x5b\x69\x78\x0c\x1d\x2f\x3e"
    b"\xd6\xc7\xf5\xe4\x90\x81\xb3\xa2\x5a\x4b\x79\x68\x1c\x0d\x3f\x2e"
    b"\xe7\xf6\xc4\xd5\xa1\xb0\x82\x93\x6b\x7a\x48\x59\x2d\x3c\x0e\x1f"
    b"\xf7\xe6\xd4\xc5\xb1\xa0\x92\x83\x7b\x6a\x58\x49\x3d\x2c\x1e\x0f"
)


def crc16(buf, start, end, crc):
    t = _TABLE
    while start < end:
        i = (buf[start] ^ crc) & 0xFF
        crc = (crc >> 8) ^ t[i] ^ t[i + 256] << 8
        start += 1
    return crc


def seal_v2(buf, info, ids, msgid):
    # (small frames: a heap frame past ~11 words, docs/design.md)
    end = 10 + (info >> 16)  # trailing zeros are implied on the wire; the first byte stays
    while end > 11 and buf[end - 1] == 0:
        end -= 1
    buf[0] = 0xFD
    buf[1] = end - 10
    _ids_v2(buf, ids, msgid)
    buf[end] = info & 0xFF  # CRC_EXTRA where the CRC's first byte goes: one pass covers it
    return _crc_after(buf, end)


def _ids_v2(buf, ids, msgid):
    buf[2] = ids >> 24
    buf[3] = 0
    buf[4] = ids & 0xFF
    buf[5] = (ids >> 8) & 0xFF
    buf[6] = (ids >> 16) & 0xFF
    buf[7] = msgid & 0xFF
    buf[8] = (msgid >> 8) & 0xFF
    buf[9] = msgid >> 16


def _crc_after(buf, end):
    crc = crc16(buf, 1, end + 1, 0xFFFF)
    buf[end] = crc & 0xFF
    buf[end + 1] = crc >> 8
    return end + 2


def find_stx(src, pos, end):
    while pos < end:
        b = src[pos]
        if b == 0xFD or b == 0xFE:
            return pos
        pos += 1
    return end


def copy(dst, src, offsets, n):
    # One index for both sides, and a while loop (a for-range loop keeps more on the
    # stack): a small frame, docs/design.md.
    s = offsets >> 10
    n += s
    d = (offsets & 0x3FF) - s
    while s < n:
        dst[d + s] = src[s]
        s += 1


def place(dst, d, src, n):
    s = 0
    while s < n:
        dst[d + s] = src[s]
        s += 1


def id_info(t, msgid):
    if 0 <= msgid <= 255:
        msgid *= 3
    else:
        msgid = _id_high(t, msgid)
        if msgid < 0:
            return 0
    return t[msgid] | t[msgid + 1] << 8 | t[msgid + 2] << 16


def _id_high(t, msgid):
    # (apart from id_info, to keep both frames small: docs/design.md)
    lo = 0
    hi = -1 if msgid < 0 else t[768] | t[769] << 8
    while lo < hi:
        mid = (lo + hi) >> 1
        j = 770 + mid * 6
        m = t[j] | t[j + 1] << 8 | t[j + 2] << 16
        if m == msgid:
            return j + 3
        if m < msgid:
            lo = mid + 1
        else:
            hi = mid
    return -1


def zero(dst, start, end):
    for i in range(start, end):
        dst[i] = 0


def scan(src, pos, end, buf, infos):
    # Small steps, each with a small frame (docs/design.md): the helpers read the
    # dialect's block from _INFOS.
    global _INFOS
    _INFOS = infos
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


_INFOS = b""  # the block of the dialect scan reads (kernels.id_info), set by scan


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
        t = src[pos + 5] * 3
        if _INFOS[t + 2] == 0 or plen < _INFOS[t + 1] or plen > _INFOS[t + 2]:
            return 0
        return plen + 8
    if end - pos < 10:
        return 0
    plen = src[pos + 1]
    if src[pos + 2] > 1 or src[pos + 8] or src[pos + 9]:
        return 0
    t = src[pos + 7] * 3
    if _INFOS[t + 2] == 0 or plen == 0 or plen > _INFOS[t + 2]:
        return 0
    return plen + (25 if src[pos + 2] else 12)


def _crc_ok(buf):
    if buf[0] == 0xFE:
        e = 6 + buf[1]
        t = _INFOS[3 * buf[5]]  # crc_extra, by msgid
    else:
        e = 10 + buf[1]
        t = _INFOS[3 * buf[7]]
    crc = crc16(buf, 1, e, 0xFFFF)
    t = (t ^ crc) & 0xFF
    crc = (crc >> 8) ^ _TABLE[t] ^ _TABLE[t + 256] << 8
    return crc == buf[e] | buf[e + 1] << 8


def _settle(buf):
    """Zero-extend the payload; count the sender's sequence number if it has a slot and
    no gap -> True, else False (Python counts it)."""
    h = 6 if buf[0] == 0xFE else 10
    i = _INFOS[3 * buf[5 if h == 6 else 7] + 2]  # the full length
    zero(buf, h + buf[1], h + i)
    h = 2 if h == 6 else 4  # now the offset of seq, then sysid, compid
    i = SLOTS
    while i < BUF_LEN:
        if buf[i] and buf[i + 1] == buf[h + 1] and buf[i + 2] == buf[h + 2]:
            break
        i += 4
    if i == BUF_LEN or (buf[h] - buf[i + 3] - 1) & 0xFF:
        return False
    buf[i + 3] = buf[h]
    return True
