"""What differs between MicroPython and CPython, in one place.

The stack is written for MicroPython; on CPython (tests, host tools) the few
MicroPython-only names get plain equivalents (compat_cpython.py), and on the emulated
boards the clock comes from qemu.py. Reference: docs/core.md.
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


wait_ms = None  # sleep_ms that ends when a byte comes, where the port has one (sleeper.py)
if time is None:
    from .qemu import ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms, wait_ms
elif hasattr(time, "ticks_ms"):
    ticks_ms = time.ticks_ms
    ticks_us = time.ticks_us
    ticks_diff = time.ticks_diff
    ticks_add = time.ticks_add
    sleep_ms = time.sleep_ms
else:  # CPython
    from .compat_cpython import ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms


def to_grid(now, period):
    """ms from now to the next point of period's grid (its multiples on the tick count)
    at least an eighth of a period ahead: periodic work on one grid falls due together
    and shares the loop's wakes, and a run a little early keeps its place (docs/core.md)."""
    ms = period - now % period
    return ms + period if ms < period >> 3 else ms


# A rare event (a file save, a new UDP peer) may take from the heap even where the board
# locks it after start-up (HEAP_LOCK guards the per-frame and per-tick paths): it opens
# the lock for the event and closes it again. heap_unlock() says how deep the lock was.
def heap_open():
    """Unlock the heap whatever its lock depth -> that depth, for heap_close()."""
    if micropython is None or not hasattr(micropython, "heap_lock"):
        return 0
    micropython.heap_lock()
    depth = micropython.heap_unlock()
    for _ in range(depth):
        micropython.heap_unlock()
    return depth


def heap_close(depth):
    for _ in range(depth):
        micropython.heap_lock()


def getenv(name):
    try:
        import os

        return os.getenv(name)
    except (ImportError, AttributeError):
        return None
