"""STATUSTEXT queue: a few short messages for the ground stations, in fixed buffers.

Texts are copied into preallocated 50-byte slots (the field's size; longer texts are
cut). When the queue is full the oldest text is dropped and counted, so a burst of
reports never grows memory nor blocks the vehicle. Status drains it onto every link.
Reference: docs/core.md.
"""
import struct

from .compat import const
from .fields import cstr_text

_MSG_STATUSTEXT = const(253)
_TEXT_LEN = const(50)

# MAV_SEVERITY
EMERGENCY = const(0)
ALERT = const(1)
CRITICAL = const(2)
ERROR = const(3)
WARNING = const(4)
NOTICE = const(5)
INFO = const(6)
DEBUG = const(7)


class TextQueue:
    def __init__(self, slots=8):
        self.texts = [bytearray(_TEXT_LEN) for _ in range(slots)]
        self.severity = bytearray(slots)
        self.head = 0  # oldest
        self.count = 0
        self.dropped = 0  # overwritten before they were sent

    def put(self, severity, text):
        """Queue text (str or bytes; bytes allocate nothing) at a MAV_SEVERITY."""
        if isinstance(text, str):
            text = text.encode()
        slots = len(self.texts)
        if self.count == slots:
            self.head = (self.head + 1) % slots
            self.count -= 1
            self.dropped += 1
        i = (self.head + self.count) % slots
        _fill(self.texts[i], text)
        self.severity[i] = severity & 7
        self.count += 1

    def send(self, link):
        """Send the oldest text on one link (it stays queued until pop())."""
        i = self.head
        off = link.tx.clear(link.tx.crc_len[_MSG_STATUSTEXT] >> 16)
        link.txbuf[off] = self.severity[i]
        struct.pack_into("50s", link.txbuf, off + 1, self.texts[i])
        return link.send(_MSG_STATUSTEXT)

    def pop(self):
        if self.count:
            self.head = (self.head + 1) % len(self.texts)
            self.count -= 1

    def text(self, i=0):
        """The i-th oldest queued text as str (for tests and consoles; allocates)."""
        return cstr_text(self.texts[(self.head + i) % len(self.texts)], 0, _TEXT_LEN)


def _fill(buf, text):
    """buf := text, cut to buf's length (before a UTF-8 character, not inside it) and
    NUL-padded (a helper of its own, with while loops: docs/design.md)."""
    n = len(text)
    if n > len(buf):
        n = len(buf)
        while n > len(buf) - 3 and text[n] & 0xC0 == 0x80:  # text[n] continues a character
            n -= 1
    j = 0
    while j < n:
        buf[j] = text[j]
        j += 1
    while j < len(buf):
        buf[j] = 0
        j += 1
