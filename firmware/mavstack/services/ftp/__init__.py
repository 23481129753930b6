"""MAVLink FTP: ground stations list, read, write and remove files in the storage folder.

FILE_TRANSFER_PROTOCOL (#110 of the common dialect) served over the vehicle's storage
folder with the rules of files.py. This module is the per-packet path: reads, writes,
bursts (from tick(), at the streams' rank) and a repeated request answered again without
running twice; all of it allocates nothing. The rare events (open, create, list, remove,
checksum) are rare.py's, with the heap open. The seed's own file transfer (the same ids
in the seed2012 dialect) is seed.py; create() attaches whichever the dialect has.
Reference (opcodes, errors, sessions, retries, bursts): docs/services/ftp.md.
"""
from ...compat import const
from ...kernels import copy, zero
from ...link import RANK_BULK, RANK_AUTO
from .files import Folder, read_into, write_from, ENOSPC
from .rare import FtpRare

_MSG_FTP = const(110)
_LEN = const(254)  # the message's payload: network, system, component, 251 bytes of FTP
# Offsets in it: the FTP header, then data.
_SEQ = const(3)
_SESSION = const(5)
_OPCODE = const(6)
_SIZE = const(7)
_REQ_OPCODE = const(8)
_BURST_COMPLETE = const(9)
_OFFSET = const(11)
_DATA = const(15)
_DATA_MAX = const(239)

# opcodes
_TERMINATE = const(1)
_RESET = const(2)
_LIST = const(3)
_OPEN_RO = const(4)
_READ = const(5)
_CREATE = const(6)
_WRITE = const(7)
_REMOVE = const(8)
_CRC32 = const(14)
_BURST = const(15)
_ACK = const(128)
_NAK = const(129)
# Answered by rare.py, with the heap open:
_RARE = const((1 << _TERMINATE) | (1 << _RESET) | (1 << _LIST) | (1 << _OPEN_RO) | (1 << _CREATE)
              | (1 << _REMOVE) | (1 << _CRC32))

# NAK codes
FAIL = const(1)
FAIL_ERRNO = const(2)
INVALID_DATA_SIZE = const(3)
INVALID_SESSION = const(4)
NO_SESSIONS = const(5)
EOF = const(6)
UNKNOWN_COMMAND = const(7)
FILE_EXISTS = const(8)
FILE_PROTECTED = const(9)
FILE_NOT_FOUND = const(10)

_FREE = const(0)
_READING = const(1)
_WRITING = const(2)

_PER_TICK = const(8)  # burst replies one tick may send
_FRAME = const(280)  # bytes of a full MAVLink 2 FILE_TRANSFER_PROTOCOL frame, for the budget


