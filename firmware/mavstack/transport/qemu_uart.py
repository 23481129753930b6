"""The emulated boards' MAVLink UART as a transport, driven through machine.mem32 (the
qemu port has no machine.UART): CMSDK UART 1 on the MPS2-AN385 (Cortex-M3; the REPL keeps
UART 0), the nRF51's one UART on the micro:bit (Cortex-M0), taken over from the REPL.
Its FIFO holds one (CMSDK) or six (nRF51) bytes, so the clock's sleep_ms drains it into a
ring, as a receive interrupt would, and readinto() takes from that ring.
Reference: docs/core.md.
"""
from machine import mem32 as _mem32

from ..qemu import MODEL, UARTS

if MODEL == "m3":
    _UART = 0x40005000  # CMSDK APB UART 1: DATA, STATE (+4), CTRL (+8), BAUDDIV (+16)
    _UART_STATE = 0x40005004
else:
    # nRF51 UART0 at 0x40002000. Addresses are written out: each is an int past 2^30
    # (docs/design.md), and base + offset would make a new one on every use.
    _RXDRDY = 0x40002108
    _RXD = 0x40002518
    _TXD = 0x4000251C


def _take(ring, h, dst, n):
    """dst[0:n] = n bytes of ring from h (wrapping) -> the new h."""
    size = len(ring)
    for i in range(n):
        dst[i] = ring[h]
        h += 1
        if h == size:
            h = 0
    return h


def _put(ring, i, b):
    ring[i % len(ring)] = b


class UartTransport:
    """The board's MAVLink UART as a transport (readinto/write/bytes_per_s/name/close).

    bytes_per_s is what the link budget assumes (the emulated UART itself is as fast
    as the pty): the baud rate a real radio link would have, / 10 for 8N1.
    """

    def __init__(self, baud=57600, ring=2048):
        self.bytes_per_s = baud // 10
        self.name = "uart-" + MODEL
        self._ring = bytearray(ring)
        self._head = 0
        self._count = 0
        if MODEL == "m3":
            _mem32[0x40005010] = 16  # BAUDDIV (QEMU wants >= 16 to pass data)
            _mem32[0x40005008] = 3  # CTRL: TX and RX enabled
        UARTS.append(self)

    if MODEL == "m3":

        def drain(self):
            # Stop when the ring is full: the rest waits in the UART (QEMU then stops
            # reading the pty), as hardware flow control would hold it.
            while self._count < len(self._ring) and _mem32[_UART_STATE] & 2:  # RXFULL
                _put(self._ring, self._head + self._count, _mem32[_UART])
                self._count += 1

        def _put(self, b):
            for _ in range(10000):  # TXFULL clears as soon as QEMU's pty takes the byte
                if not _mem32[_UART_STATE] & 1:
                    _mem32[_UART] = b
                    return True
            return False

    else:

        def drain(self):
            while self._count < len(self._ring) and _mem32[_RXDRDY]:
                _mem32[_RXDRDY] = 0
                _put(self._ring, self._head + self._count, _mem32[_RXD])
                self._count += 1

        def _put(self, b):
            _mem32[_TXD] = b  # QEMU's nRF51 UART sends at once
            return True

    def readinto(self, buf, limit=0):
        # (small functions: docs/design.md)
        self.drain()
        n = self._count
        if n > len(buf):
            n = len(buf)
        if limit and n > limit:
            n = limit
        self._head = _take(self._ring, self._head, buf, n)
        self._count -= n
        return n

    def write(self, buf, n):
        for i in range(n):
            if not self._put(buf[i]):
                return i
        return n

    def close(self):
        # A vehicle restarted in place opens the UART again: this one stops draining it.
        if self in UARTS:
            UARTS.remove(self)
