"""MAVLink 1 and 2 frame parser: bytes in, CRC-checked frames out, nothing allocated.

A small state machine over one frame buffer (as in MAVLink's C library and
fastmavlink), fed whatever chunk the transport has; a rejected candidate's bytes are
scanned again, so a valid frame that begins inside them is still found. Frames that
arrive whole in a chunk take one kernel call (kernels.scan); the rest go through the
bytewise state machine, with the same results either way.
Reference (statistics, late frames, the verify hook): docs/core.md.
"""
from .compat import const
from .kernels import crc16, find_stx, copy, id_info, zero, scan, SLOTS, FIELDS, BUF_LEN

STX_V1 = const(0xFE)
STX_V2 = const(0xFD)
HEADER_V1 = const(6)
HEADER_V2 = const(10)
SIGNATURE_LEN = const(13)
IFLAG_SIGNED = const(0x01)
FRAME_MAX = const(280)  # 10 header + 255 payload + 2 crc + 13 signature
_SOURCES = const(8)  # senders tracked for sequence-gap loss figures
# Statistics wrap at 2^29, below the small ints' end (docs/design.md): a day of garbage
# from a noisy radio, six days of frames at 1 kHz would pass it. Compare counts by
# difference modulo 2^29 (COUNT_WRAP + 1), as link.TX_WRAP.
COUNT_WRAP = const(0x1FFFFFFF)
# A frame numbered up to this many before the newest one from its sender is late (held
# back by the link, or reordered), not a jump ahead over some 200 lost frames. (After an
# outage that lost 192 to 254 frames in a row, or a sender's restart from 0, its next
# frames read as late until its numbers pass the old ones: at most this many.)
_LATE_WINDOW = const(64)