class Ftp(FtpRare):
    NAME = "ftp"
    CLOCK = False

    def __init__(self, sessions=4, burst_packets=32, protected=(), space=0):
        self.burst_packets = burst_packets if 0 < burst_packets < 256 else 255
        self._protected = protected
        self._space = space
        self.folder = None
        self.ep = None
        self._req = bytearray(_LEN)  # the request being answered (and the last, for repeats)
        self._reply = bytearray(_LEN)  # its reply, kept for a repeat
        self._burst = bytearray(_LEN)
        self._wdata = memoryview(self._req)[_DATA:]
        self._rdata = memoryview(self._reply)[_DATA:]
        self._bdata = memoryview(self._burst)[_DATA:]
        self._cached = False  # _req/_reply hold an answered request
        self._from = 0  # its sender: sysid << 8 | compid
        self._link = None
        self._room = 0  # bytes the file being written may still grow by (FTP_SPACE)
        self._wf = None  # the file a WriteFile goes to
        # Sessions, by slot.
        self._files = [None] * sessions
        self._sid = bytearray(sessions)
        self._mode = bytearray(sessions)
        self._fsize = [0] * sessions
        self._paths = [None] * sessions  # the file's host path
        self._full = bytearray(sessions)  # 1: a write found no space; closing removes the file
        # Bursts in progress, by slot: replies left, next offset, size, sequence, link, to.
        self._b_left = bytearray(sessions)
        self._b_off = [0] * sessions
        self._b_size = bytearray(sessions)
        self._b_seq = [0] * sessions
        self._b_link = [None] * sessions
        self._b_to = [0] * sessions

    def attach(self, ep):
        self.ep = ep
        root = getattr(getattr(ep, "storage", None), "root", None)
        if root is None or getattr(ep.storage, "mem", None) is not None:
            return  # no storage folder (storage_ram keeps named areas, not files)
        self.folder = Folder(root, self._protected, self._space)
        ep.on(_MSG_FTP, self._on_request)

    # --- per packet (allocation-free; small functions: docs/design.md) ------------------
    def _on_request(self, link, p):
        if not self.ep.for_us(p[1], p[2]) or self._repeat(link, p):
            return
        self._take(link, p)
        if p[_OPCODE] == _BURST:
            self._burst_begin(link)
            return
        self._answer(p[_OPCODE])
        self._cached = True
        link.send_payload(_MSG_FTP, self._reply, _LEN)

    def _repeat(self, link, p):
        """A retry of the last request: its reply again -> True."""
        if not self._cached or (link.rx.sysid << 8 | link.rx.compid) != self._from:
            return False
        if not self._repeats(p):
            return False
        link.send_payload(_MSG_FTP, self._reply, _LEN)
        return True

    def _take(self, link, p):
        copy(self._req, p, 0, _LEN)
        self._from = link.rx.sysid << 8 | link.rx.compid
        self._link = link
        self._cached = False

    def _repeats(self, p):
        """Is p the last request again, byte for byte (header and data)?"""
        q = self._req
        n = _DATA + p[_SIZE]
        if n > _LEN:
            n = _LEN
        i = 0
        while i < n:
            if p[i] != q[i]:
                return False
            i += 1
        return True

    def _answer(self, op):
        if op == _READ:
            self._read()
        elif op == _WRITE:
            self._write()
        elif op < 16 and (1 << op) & _RARE:
            self._rare_event(op)
        else:
            self._nak(UNKNOWN_COMMAND, 0)

    def _head(self, opcode, size):
        """The reply's header for the request in _req."""
        r = self._reply
        q = self._req
        r[0] = 0
        r[1] = self._from >> 8
        r[2] = self._from & 0xFF
        seq = (q[_SEQ] | q[_SEQ + 1] << 8) + 1
        r[_SEQ] = seq & 0xFF
        r[_SEQ + 1] = (seq >> 8) & 0xFF
        r[_SESSION] = q[_SESSION]
        r[_OPCODE] = opcode
        r[_SIZE] = size
        r[_REQ_OPCODE] = q[_OPCODE]
        r[_BURST_COMPLETE] = 0
        r[10] = 0
        copy(r, q, _OFFSET << 10 | _OFFSET, 4)
        zero(r, _DATA + size, _LEN)

    def _ack(self, size):
        self._head(_ACK, size)

    def _nak(self, error, errno):
        self._head(_NAK, 2 if error == FAIL_ERRNO else 1)
        self._reply[_DATA] = error
        self._reply[_DATA + 1] = errno

    def _offset(self, b):
        """The offset field of buffer b, -1 from 2^30 on (past the small ints: docs/design.md)."""
        if b[_OFFSET + 3] >= 0x40:
            return -1
        return b[_OFFSET] | b[_OFFSET + 1] << 8 | b[_OFFSET + 2] << 16 | b[_OFFSET + 3] << 24

    def _slot(self, sid, mode):
        """The slot of open session sid in this mode, -1 if none."""
        i = 0
        while i < len(self._sid):
            if self._mode[i] == mode and self._sid[i] == sid:
                return i
            i += 1
        return -1

    def _read(self):
        slot = self._slot(self._req[_SESSION], _READING)
        if slot < 0:
            self._nak(INVALID_SESSION, 0)
            return
        off = self._offset(self._req)
        left = self._fsize[slot] - off
        if off < 0 or left <= 0:
            self._nak(EOF, 0)
            return
        n = self._req[_SIZE]
        if n == 0 or n > _DATA_MAX:
            n = _DATA_MAX
        self._files[slot].seek(off)
        n = read_into(self._files[slot], self._rdata, n if n < left else left)
        self._ack(n)

    def _write(self):
        slot = self._slot(self._req[_SESSION], _WRITING)
        if slot < 0:
            self._nak(INVALID_SESSION, 0)
        elif self._req[_SIZE] > _DATA_MAX:
            self._nak(INVALID_DATA_SIZE, 0)
        else:
            self._write_at(slot, self._offset(self._req), self._req[_SIZE])

    def _write_at(self, slot, off, n):
        grow = off + n - self._fsize[slot]
        if off >= 0 and grow <= self._room:
            self._wf = self._files[slot]
            self._wf.seek(off)
            if self._put(n) == n:
                self._wrote(slot, grow)
                return
        # Past FTP_SPACE, or the file system took less: the store is full. The partial
        # file goes when the session closes, giving its room back.
        self._full[slot] = 1
        self._nak(FAIL_ERRNO, ENOSPC)

    def _wrote(self, slot, grow):
        if grow > 0:
            self._fsize[slot] += grow
            self._room -= grow
        self._ack(0)

    def _put(self, n):
        # (seeking a file never fails; writing may: full, or removed under us). Few
        # locals: a try block takes frame words too.
        try:
            return write_from(self._wf, self._wdata, n)
        except OSError:
            return -1

    # --- bursts -------------------------------------------------------------------
    def _burst_begin(self, link):
        q = self._req
        slot = self._slot(q[_SESSION], _READING)
        off = self._offset(q)
        if slot < 0 or off < 0:
            self._nak(INVALID_SESSION if slot < 0 else EOF, 0)
            self._reply[_BURST_COMPLETE] = 1
            link.send_payload(_MSG_FTP, self._reply, _LEN)
            return
        n = q[_SIZE]
        self._b_size[slot] = n if 0 < n <= _DATA_MAX else _DATA_MAX
        self._b_off[slot] = off
        self._b_seq[slot] = ((q[_SEQ] | q[_SEQ + 1] << 8) + 1) & 0xFFFF
        self._b_link[slot] = link
        self._b_to[slot] = self._from
        self._b_left[slot] = self.burst_packets

    def tick(self, now):
        i = 0
        while i < len(self._b_left):
            if self._b_left[i]:
                self._pump(i)
            i += 1

    def _pump(self, slot):
        link = self._b_link[slot]
        k = 0
        while k < _PER_TICK and self._b_left[slot]:
            if not link.can_send(_FRAME, RANK_BULK):
                return
            self._burst_next(slot)
            link.rank = RANK_BULK
            link.send_payload(_MSG_FTP, self._burst, _LEN)
            link.rank = RANK_AUTO
            k += 1

    def _burst_next(self, slot):
        """The next reply of slot's burst into _burst: data, or NAK EOF past the end."""
        b = self._burst
        self._burst_head(slot)
        off = self._b_off[slot]
        n = self._fsize[slot] - off
        if n > self._b_size[slot]:
            n = self._b_size[slot]
        if n > 0:
            self._files[slot].seek(off)
            n = read_into(self._files[slot], self._bdata, n)
        if n <= 0:  # at the end: EOF ends the burst
            b[_OPCODE] = _NAK
            b[_SIZE] = 1
            b[_DATA] = EOF
            b[_BURST_COMPLETE] = 1
            zero(b, _DATA + 1, _LEN)
            self._b_left[slot] = 0
            return
        b[_SIZE] = n
        zero(b, _DATA + n, _LEN)
        self._b_off[slot] = off + n
        self._b_left[slot] -= 1
        if n < self._b_size[slot]:
            self._b_left[slot] = 0  # a short reply is the file's end
        b[_BURST_COMPLETE] = 0 if self._b_left[slot] else 1

    def _burst_head(self, slot):
        b = self._burst
        to = self._b_to[slot]
        seq = self._b_seq[slot]
        b[0] = 0
        b[1] = to >> 8
        b[2] = to & 0xFF
        b[_SEQ] = seq & 0xFF
        b[_SEQ + 1] = seq >> 8
        self._b_seq[slot] = (seq + 1) & 0xFFFF
        b[_SESSION] = self._sid[slot]
        b[_OPCODE] = _ACK
        b[_REQ_OPCODE] = _BURST
        b[10] = 0
        off = self._b_off[slot]
        b[_OFFSET] = off & 0xFF
        b[_OFFSET + 1] = (off >> 8) & 0xFF
        b[_OFFSET + 2] = (off >> 16) & 0xFF
        b[_OFFSET + 3] = off >> 24


def _names(setting):
    # FTP_PROTECTED: a tuple in a profile, "a,b" from --set
    return tuple(setting.split(",")) if isinstance(setting, str) else tuple(setting or ())


def create(ep):
    fmt = ep.dialect.FMT.get(_MSG_FTP)
    if fmt is not None and fmt.endswith("251B"):
        return ep.add(Ftp(
            sessions=ep.setting("FTP_SESSIONS", 4),
            burst_packets=ep.setting("FTP_BURST_PACKETS", 32),
            protected=_names(ep.setting("FTP_PROTECTED", ())),
            space=ep.setting("FTP_SPACE", 0),
        ))
    if ep.has(112) and ep.dialect.FMT.get(112) == "<QB":  # the seed's FILE_TRANSFER_RES
        from .seed import SeedFiles

        return ep.add(SeedFiles(protected=_names(ep.setting("FTP_PROTECTED", ())), space=ep.setting("FTP_SPACE", 0)))
    return None
