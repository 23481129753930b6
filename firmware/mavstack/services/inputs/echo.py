"""What the inputs service sends back: the setpoints it took, and HIL_CONTROLS.

Each setpoint is answered with its target message (ECHOES below: SET_POSITION_TARGET_*
-> POSITION_TARGET_*, SET_ATTITUDE_TARGET -> ATTITUDE_TARGET, the seed's two), a slot the
streams send, its fields copied as bytes. In HIL, HIL_CONTROLS carries the pilot's manual
input as float32s made from integers. Reference: docs/services/inputs.md.
"""
from ...kernels import copy
from ..streams.slots import Slot


class Echo:
    """Copies n bytes from the setpoint's offset `src` to the slot's `dst`, and one byte
    (type_mask or frame) from `src_byte` to `dst_byte` (-1: none); stamps time_boot_ms
    at 0 when `stamp`."""

    def __init__(self, ep, msgid, src, dst, n, src_byte=-1, dst_byte=-1, stamp=True):
        self.slot = Slot(ep, msgid)
        self.clock = ep.clock
        self.offsets = src << 10 | dst
        self.n = n
        self.src_byte = src_byte
        self.dst_byte = dst_byte
        self.stamp = stamp
        ep.producers[msgid] = self.slot.send

    def answer(self, p):
        b = self.slot.buf
        copy(b, p, self.offsets, self.n)
        if self.src_byte >= 0:
            b[self.dst_byte] = p[self.src_byte]
        if self.stamp:
            self.clock.stamp_ms(b, 0)
        self.slot.written = True


# (setpoint id, target id, src, dst, n, src_byte, dst_byte, stamp, seed crc_extra or -1)
ECHOES = (
    (84, 85, 4, 4, 46, 52, 50, True, -1),  # x..yaw_rate, type_mask; coordinate_frame
    (86, 87, 4, 4, 46, 52, 50, True, -1),
    (82, 83, 4, 4, 32, 38, 36, True, -1),  # q, rates, thrust; type_mask
    (50, 51, 0, 0, 16, 18, 16, False, 0xD6),  # seed: x y z yaw; coordinate_frame
    (53, 52, 0, 0, 15, -1, -1, False, 0x21),  # seed: the same layout, copied whole
)


class HilControls:
    """The HIL_CONTROLS slot: time_usec, roll, pitch, yaw, throttle, aux1-4, mode, nav_mode."""

    def __init__(self, ep):
        self.slot = Slot(ep, 91)
        self.clock = ep.clock
        ep.producers[91] = self.slot.send

    def write(self, manual, base_mode):
        b = self.slot.buf
        self.clock.stamp_us(b, 0)
        if manual is not None and manual.fresh():
            put_f32_milli(b, 8, manual.y())
            put_f32_milli(b, 12, manual.x())
            put_f32_milli(b, 16, manual.r())
            put_f32_milli(b, 20, manual.z())
        else:
            _zero(b, 8, 24)
        b[40] = base_mode
        self.slot.written = True


def _zero(b, o, end):
    while o < end:
        b[o] = 0
        o += 1


def put_f32_milli(b, o, n):
    """Write n / 1000 as a little-endian float32 at b[o] from integer arithmetic alone
    (|n| < 2^20): the mantissa by long division, rounded to nearest (in small functions:
    see docs/design.md)."""
    if n == 0:
        _zero(b, o, o + 4)
        return
    sign = 0x80 if n < 0 else 0
    if n < 0:
        n = -n
    e = _exponent(n)
    m = _mantissa(n, e)
    if m >= 0x800000:  # rounded up to the next power of two
        m = 0
        e += 1
    b[o] = m & 0xFF
    b[o + 1] = m >> 8 & 0xFF
    b[o + 2] = (m >> 16 & 0x7F) | (e & 1) << 7
    b[o + 3] = sign | e >> 1


def _exponent(n):
    # The biased exponent of n / 1000 (n > 0).
    e = 127
    d = 1000
    while n >= d << 1:
        d <<= 1
        e += 1
    while n < d:
        n <<= 1
        e -= 1
    return e


def _mantissa(n, e):
    # The 23 fraction bits of n / 1000 = 1.f * 2^(e - 127), rounded (2^23: carried over).
    if e >= 127:
        d = 1000 << (e - 127)
    else:
        d = 1000
        n <<= 127 - e
    r = n - d
    m = 0
    i = 0
    while i < 24:  # 23 bits and one to round with
        r <<= 1
        m <<= 1
        if r >= d:
            r -= d
            m |= 1
        i += 1
    return (m + 1) >> 1
