"""What differs between MicroPython and CPython, in one place.

The stack is written for MicroPython; on CPython (tests, host tools) the few
MicroPython-only names get plain equivalents here.
"""
try:
    import time
except ImportError:  # MicroPython's qemu port before 1.27: the clock is a timer (qemu.py)
    time = None

try:
    from micropython import const
    import micropython

    MICROPYTHON = True
except ImportError:
    micropython = None
    MICROPYTHON = False

    def const(x):
        return x


if time is None:
    from .qemu import ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms
elif hasattr(time, "ticks_ms"):
    ticks_ms = time.ticks_ms
    ticks_us = time.ticks_us
    ticks_diff = time.ticks_diff
    ticks_add = time.ticks_add
    sleep_ms = time.sleep_ms
else:
    # Same wrap-around as MicroPython's ports, so wrap handling is exercised here too.
    _TICKS_PERIOD = 1 << 30
    _TICKS_HALF = _TICKS_PERIOD >> 1

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


def getenv(name):
    try:
        import os

        return os.getenv(name)
    except (ImportError, AttributeError):
        return None
