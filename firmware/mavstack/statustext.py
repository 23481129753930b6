"""STATUSTEXT queue: a few short messages for the ground stations, in fixed buffers.

Texts are copied into preallocated 50-byte slots (the field's size; longer texts are
cut). When the queue is full the oldest text is dropped and counted, so a burst of
reports never grows memory nor blocks the vehicle. Status drains it onto every link.
Reference: docs/core.md.
"""
from .compat import const
from .fields import cstr_text
from .kernels import copy

_MSG_STATUSTEXT = const(253)
_TEXT_LEN = const(50)
_SLOT = const(51)  # a queued text: its severity, then its 50 bytes

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
        # One block for every slot (a buffer apiece cost twice the heap): slot i's
        # severity at i * _SLOT, its text after it.
        self.buf = bytearray(slots * _SLOT)
        self.slots = slots
        self.head = 0  # oldest
        self.count = 0
        self.dropped = 0  # overwritten before they were sent

    def put(self, severity, text):
        """Queue text (str or bytes; bytes allocate nothing) at a MAV_SEVERITY."""
        if isinstance(text, str):
            text = text.encode()
        slots = self.slots
        if self.count == slots:
            self.head = (self.head + 1) % slots
            self.count -= 1
            self.dropped += 1
        o = (self.head + self.count) % slots * _SLOT
        self.buf[o] = severity & 7
        _fill(self.buf, o + 1, text)
        self.count += 1

    def send(self, link):
        """Send the oldest text on one link (it stays queued until pop())."""
        off = link.tx.clear(link.tx.crc_len[_MSG_STATUSTEXT] >> 16)
        copy(link.txbuf, self.buf, self.head * _SLOT << 10 | off, _SLOT)  # severity, text
        return link.send(_MSG_STATUSTEXT)

    def pop(self):
        if self.count:
            self.head = (self.head + 1) % self.slots
            self.count -= 1

    def text(self, i=0):
        """The i-th oldest queued text as str (for tests and consoles; allocates)."""
        return cstr_text(self.buf, (self.head + i) % self.slots * _SLOT + 1, _TEXT_LEN)


def _fill(buf, o, text):
    """buf[o:o + _TEXT_LEN] := text, cut to that length (before a UTF-8 character, not
    inside it) and NUL-padded (a helper of its own, with while loops: docs/design.md)."""
    n = len(text)
    if n > _TEXT_LEN:
        n = _TEXT_LEN
        while n > _TEXT_LEN - 3 and text[n] & 0xC0 == 0x80:  # text[n] continues a character
            n -= 1
    j = 0
    while j < n:
        buf[o + j] = text[j]
        j += 1
    while j < _TEXT_LEN:
        buf[o + j] = 0
        j += 1
