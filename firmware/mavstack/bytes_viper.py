"""Byte kernels compiled to machine code with @micropython.viper (MicroPython only).

Same contract as bytes_portable: tests run both on the same inputs.
"""
import micropython


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
def zero(dst: ptr8, start: int, end: int):
    while start < end:
        dst[start] = 0
        start += 1
