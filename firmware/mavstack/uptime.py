"""The vehicle's clock as the messages carry it: time since boot in ms (uint32) and us
(uint64), and the time of day in unix us (uint64) once something has told it.

All three are kept as little-endian bytes and stamped into payloads as bytes (uptime
passes 2^30 ms after 12.4 days, 2^30 us after 18 minutes, and the time of day always:
docs/design.md). The endpoint's poll tells it the time; what passed is added bytewise
when the time is next read (or within a minute), so nothing here allocates and a pass
without a reader costs a comparison.

    clock = ep.clock                   # made by the endpoint, advanced by its poll
    clock.stamp_ms(buf, off)           # time_boot_ms
    clock.stamp_us(buf, off)           # time_usec (since boot)
    clock.stamp_unix(buf, off)         # time_unix_usec (0 while unknown)
    clock.seconds                      # uptime in whole seconds (a small int for years)
Reference: docs/core.md.
"""
from .compat import const, ticks_diff
from .kernels import place

_LAZY_MS = const(50000)  # the most advance() leaves uncounted


def add_le(buf, n, size):
    """buf[0:size] (little-endian unsigned) += n, for 0 <= n < 2^22; wraps like the field."""
    i = 0
    while n and i < size:
        n += buf[i]
        buf[i] = n & 0xFF
        n >>= 8
        i += 1


def _copy(dst, off, src, n):
    place(dst, off, src, n)


class Clock:
    def __init__(self, now, offset_ms=0):
        self.ms = bytearray(8)  # uptime in ms (time_boot_ms is its low four bytes)
        self.us = bytearray(8)  # uptime in us
        self.unix = bytearray(8)  # unix time in us, all zero while unknown
        self.known = False
        self._seconds = 0
        self._sub_ms = 0  # ms not yet a whole second
        self._last = self._now = now
        if offset_ms:  # tests start the clock late, to see values past 2^30 (boot only)
            for i in range(8):
                self.ms[i] = (offset_ms >> (8 * i)) & 0xFF
                self.us[i] = (offset_ms * 1000 >> (8 * i)) & 0xFF
            self._seconds = offset_ms // 1000
            self._sub_ms = offset_ms % 1000

    def advance(self, now):
        """The time is now (the endpoint's poll, every pass). Counted into the bytes when
        they are next read, or once the time not counted nears a minute: a pass costs a
        comparison, not three sums."""
        self._now = now
        if ticks_diff(now, self._last) > _LAZY_MS:
            self._count()

    def _count(self):
        now = self._now
        d = ticks_diff(now, self._last)
        self._last = now
        if d <= 0:  # the same ms, or a clock set back: nothing to add
            return
        while d > 4000:  # a long stall: in steps that keep d * 1000 below 2^22
            self._add(4000)
            d -= 4000
        self._add(d)

    def _add(self, d):
        add_le(self.ms, d, 8)
        us = d * 1000
        add_le(self.us, us, 8)
        if self.known:
            add_le(self.unix, us, 8)
        s = self._sub_ms + d
        self._seconds += s // 1000
        self._sub_ms = s % 1000

    def set_unix(self, src, off=0):
        """Time of day from 8 little-endian bytes (SYSTEM_TIME, GPS); zero means unknown."""
        self._count()  # (the time before it is not added to the new time of day)
        known = False
        for i in range(8):
            b = src[off + i]
            self.unix[i] = b
            if b:
                known = True
        self.known = known

    def stamp_ms(self, buf, off):
        self._count()
        _copy(buf, off, self.ms, 4)

    def stamp_us(self, buf, off):
        self._count()
        _copy(buf, off, self.us, 8)

    def stamp_us32(self, buf, off):
        """A uint32 time_usec (SERVO_OUTPUT_RAW): the low four bytes."""
        self._count()
        _copy(buf, off, self.us, 4)

    def stamp_unix(self, buf, off):
        self._count()
        _copy(buf, off, self.unix, 8)

    @property
    def seconds(self):
        self._count()
        return self._seconds

    # Python ints, for the application and tests (past the small ints: docs/design.md).
    def uptime_ms(self):
        self._count()
        return int.from_bytes(self.ms, "little")

    def unix_usec(self):
        self._count()
        return int.from_bytes(self.unix, "little")
