"""Serial byte transports: a tty or pty on a unix host, and a board's machine.UART.

Same face as every transport (transport/__init__.py): readinto(buf), write(buf, n),
bytes_per_s (the baud rate / 10: 8N1 takes ten bit times a byte), name, close().
Reference: docs/core.md.
"""
from ..compat import MICROPYTHON


class SerialTransport:
    """A tty or pty on a unix host (MicroPython's unix port or CPython), raw mode.

    Reads never wait: the terminal is set to return at once with what it has
    (VMIN=0, VTIME=0). Writes are skipped while the device cannot take them.
    """

    rx_peer = None  # one peer at the other end of the wire: no address

    def __init__(self, device, baud):
        import termios

        self.device = device
        self.baud = baud
        self.bytes_per_s = baud // 10  # 8N1: ten bit times a byte
        self.name = "serial:%s:%d" % (device, baud)
        if MICROPYTHON:
            self._f = open(device, "r+b")
            fd = self._f.fileno()
        else:
            import os

            fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            self._f = None
        self.fd = fd
        self.waitable = self._f if MICROPYTHON else fd  # for the loop's sleep (sleeper.py)
        if MICROPYTHON:
            termios.setraw(fd)
        else:  # CPython keeps setraw in the tty module
            import tty

            tty.setraw(fd)
        attr = termios.tcgetattr(fd)
        attr[6][6] = 0  # VMIN
        attr[6][5] = 0  # VTIME
        speed = getattr(termios, "B%d" % baud, None)
        if speed is not None:
            attr[4] = attr[5] = speed
        termios.tcsetattr(fd, termios.TCSANOW, attr)
        import select

        self._poll = select.poll()
        self._poll.register(self._f if MICROPYTHON else fd, select.POLLOUT)
        self._POLLOUT = select.POLLOUT
        self._n = 0  # write's count for _write (made here: the heap may be locked later)

    if MICROPYTHON:

        # Small functions, few locals (a try takes frame words too): docs/design.md.
        def readinto(self, buf):
            try:
                return self._f.readinto(buf) or 0
            except OSError:
                return 0

        def write(self, buf, n):
            if not self._writable():
                return 0
            self._n = n
            return self._write(buf)

        def _writable(self):
            for _obj, ev in self._poll.ipoll(0):
                if ev & self._POLLOUT:
                    return True
            return False

        def _write(self, buf):
            try:
                return self._f.write(buf, self._n) or 0
            except OSError:
                return 0

    else:

        def readinto(self, buf):
            import os

            try:
                return os.readv(self.fd, [buf])
            except OSError:
                return 0

        def write(self, buf, n):
            import os

            try:
                return os.write(self.fd, memoryview(buf)[:n])
            except OSError:
                return 0

    def close(self):
        if self._f is not None:
            self._f.close()
        else:
            import os

            os.close(self.fd)


class UartTransport:
    """A board's machine.UART, created by the board profile."""

    rx_peer = None

    def __init__(self, uart, baud, name="uart"):
        self.uart = uart
        self.bytes_per_s = baud // 10
        self.name = name

    def readinto(self, buf):
        if not self.uart.any():
            return 0
        return self.uart.readinto(buf) or 0

    def write(self, buf, n):
        return self.uart.write(buf, n) or 0

    def close(self):
        pass
