"""Byte kernels compiled to machine code with @micropython.viper (MicroPython only).

Same contract as bytes_portable: tests run both on the same inputs.
"""
import micropython
from micropython import const


@micropython.viper
def crc16(buf: ptr8, start: int, end: int, crc: int) -> int:
    i = start
    while i < end:
        t = (buf[i] ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
        i += 1
    return crc


@micropython.viper
def seal_v2(buf: ptr8, info: int, ids: int, msgid: int) -> int:
    end = 10 + (info >> 16)
    while end > 11 and buf[end - 1] == 0:
        end -= 1
    buf[0] = 0xFD
    buf[1] = end - 10
    buf[2] = ids >> 24
    buf[3] = 0
    buf[4] = ids & 0xFF
    buf[5] = (ids >> 8) & 0xFF
    buf[6] = (ids >> 16) & 0xFF
    buf[7] = msgid & 0xFF
    buf[8] = (msgid >> 8) & 0xFF
    buf[9] = (msgid >> 16) & 0xFF
    buf[end] = info & 0xFF
    crc = 0xFFFF
    i = 1
    while i <= end:
        t = (buf[i] ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
        i += 1
    buf[end] = crc & 0xFF
    buf[end + 1] = crc >> 8
    return end + 2


@micropython.viper
def find_stx(src: ptr8, pos: int, end: int) -> int:
    while pos < end:
        b = src[pos]
        if b == 0xFD or b == 0xFE:
            return pos
        pos += 1
    return end


@micropython.viper
def copy(dst: ptr8, src: ptr8, offsets: int, n: int):
    d = offsets & 0x3FF
    s = offsets >> 10
    i = 0
    while i < n:
        dst[d + i] = src[s + i]
        i += 1


@micropython.viper
def place(dst: ptr8, d: int, src: ptr8, n: int):
    i = 0
    while i < n:
        dst[d + i] = src[i]
        i += 1


@micropython.viper
def id_info(t: ptr8, msgid: int) -> int:
    i = -1
    if msgid >= 0 and msgid <= 255:
        i = msgid * 3
    elif msgid > 255:
        lo = 0
        hi = t[768] | t[769] << 8
        while lo < hi:
            mid = (lo + hi) >> 1
            j = 770 + mid * 6
            m = t[j] | t[j + 1] << 8 | t[j + 2] << 16
            if m == msgid:
                i = j + 3
                break
            if m < msgid:
                lo = mid + 1
            else:
                hi = mid
    if i < 0:
        return 0
    return t[i] | t[i + 1] << 8 | t[i + 2] << 16


@micropython.viper
def zero(dst: ptr8, start: int, end: int):
    while start < end:
        dst[start] = 0
        start += 1


# scan's layout of the parser's buffer after the frame; docs/core.md has the contract.
SLOTS = const(280)
FIELDS = const(312)
BUF_LEN = const(316)
_CRC = bytearray(512)  # the CRC's table, 256 16-bit entries: one lookup a byte


@micropython.viper
def _crc_table(t: ptr16):
    i = 0
    while i < 256:
        c = (i ^ (i << 4)) & 0xFF
        t[i] = ((c << 8) ^ (c << 3) ^ (c >> 4)) & 0xFFFF
        i += 1


_crc_table(_CRC)


@micropython.viper
def scan(src: ptr8, pos: int, end: int, buf: ptr8, infos: ptr8) -> int:
    fast = 1
    if end < 0:
        fast = 0
        end = 0 - end
    k = pos
    while k < end:
        b = src[k]
        if b == 0xFD or b == 0xFE:
            break
        k += 1
    if k > pos:
        return -1 - (k << 2)
    more = -1 - (pos << 2 | 1)  # bytewise from pos
    if src[pos] == 0xFE:
        if end - pos < 6:
            return more
        plen = src[pos + 1]
        t = src[pos + 5] * 3
        full = infos[t + 2]
        if full == 0 or plen < infos[t + 1] or plen > full:
            return more
        hdr = 6
        n = plen + 8
        signed = 0
    else:
        if end - pos < 10:
            return more
        plen = src[pos + 1]
        signed = src[pos + 2]
        if signed > 1 or src[pos + 8] or src[pos + 9]:
            return more
        t = src[pos + 7] * 3
        full = infos[t + 2]
        if full == 0 or plen == 0 or plen > full:
            return more
        hdr = 10
        n = plen + 12
        if signed:
            n += 13
    if end - pos < n:
        return more
    # Copy and CRC in one pass over header and payload (dst: buf as seen from src's
    # indices), then CRC_EXTRA.
    crc = 0xFFFF
    tbl = ptr16(_CRC)
    dst = ptr8(int(buf) - pos)
    i = pos
    e = pos + hdr + plen
    dst[i] = src[i]
    i += 1
    while i < e:
        b = src[i]
        dst[i] = b
        crc = (crc >> 8) ^ tbl[(crc ^ b) & 0xFF]
        i += 1
    crc = (crc >> 8) ^ tbl[(crc ^ infos[t]) & 0xFF]
    if crc != (src[e] | src[e + 1] << 8):
        return more
    e = pos + n
    while i < e:
        dst[i] = src[i]
        i += 1
    if fast == 0 or signed:
        return -1 - (e << 2 | 2)
    i = hdr + plen
    full += hdr
    while i < full:
        buf[i] = 0
        i += 1
    # A sender already seen, with no sequence gap: count it here; else Python does.
    hdr = 2 if hdr == 6 else 4  # now the offset of seq, then sysid, compid
    i = SLOTS
    while i < BUF_LEN:
        if buf[i] and buf[i + 1] == buf[hdr + 1] and buf[i + 2] == buf[hdr + 2]:
            break
        i += 4
    if i == BUF_LEN or ((buf[hdr] - buf[i + 3] - 1) & 0xFF):
        return -1 - (e << 2 | 2)
    buf[i + 3] = buf[hdr]
    # Bit 0: the parser's version, payload and signed fields need setting (FIELDS says
    # what the last fast frame left in them; Python clears it when it sets them).
    if hdr == 2:
        if buf[FIELDS] == 1:
            return e << 2 | 2
        buf[FIELDS] = 1
        return e << 2 | 3
    if buf[FIELDS] == 2:
        return e << 2
    buf[FIELDS] = 2
    return e << 2 | 1
