"""MAVLink 1 and 2 frame encoder into one preallocated transmit buffer.

Usage, allocation-free per frame:
    off = enc.begin()                       # payload offset for this link's version
    struct.pack_into(FMT, enc.buf, off, ...) # pack the full (MAVLink 2) payload
    n = enc.finish(msgid, sysid, compid)    # frame is enc.buf[0:n]; 0 if not sendable
Reference: docs/core.md.
"""
from .compat import const
from .kernels import crc16, copy, id_info, seal_v2, zero
from .parser import STX_V1, HEADER_V1, HEADER_V2, FRAME_MAX, IFLAG_SIGNED


class Encoder:
    # sign(buf, end) -> bytes appended after the CRC at buf[end], set on an instance by a
    # signing service; MAVLink 2 frames are then flagged signed. A class attribute, so
    # that encoders without one carry nothing extra.
    sign = None

    def __init__(self, crc_len, version=2):
        self.crc_len = crc_len  # the dialect's CRC_LEN (services read lengths from it)
        self.infos = crc_len.block  # its block, read per frame by kernels.id_info
        self.version = version
        self.buf = bytearray(FRAME_MAX)
        self.seq = 0
        self.frames = 0

    def begin(self):
        """Payload offset in buf; the caller packs the whole payload there."""
        return HEADER_V2 if self.version == 2 else HEADER_V1

    def load(self, payload, n, msgid=-1):
        """Copy a prepacked payload (payload[0:n]) into place; returns its offset.

        With msgid, the rest of that message's payload is zeroed: bytes left from an
        earlier, longer frame must not go out as its tail.
        """
        off = HEADER_V2 if self.version == 2 else HEADER_V1
        copy(self.buf, payload, off, n)
        info = id_info(self.infos, msgid)
        if info and n < info >> 16:
            info = off + (info >> 16)  # the payload's end
            zero(self.buf, off + n, info)
        return off

    # finish and its helpers keep few locals and a shallow stack: docs/design.md.
    def finish(self, msgid, sysid, compid):
        info = id_info(self.infos, msgid)
        if not info:
            return 0
        if self.version == 2:
            sysid = sysid << 8 | compid << 16
            return self._seal_v2(info, sysid, msgid)
        if msgid > 255:
            return 0
        return self._frame_v1(info, msgid, sysid, compid)

    def _frame_v1(self, info, msgid, sysid, compid):
        buf = self.buf
        end = HEADER_V1 + ((info >> 8) & 0xFF)
        buf[0] = STX_V1
        buf[1] = end - HEADER_V1
        buf[2] = self.seq
        buf[3] = sysid
        buf[4] = compid
        buf[5] = msgid
        # CRC_EXTRA goes where the CRC's first byte will, so one kernel call covers it.
        buf[end] = info & 0xFF
        return self._seal_v1(end)

    def _seal_v2(self, info, ids, msgid):
        # Header, trimmed payload and CRC in one kernel call; the signature after.
        ids |= self.seq
        if self.sign is not None:
            ids |= IFLAG_SIGNED << 24
        end = seal_v2(self.buf, info, ids, msgid)
        self.seq = (self.seq + 1) & 0xFF  # (as _count: one call less a frame)
        self.frames = (self.frames + 1) & 0x1FFFFFFF
        if self.sign is None:
            return end
        return end + self.sign(self.buf, end)

    def _seal_v1(self, end):
        buf = self.buf
        crc = crc16(buf, 1, end + 1, 0xFFFF)
        buf[end] = crc & 0xFF
        buf[end + 1] = crc >> 8
        self._count()
        return end + 2

    def _count(self):
        self.seq = (self.seq + 1) & 0xFF
        self.frames = (self.frames + 1) & 0x1FFFFFFF  # as the parser's counters (COUNT_WRAP)

    def clear(self, n):
        """Zero the payload area before packing a message field by field."""
        off = self.begin()
        zero(self.buf, off, off + n)
        return off