class Parser:
    def __init__(self, crc_len, on_frame):
        # verify(buf, plen, signed) -> bool, set by a signing service: called with the
        # frame still as on the wire (CRC in place); False drops it undelivered. Looked
        # up on every frame: an instance attribute is found first.
        self.verify = None
        self.infos = crc_len.block  # dialect.CRC_LEN's block, read by kernels.id_info
        self.on_frame = on_frame  # called as on_frame(msgid, payload)
        # The frame at [0:FRAME_MAX), then what kernels.scan reads and keeps: the sender
        # slots for sequence numbers, the fields it left set.
        self.buf = bytearray(BUF_LEN)
        mv = memoryview(self.buf)
        self._payload_v1 = mv[HEADER_V1 : HEADER_V1 + 255]
        self._payload_v2 = mv[HEADER_V2 : HEADER_V2 + 255]
        self.signature = bytearray(SIGNATURE_LEN)
        # Bytes of a rejected candidate, waiting to be scanned again.
        self._replay = bytearray(FRAME_MAX)
        self._rpos = 0
        self._rlen = 0
        self._rstart = -1
        self._cnt = 0  # bytes of the current candidate in buf
        self._want = 0  # bytes needed before the next decision
        self._have_header = False
        self._plen = 0
        self._info = 0
        # The frame being delivered.
        self.version = 0
        self.msgid = 0
        self.seq = 0
        self.sysid = 0
        self.compid = 0
        self.signed = False
        self.payload = self._payload_v2
        # Statistics.
        self.frames = 0
        self.crc_errors = 0
        self.bytes_discarded = 0
        self.unknown_ids = 0
        self.bad_frames = 0  # impossible length or unknown incompat flags
        self.lost = 0
        # frames when the frame last delivered late came (see _LATE_WINDOW): the frame in
        # hand is late when late_at == frames. Services that must not take an old frame
        # for a new one (a mission upload's items) ask.
        self.late_at = -1
        self._src_next = 0  # the sender slot a new sender takes

    def feed(self, data, n=-1):
        """Consume data[0:n] (all of it when n < 0)."""
        if n < 0:
            n = len(data)
        pos = 0
        while True:
            if self._rpos < self._rlen:
                self._rpos = self._step(self._replay, self._rpos, self._rlen)
                continue
            if self._cnt:
                if pos >= n:
                    return
                pos = self._step(data, pos, n)
                continue
            # Idle: whole frames in data, one kernel call each (see kernels.scan). Few
            # locals (no local for self.buf): docs/design.md.
            while pos < n:
                r = scan(data, pos, n if self.verify is None else -n, self.buf, self.infos)
                if r < 0:
                    break
                pos = r >> 2
                if r & 2:
                    if r & 1:
                        self.version = 1
                        self.signed = False
                        self.payload = self._payload_v1
                    self.seq = self.buf[2]
                    self.sysid = self.buf[3]
                    self.compid = self.buf[4]
                    r = self.buf[5]
                else:
                    if r & 1:
                        self.version = 2
                        self.signed = False
                        self.payload = self._payload_v2
                    self.seq = self.buf[4]
                    self.sysid = self.buf[5]
                    self.compid = self.buf[6]
                    r = self.buf[7]
                self.msgid = r
                self.frames = (self.frames + 1) & COUNT_WRAP
                self.on_frame(r, self.payload)
            else:
                return
            r = -1 - r
            if r & 3 == 1:  # the state machine's, from pos
                pos = self._step(data, pos, n)
            else:
                pos = self._scanned(pos, r)

    def _scanned(self, pos, r):
        """A gap or a frame a scan call left to Python (r = its answer decoded) -> the
        next pos."""
        if r & 3 == 0:  # no start marker up to r >> 2
            self.bytes_discarded = (self.bytes_discarded + (r >> 2) - pos) & COUNT_WRAP
        else:
            self._deliver()
        return r >> 2

    # The per-frame path keeps few locals (docs/design.md). Bytes being replayed are told
    # by their buffer (src is self._replay).
    def _step(self, src, pos, end):
        cnt = self._cnt
        if cnt == 0:
            k = find_stx(src, pos, end)
            self.bytes_discarded = (self.bytes_discarded + k - pos) & COUNT_WRAP
            if k >= end:
                return end
            self._rstart = k if src is self._replay else -1
            pos = k + 1
            k = src[k]  # the start marker
            self.buf[0] = k
            self._want = HEADER_V2 if k == STX_V2 else HEADER_V1
            self._have_header = False
            cnt = 1
        # Header, then the rest: a frame already all in src takes one call.
        while True:
            k = self._want - cnt
            if k > end - pos:
                k = end - pos
            copy(self.buf, src, pos << 10 | cnt, k)
            cnt += k
            pos += k
            self._cnt = cnt
            if cnt < self._want:
                return pos
            if not self._have_header:
                if self._header():
                    self._have_header = True
                    continue
            elif self._check():
                self._cnt = 0
                self._deliver()
                return pos
            return self._reject(pos, src is self._replay)

    def _header(self):
        buf = self.buf
        plen = buf[1]
        if buf[0] == STX_V2:
            if buf[2] & ~IFLAG_SIGNED:
                self.bad_frames = (self.bad_frames + 1) & COUNT_WRAP
                return False
            msgid = buf[7] | buf[8] << 8 | buf[9] << 16
            info = id_info(self.infos, msgid)
            if not info:
                self.unknown_ids = (self.unknown_ids + 1) & COUNT_WRAP
                return False
            if plen == 0 or plen > (info >> 16):
                self.bad_frames = (self.bad_frames + 1) & COUNT_WRAP
                return False
            want = HEADER_V2 + plen + 2
            if buf[2] & IFLAG_SIGNED:
                want += SIGNATURE_LEN
        else:
            msgid = buf[5]
            info = id_info(self.infos, msgid)
            if not info:
                self.unknown_ids = (self.unknown_ids + 1) & COUNT_WRAP
                return False
            # At least the base fields; senders built from a newer definition (the
            # MAVLink C library, pymavlink forced to v1) may add extension bytes.
            if plen < (info >> 8) & 0xFF or plen > info >> 16:
                self.bad_frames = (self.bad_frames + 1) & COUNT_WRAP
                return False
            want = HEADER_V1 + plen + 2
        self._plen = plen
        self._info = info
        self._want = want
        return True

    def _check(self):
        buf = self.buf
        end = (HEADER_V2 if buf[0] == STX_V2 else HEADER_V1) + self._plen
        # CRC_EXTRA goes where the CRC's first byte was, so one kernel call covers it.
        wire = buf[end] | buf[end + 1] << 8
        buf[end] = self._info & 0xFF
        crc = crc16(buf, 1, end + 1, 0xFFFF)
        buf[end] = wire & 0xFF
        if crc != wire:
            self.crc_errors = (self.crc_errors + 1) & COUNT_WRAP
            return False
        return True

    def _deliver(self):
        buf = self.buf
        buf[FIELDS] = 0  # the fields kernels.scan left are changed here
        plen = buf[1]
        if buf[0] == STX_V2:
            self.version = 2
            self.seq = buf[4]
            self.sysid = buf[5]
            self.compid = buf[6]
            self.msgid = buf[7] | buf[8] << 8 | buf[9] << 16
            self.signed = bool(buf[2] & IFLAG_SIGNED)
            if self.signed:
                copy(self.signature, buf, (HEADER_V2 + plen + 2) << 10, SIGNATURE_LEN)
            self.payload = self._payload_v2
            start = HEADER_V2
        else:
            self.version = 1
            self.seq = buf[2]
            self.sysid = buf[3]
            self.compid = buf[4]
            self.msgid = buf[5]
            self.signed = False
            self.payload = self._payload_v1
            start = HEADER_V1
        if self.verify is not None and not self.verify(buf, plen, self.signed):
            return
        full = id_info(self.infos, self.msgid) >> 16
        if plen < full:
            zero(buf, start + plen, start + full)
        self.frames = (self.frames + 1) & COUNT_WRAP
        self._count_sequence()
        self.on_frame(self.msgid, self.payload)

    def _reject(self, pos, replaying):
        # Everything after the start marker may hold the next real frame.
        n = self._cnt
        self._cnt = 0
        self.bytes_discarded = (self.bytes_discarded + 1) & COUNT_WRAP
        if replaying:
            return self._rstart + 1
        copy(self._replay, self.buf, 1 << 10, n - 1)
        self._rpos = 0
        self._rlen = n - 1
        return pos

    def _count_sequence(self):
        # The sender slots in buf (kernels.scan counts a known sender with no gap itself).
        buf = self.buf
        i = SLOTS
        while i < BUF_LEN:
            if buf[i] and buf[i + 1] == self.sysid and buf[i + 2] == self.compid:
                self._gap(i)
                return
            i += 4
        i = SLOTS + 4 * self._src_next
        self._src_next = (self._src_next + 1) % _SOURCES
        buf[i] = 1
        buf[i + 1] = self.sysid
        buf[i + 2] = self.compid
        buf[i + 3] = self.seq

    def _gap(self, i):
        # A late frame is marked (late_at) and leaves the sender's newest number as it
        # was; a repeated number (a duplicate, or a sender that numbers nothing) is no loss.
        buf = self.buf
        gap = (self.seq - buf[i + 3] - 1) & 0xFF
        if gap == 255:
            return
        if gap >= 256 - _LATE_WINDOW:
            self.late_at = self.frames
            return
        self.lost = (self.lost + gap) & COUNT_WRAP
        buf[i + 3] = self.seq

    def reset_stats(self):
        self.frames = self.crc_errors = self.bytes_discarded = 0
        self.unknown_ids = self.bad_frames = self.lost = 0
        self.late_at = -1
