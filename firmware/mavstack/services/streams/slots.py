"""Slots: a message's payload kept ready to send, and the packers that fill payloads.

A Slot holds one message's preallocated payload: whoever owns it packs values in place
(allocating nothing) and its send() is the message's producer, sending the last value
written (nothing until one is). NamedSlot keeps one payload per name (NAMED_VALUE_*); a Sink takes what
nobody sends.
The telemetry writers, the inputs service's echoes and other services' slots are made
of these. Reference: docs/services/streams.md.
"""
from struct import calcsize, pack_into

from ...compat import const

# NAMED_VALUE_* carry several values told apart by name; each name keeps its own payload.
NAMED_VALUES = 4

_UNUSED_U16 = const(0xFFFF)
_UNUSED_I16 = const(0x7FFF)


def split_fmt(fmt, base_len):
    """('<base', '<extensions' or None) of a payload format: the MAVLink 1 fields
    (the first base_len bytes) and those MAVLink 2 appended."""
    for i in range(1, len(fmt)):
        if "0" <= fmt[i] <= "9":
            continue
        if calcsize(fmt[: i + 1]) == base_len:
            if i + 1 == len(fmt):
                return fmt, None
            return fmt[: i + 1], "<" + fmt[i + 1:]
    raise ValueError("format %r is not %d bytes" % (fmt, base_len))


class Slot:
    """One message's payload, packed by its setter and sent as it stands."""

    def __init__(self, ep, msgid):
        info = ep.dialect.CRC_LEN[msgid]
        self.msgid = msgid
        self.size = info >> 16
        self.buf = bytearray(self.size)
        self.ext_off = (info >> 8) & 0xFF
        self.base, self.ext = split_fmt(ep.fmt(msgid), self.ext_off)
        self.written = False

    def send(self, link):
        """Producer: send the last value written; False while there is none."""
        if not self.written:
            return False
        return link.send_payload(self.msgid, self.buf, self.size)


class NamedSlot(Slot):
    """NAMED_VALUE_FLOAT/INT: up to NAMED_VALUES names, sent in turn."""

    def __init__(self, ep, msgid, count=NAMED_VALUES):
        Slot.__init__(self, ep, msgid)
        self.bufs = [bytearray(self.size) for _ in range(count)]
        self.names = [None] * count
        self.used = 0
        self.next = 0

    def find(self, name):
        names = self.names
        for i in range(self.used):
            if names[i] == name:
                return self.bufs[i]
        if self.used == len(names):
            return self.bufs[self.used - 1]  # full: the last one is shared
        names[self.used] = name
        self.used += 1
        return self.bufs[self.used - 1]

    def send(self, link):
        if not self.used:
            return False
        i = self.next
        self.next = i + 1 if i + 1 < self.used else 0
        return link.send_payload(self.msgid, self.bufs[i], self.size)


class Sink(NamedSlot):
    """Where the writers of messages a board leaves out of TELEMETRY write (one for them
    all, never sent): room for the largest payload, and no struct format (the writers that
    pack by the dialect's format check base)."""

    def __init__(self, size):
        self.msgid = -1
        self.size = size
        self.buf = bytearray(size)
        self.ext_off = 0
        self.base = self.ext = None
        self.written = False
        self.bufs = [self.buf]
        self.names = [None]
        self.used = 0
        self.next = 0

    def send(self, link):
        return False


# Packers, of few locals (their frames stay small: see docs/design.md).
def put_bytes20(b, off, values):
    """20 bytes from off: values' (their low bytes), 0 past their end."""
    i = 0
    while i < 20:
        b[off + i] = values[i] & 0xFF if i < len(values) else 0
        i += 1


def put_u16s(b, off, end, values, k):
    """values[k], values[k + 1], ... as uint16 from off, up to end or values' end ->
    the offset after them."""
    while off < end and k < len(values):
        pack_into("<H", b, off, values[k])
        off += 2
        k += 1
    return off


def fill_u16(b, off, end, v):
    """uint16 v from off up to end."""
    while off < end:
        pack_into("<H", b, off, v)
        off += 2


def put_rc8(raw, scaled, chans):
    """The first 8 channels into RC_CHANNELS_RAW (us) and _SCALED (1000..2000 us as
    -10000..10000); those not given are UINT16_MAX and INT16_MAX."""
    o = 4
    while o < 20:
        k = (o - 4) >> 1
        if k < len(chans):
            v = chans[k]
            pack_into("<H", raw, o, v)
            v = (v - 1500) * 20
            if v < -10000:
                v = -10000
            elif v > 10000:
                v = 10000
            pack_into("<h", scaled, o, v)
        else:
            pack_into("<H", raw, o, _UNUSED_U16)
            pack_into("<h", scaled, o, _UNUSED_I16)
        o += 2


def put_cells(b, off, end, total_mv, cells):
    # Unknown cells are UINT16_MAX; without cell voltages the total goes in cell 1.
    if cells:
        off = put_u16s(b, off, end, cells, 0)
    else:
        pack_into("<H", b, off, total_mv if total_mv < _UNUSED_U16 else _UNUSED_U16 - 1)
        off += 2
    fill_u16(b, off, end, _UNUSED_U16)


def put_ext_cells(b, cells):
    # BATTERY_STATUS's voltages_ext: cells 11..14, 0 for those not given.
    fill_u16(b, put_u16s(b, 41, 49, cells, 10) if cells else 41, 49, 0)
