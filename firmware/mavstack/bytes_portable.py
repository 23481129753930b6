"""Byte kernels in plain Python: the fallback where viper is unavailable, and CPython.

Contract shared with bytes_viper:
  crc16(buf, start, end, crc)  X.25 (CRC-16/MCRF4XX) over buf[start:end], continuing crc
  find_stx(src, pos, end)      index of the first 0xFD/0xFE in src[pos:end], else end
  copy(dst, src, offsets, n)   dst[d:d+n] = src[s:s+n], offsets = d | s << 10 (d < 1024)
  zero(dst, start, end)        dst[start:end] = 0
Loops over indices rather than slices so that nothing is allocated on MicroPython.
"""


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
