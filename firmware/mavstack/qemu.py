"""Peripherals of the emulated boards (boards/qemu_m3.py, qemu_m0.py), driven through
machine.mem32: MicroPython's qemu port has no `time` module (before 1.27) and no
machine.UART, so the clock is here and the MAVLink UART in transport/qemu_uart.py.

  MPS2-AN385 (Cortex-M3)  clock: CMSDK APB timer 0 at 25 MHz; MAVLink: CMSDK UART 1
                          (QEMU's second -serial; the REPL keeps UART 0)
  micro:bit (Cortex-M0)   clock: nRF51 TIMER0 at 31.25 kHz; MAVLink: the one UART,
                          taken over from the REPL when the vehicle starts

Every register value read here is below 2^30, a small int (docs/design.md). Waiting
(sleep_ms) drains the UARTs' small receive FIFOs into their rings, as a receive
interrupt would. Reference: docs/core.md.
"""
import machine

from micropython import const  # (not compat: compat imports this module)

_mem32 = machine.mem32
_MASK = const(0x3FFFFFFF)  # MicroPython's ticks period: 2^30
_HALF = const(0x20000000)
_PERIOD_M3 = const(1000000000)  # CMSDK timer counts a wrap: 40 s at 25 MHz, below 2^30
_KHZ_M3 = const(25000)  # its counts a ms
_PERIOD_M0 = const(0x1000000)  # nRF51 timer in 24-bit mode: a wrap is 537 s of 32 us counts

# SCB CPUID (the same address on every Cortex-M): part number 0xC20 is a Cortex-M0.
MODEL = "m0" if (_mem32[0xE000ED00] >> 4) & 0xFFF == 0xC20 else "m3"

if MODEL == "m3":
    _TIMER = 0x40000000  # CMSDK APB timer 0: counts down from RELOAD at 25 MHz
    _VALUE = 0x40000004
    _mem32[0x40000008] = _PERIOD_M3 - 1  # RELOAD
    _mem32[_VALUE] = _PERIOD_M3 - 1
    _mem32[_TIMER] = 1  # CTRL: enable
else:
    _TIMER = 0x40008000  # nRF51 TIMER0, counting up; CAPTURE[0] copies it into CC[0]
    _CAPTURE = 0x40008040
    _VALUE = 0x40008540
    _mem32[0x40008504] = 0  # MODE: timer
    _mem32[0x40008508] = 2  # BITMODE: 24 bit
    _mem32[0x40008510] = 9  # PRESCALER: 16 MHz / 2^9
    _mem32[0x4000800C] = 1  # TASKS_CLEAR
    _mem32[_TIMER] = 1  # TASKS_START


class _Clock:
    """Milliseconds since boot, wrapped like time.ticks_ms(), from the counter's deltas."""

    def __init__(self):
        self.last = self.read()
        self.sub = 0  # counts (M3) or microseconds (M0) not yet a whole ms
        self.ms = 0
        self.us = 0

    if MODEL == "m3":

        def read(self):
            return _mem32[_VALUE]

        def update(self):
            v = _mem32[_VALUE]
            d = self.last - v  # counting down
            if d < 0:
                d += _PERIOD_M3
            self.last = v
            self.us = ticks_add(self.us, d // 25)
            sub = self.sub + d
            self.ms = ticks_add(self.ms, sub // _KHZ_M3)
            self.sub = sub % _KHZ_M3
            return self.ms

    else:

        def read(self):
            _mem32[_CAPTURE] = 1
            return _mem32[_VALUE]

        def update(self):
            _mem32[_CAPTURE] = 1
            v = _mem32[_VALUE]
            d = v - self.last  # counting up, 24 bits
            if d < 0:
                d += _PERIOD_M0
            self.last = v
            d <<= 5  # 32 us a count (< 2^29)
            self.us = ticks_add(self.us, d)
            sub = self.sub + d
            self.ms = ticks_add(self.ms, sub // 1000)
            self.sub = sub % 1000
            return self.ms


_clock = _Clock()
UARTS = []  # the transports whose FIFOs sleep_ms drains (transport/qemu_uart.py)


def ticks_ms():
    return _clock.update()


def ticks_us():
    _clock.update()
    return _clock.us


# Wrapping arithmetic on the 30-bit ticks with every intermediate value a small int
# (t + delta itself can pass 2^30: docs/design.md).
def ticks_add(t, delta):
    if t >= _HALF:
        t = t - _HALF - _HALF
    return (t + delta) & _MASK


def ticks_diff(a, b):
    d = a - b
    if d >= _HALF:
        return d - _HALF - _HALF
    if d < -_HALF:
        return d + _HALF + _HALF
    return d


def sleep_ms(ms):
    end = ticks_add(_clock.update(), ms)
    while True:
        for u in UARTS:
            u.drain()
        if ticks_diff(end, _clock.update()) <= 0:
            return
