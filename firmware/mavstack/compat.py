"""What differs between MicroPython and CPython, in one place.

The stack is written for MicroPython; on CPython (tests, host tools) the few
MicroPython-only names get plain equivalents (compat_cpython.py).
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
    from .compat_cpython import const

    micropython = None
    MICROPYTHON = False


if time is None:
    from .qemu import ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms
elif hasattr(time, "ticks_ms"):
    ticks_ms = time.ticks_ms
    ticks_us = time.ticks_us
    ticks_diff = time.ticks_diff
    ticks_add = time.ticks_add
    sleep_ms = time.sleep_ms
else:  # CPython
    from .compat_cpython import ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms


def getenv(name):
    try:
        import os

        return os.getenv(name)
    except (ImportError, AttributeError):
        return None
