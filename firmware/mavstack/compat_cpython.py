"""MicroPython's names for CPython (tests, host tools): compat.py imports them there.

Apart from compat.py, so that a board does not load code it never runs.
"""
import time

# Same wrap-around as MicroPython's ports, so wrap handling is exercised here too.
_TICKS_PERIOD = 1 << 30
_TICKS_HALF = _TICKS_PERIOD >> 1


def const(x):
    return x


def ticks_ms():
    return int(time.monotonic() * 1000) & (_TICKS_PERIOD - 1)


def ticks_us():
    return int(time.perf_counter() * 1000000) & (_TICKS_PERIOD - 1)


def ticks_add(t, delta):
    return (t + delta) & (_TICKS_PERIOD - 1)


def ticks_diff(a, b):
    return ((a - b + _TICKS_HALF) & (_TICKS_PERIOD - 1)) - _TICKS_HALF


def sleep_ms(ms):
    time.sleep(ms / 1000)
