"""Peripherals of the emulated boards (boards/qemu_m3.py, qemu_m0.py), driven through
machine.mem32: MicroPython's qemu port has no `time` module (before 1.27) and no
machine.UART, so the clock and the MAVLink UART (a transport) are here: one module,
as sleep_ms drains the UART, and the boards that run on them load nothing else.

  MPS2-AN385 (Cortex-M3)  clock: CMSDK APB timer 0 at 25 MHz; MAVLink: CMSDK UART 1
                          (QEMU's second -serial; the REPL keeps UART 0); watchdog:
                          the CMSDK APB watchdog
  micro:bit (Cortex-M0)   clock: nRF51 TIMER0 at 31.25 kHz; MAVLink: the one UART,
                          taken over from the REPL when the vehicle starts; no watchdog

Every register value read while the vehicle runs is below 2^30, a small int
(docs/design.md). Waiting (sleep_ms) drains the UARTs' small receive FIFOs into their
rings, as a receive interrupt would. Reference: docs/core.md; the watchdog:
docs/reliability.md.
"""
import machine

from micropython import const  # (not compat: compat imports this module)

_mem32 = machine.mem32
_MASK = const(0x3FFFFFFF)  # MicroPython's ticks period: 2^30
_HALF = const(0x20000000)
_PERIOD_M3 = const(1000000000)  # CMSDK timer counts a wrap: 40 s at 25 MHz, below 2^30
_KHZ_M3 = const(25000)  # its counts a ms
_GAP_US = const(1000)  # a receiving UART quiet this long: what came is whole (wait_ms)
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


# The M3's clock and UART in viper where the firmware has the native emitter
# (qemu_viper.py); the Python below is the fallback, with the same results.
VIPER = False
if MODEL == "m3":
    try:
        from .qemu_viper import clock_update, uart_drain, uart_write, ring_take

        VIPER = True
    except ImportError:
        pass


class _Clock:
    """Milliseconds since boot, wrapped like time.ticks_ms(), from the counter's deltas."""

    def __init__(self):
        self.last = self.read()
        self.sub = 0  # counts (M3) or microseconds (M0) not yet a whole ms
        self.ms = 0
        self.us = 0
        if VIPER:
            from array import array

            self._st = array("i", (self.last, 0, 0, 0, 0))  # clock_update's state

    if MODEL == "m3":

        def read(self):
            return _mem32[_VALUE]

    if VIPER:

        def update(self):
            self.ms = clock_update(self._st)
            self.us = self._st[3]
            return self.ms

    elif MODEL == "m3":

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
UARTS = []  # the transports whose FIFOs sleep_ms drains


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


if VIPER:  # the same, a call cheaper (qemu_viper.py)
    from .qemu_viper import ticks_add, ticks_diff  # noqa: F811

    _ST = _clock._st

    def ticks_ms():  # noqa: F811
        return clock_update(_ST)

    def ticks_us():  # noqa: F811
        clock_update(_ST)
        return _ST[3]


def sleep_ms(ms):
    end = ticks_add(_clock.update(), ms)
    while True:
        for u in UARTS:
            u.drain()
        if ticks_diff(end, _clock.update()) <= 0:
            return


def wait_ms(ms):
    """sleep_ms that ends early once bytes came into a UART's ring and the line has
    been quiet for _GAP_US since, as a receive-idle interrupt would tell: a frame comes
    in whole, not a pass a byte (the loop's sleep, sleeper.py)."""
    end = ticks_add(ticks_ms(), ms)
    heard = -1  # ticks_us() when bytes last came, -1: none yet
    while True:
        for u in UARTS:
            if u.drain():
                heard = ticks_us()
        if heard >= 0 and ticks_diff(ticks_us(), heard) >= _GAP_US:
            return
        if ticks_diff(end, ticks_ms()) <= 0:
            return


# --- the MAVLink UART ----------------------------------------------------------
if MODEL == "m3":
    _UART = 0x40005000  # CMSDK APB UART 1: DATA, STATE (+4), CTRL (+8), BAUDDIV (+16)
    _UART_STATE = 0x40005004
else:
    # nRF51 UART0 at 0x40002000. Addresses are written out: each is an int past 2^30
    # (docs/design.md), and base + offset would make a new one on every use.
    _RXDRDY = 0x40002108
    _RXD = 0x40002518
    _TXD = 0x4000251C


def _take(ring, size, h, dst, n):
    """dst[0:n] = n bytes of ring from h (wrapping) -> the new h."""
    for i in range(n):
        dst[i] = ring[h]
        h += 1
        if h == size:
            h = 0
    return h


def _tx_room():
    """Wait for the M3 UART's TXFULL to clear (it does as soon as QEMU's pty takes the
    byte) -> False when it does not."""
    for _ in range(10000):
        if not _mem32[_UART_STATE] & 1:
            return True
    return False


