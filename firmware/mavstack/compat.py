"""What differs between MicroPython and CPython, in one place.

The stack is written for MicroPython; on CPython (tests, host tools) the few
MicroPython-only names get plain equivalents here.
"""
import time

try:
    from micropython import const
    import micropython

    MICROPYTHON = True
except ImportError:
    micropython = None
    MICROPYTHON = False

    def const(x):
        return x


if hasattr(time, "ticks_ms"):
    ticks_ms = time.ticks_ms
    ticks_diff = time.ticks_diff
    ticks_add = time.ticks_add
    sleep_ms = time.sleep_ms
else:
    # Same wrap-around as MicroPython's ports, so wrap handling is exercised here too.
    _TICKS_PERIOD = 1 << 30
    _TICKS_HALF = _TICKS_PERIOD >> 1

    def ticks_ms():
        return int(time.monotonic() * 1000) & (_TICKS_PERIOD - 1)

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