class UartTransport:
    """The board's MAVLink UART as a transport (readinto/write/bytes_per_s/name/close).

    bytes_per_s is what the link budget assumes (the emulated UART itself is as fast
    as the pty): the baud rate a real radio link would have, / 10 for 8N1.
    """

    rx_chunk = 128  # what the link reads at a time (link.py); the ring holds more

    def __init__(self, baud=57600, ring=256):
        self.bytes_per_s = baud // 10
        self.name = "uart-" + MODEL
        self._ring = bytearray(ring)
        self._head = 0
        self._count = 0
        if MODEL == "m3":
            _mem32[0x40005010] = 16  # BAUDDIV (QEMU wants >= 16 to pass data)
            _mem32[0x40005008] = 3  # CTRL: TX and RX enabled
        UARTS.append(self)

    if VIPER:

        def drain(self):
            n = uart_drain(self._ring, len(self._ring), self._head, self._count)
            return self._took(n)

        def write(self, buf, n):
            return uart_write(buf, n)

    elif MODEL == "m3":

        def drain(self):
            """Bytes from the UART into the ring -> how many. Stops when the ring is
            full: the rest waits in the UART (QEMU then stops reading the pty), as
            hardware flow control would hold it."""
            n = self._count
            while n < len(self._ring) and _mem32[_UART_STATE] & 2:  # RXFULL
                self._put(n, _mem32[_UART])
                n += 1
            return self._took(n)

        def write(self, buf, n):
            i = 0
            while i < n:
                if _mem32[_UART_STATE] & 1 and not _tx_room():  # TXFULL
                    return i
                _mem32[_UART] = buf[i]
                i += 1
            return n

    else:

        def drain(self):
            n = self._count
            while n < len(self._ring) and _mem32[_RXDRDY]:
                _mem32[_RXDRDY] = 0
                self._put(n, _mem32[_RXD])
                n += 1
            return self._took(n)

        def write(self, buf, n):
            for i in range(n):
                _mem32[_TXD] = buf[i]  # QEMU's nRF51 UART sends at once
            return n

    def _put(self, n, b):
        # The ring's byte n from its head.
        i = self._head + n
        self._ring[i if i < len(self._ring) else i - len(self._ring)] = b

    def _took(self, n):
        k = n - self._count
        self._count = n
        return k

    def readinto(self, buf, limit=0):
        # (small functions: docs/design.md)
        self.drain()
        n = self._count
        if n > len(buf):
            n = len(buf)
        if limit and n > limit:
            n = limit
        self._head = (ring_take if VIPER else _take)(self._ring, len(self._ring), self._head, buf, n)
        self._count -= n
        return n

    def close(self):
        # A vehicle restarted in place opens the UART again: this one stops draining it.
        if self in UARTS:
            UARTS.remove(self)


# --- the watchdog (MPS2-AN385 only) ----------------------------------------------
if MODEL == "m3":
    # CMSDK APB watchdog at 0x40008000 (LOAD, VALUE +4, CONTROL +8, INTCLR +0xC, RIS
    # +0x10), counting down at 25 MHz. Its counter always runs: at zero it sets RIS and
    # starts again from LOAD; at zero again with RIS still set it latches its reset, which
    # RESEN passes on (QEMU 7.2 resets the machine). Writing INTCLR clears RIS and starts
    # again from LOAD: the feed. Addresses are written out where used: each is an int
    # past 2^30, a constant there, a heap object as a global (docs/design.md).
    _COUNTS_HALF_MS = const(12500)  # LOAD a ms of the timeout: the counter runs out twice
    _RESEN = const(2)  # CONTROL: reset enabled (not INTEN: the port has no handler for it)

    class Watchdog:
        """The board reset when feed() is not called for `ms`. `restart` is a RAM word
        kept through a reset: non-zero while the watchdog runs, so that the firmware
        starts the vehicle again after the reset (mcu/firmware.py)."""

        def __init__(self, ms, restart):
            self.restart = restart
            _mem32[0x40008000] = ms * _COUNTS_HALF_MS  # LOAD
            _mem32[0x4000800C] = 1  # INTCLR
            _mem32[0x40008008] = _RESEN  # CONTROL
            _mem32[restart] = 1

        def feed(self):
            _mem32[0x4000800C] = 1  # INTCLR

        def reset(self):
            """Reset the board now, as machine.reset() does a real one: the counter from
            its shortest load, not fed. The restart word stays: the vehicle starts again."""
            _mem32[0x40008000] = 1  # LOAD (reloads the counter)
            while True:
                pass

        def stop(self):
            """Back to the REPL: no reset, no restart. The counter runs on (it cannot be
            stopped) from the longest LOAD, 172 s a turn."""
            _mem32[0x40008008] = 0
            _mem32[0x40008000] = -1
            _mem32[0x4000800C] = 1
            _mem32[self.restart] = 0

    def latched():
        """The watchdog ran out twice since the board's reset (343 s at an idle REPL from
        power-on or from stop()): its reset is latched, and enabling it would reset the
        board at once; only a reset clears it. Its counter stands still then (RIS set)."""
        return _mem32[0x40008010] and _mem32[0x40008004] == _mem32[0x40008004]
