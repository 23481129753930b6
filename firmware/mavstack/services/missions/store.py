"""Mission, fence and rally plans in flash: fixed-size records, two slots, atomic commit.
A plan is never held in RAM: each item is a 32-byte record laid out like the start of a
MISSION_ITEM_INT payload, so a download copies bytes and an item costs one seek and one
read. A store keeps two slot files, NAME.0 and NAME.1, open for its lifetime: the plan
in force lives in one, a new plan is written into the other and becomes the plan in
force when its header is written, last, so a process killed at any point leaves the
old plan or the new one, never a mix. A slot found damaged at boot and not provably
older than the plan in force makes the store corrupt: reported, wiped, and the vehicle
starts with an empty plan. Staging, commit and load() allocate nothing (the u32
generation is kept by 16-bit halves), so a transfer runs under heap_lock().
Reference (record and header layout): docs/services/missions.md.
"""
from ...compat import const
from ...kernels import crc16, zero

RECORD_SIZE = const(32)
HEADER_SIZE = const(16)
_MAGIC0 = const(0x4D)  # b"MSN\x01"
_MAGIC1 = const(0x53)
_MAGIC2 = const(0x4E)
_MAGIC3 = const(0x01)
_CMD_DO_JUMP = const(177)

_EMPTY = const(0)  # slot states at boot
_VALID = const(1)
_DAMAGED = const(2)  # header checks out, records do not: its generation is known
_GARBAGE = const(3)  # header itself is wrong


class MissionStore:
    """One plan type (0 mission, 1 fence, 2 rally) with room for `capacity` items."""

    def __init__(self, storage, name, mission_type, capacity):
        self.mission_type = mission_type
        self.capacity = capacity
        self.count = 0  # items in the plan in force
        self.gen_hi = 0  # its generation (u32; 0: nothing committed yet), by 16-bit halves
        self.gen_lo = 0
        self.crc = 0xFFFF  # CRC of its records
        self.corrupt = False  # found corrupt at boot (and wiped)
        self.staged_jumps = 0  # DO_JUMP items in the staged plan, after seal()
        self._staged_crc = 0xFFFF  # and its CRC (also the scratch of _scan)
        self._staged_count = 0
        self._rec = bytearray(RECORD_SIZE)
        self._hdr = bytearray(HEADER_SIZE)
        # What load() found in each slot, 5 ints a slot: state, generation (high half,
        # low half), count, CRC. One list made here, so that load() makes nothing.
        self._slots = [0] * 10
        # False when storage refused a write: staging is refused until a restart.
        self.writable = True
        size = HEADER_SIZE + capacity * RECORD_SIZE
        self._files = [self._open(storage, name + ".0", size), self._open(storage, name + ".1", size)]
        self._active = 0
        self.load()

    def _open(self, storage, fname, size):
        # size: the most the file will hold. storage_ram hands out its area when the file
        # is first made, at that size; files on a filesystem ignore it.
        try:
            if not storage.exists(fname):
                f = storage.open(fname, "wb", size=size)
                f.write(bytearray(HEADER_SIZE))
                f.close()
            return storage.open(fname, "r+b", size=size)
        except OSError:
            pass
        # Read-only storage (or no room to make the file): the stored plan is still
        # flown and served, new plans are refused (begin() -> False).
        self.writable = False
        try:
            return storage.open(fname, "rb", size=size)
        except OSError:
            return None  # nothing stored, nothing to read: an empty slot

    @property
    def gen(self):
        """The generation as one int (not on the protocol's paths: see gen_hi, gen_lo)."""
        return self.gen_hi << 16 | self.gen_lo

    # --- boot -------------------------------------------------------------------

    def load(self):
        """Pick the plan in force: the valid slot with the higher generation. Runs at boot;
        allocates nothing, so it may run again under heap_lock()."""
        self._check(0)
        self._check(1)
        s = self._slots
        newer = self._newer(1, 0)
        # The valid slot with the higher generation (slot 0 on a tie), -1 for none.
        best = 1 if s[5] == _VALID and (newer or s[0] != _VALID) else (0 if s[0] == _VALID else -1)
        # A damaged slot that is provably older than the winner is a harmless leftover.
        self.corrupt = self._bad(0, best) or self._bad(1, best)
        self._active = 0
        self.count = 0
        self.crc = 0xFFFF
        if self.corrupt or best < 0:
            if self.corrupt:  # both headers zeroed
                zero(self._hdr, 0, HEADER_SIZE)
                self._safely(self._files[0])
                self._safely(self._files[1])
            best = 1 if newer else 0  # the higher generation: the next commit goes above both
        else:
            self._active = best
            self.count = s[5 * best + 3]
            self.crc = s[5 * best + 4]
        self.gen_hi = s[5 * best + 1]
        self.gen_lo = s[5 * best + 2]

    def _check(self, i):
        """Slot i's state, generation, count and CRC into self._slots."""
        s = self._slots
        o = 5 * i
        st = self._state(self._files[i])
        s[o] = st
        h = self._hdr
        known = st == _VALID or st == _DAMAGED  # the header checks out: its fields count
        s[o + 1] = h[10] | h[11] << 8 if known else 0
        s[o + 2] = h[8] | h[9] << 8 if known else 0
        s[o + 3] = h[6] | h[7] << 8
        s[o + 4] = h[12] | h[13] << 8

    def _state(self, f):
        """_EMPTY, _VALID, _DAMAGED or _GARBAGE: one slot file (its header left in _hdr)."""
        hdr = self._hdr
        if f is None:
            return _EMPTY
        f.seek(0)
        n = f.readinto(hdr)
        i = 0
        while i < n and not hdr[i]:
            i += 1
        if i == n:  # nothing read, or zeros
            return _EMPTY
        if (n < HEADER_SIZE or hdr[0] != _MAGIC0 or hdr[1] != _MAGIC1 or hdr[2] != _MAGIC2
                or hdr[3] != _MAGIC3 or crc16(hdr, 0, 14, 0xFFFF) != hdr[14] | hdr[15] << 8
                or hdr[4] != self.mission_type or hdr[5] != RECORD_SIZE):
            return _GARBAGE
        n = hdr[6] | hdr[7] << 8
        if n > self.capacity or not self._scan(f, n) or self._staged_crc != hdr[12] | hdr[13] << 8:
            return _DAMAGED
        return _VALID

    def _newer(self, i, j):
        """Slot i's generation is above slot j's (compared by halves)."""
        s = self._slots
        i *= 5
        j *= 5
        return s[i + 1] > s[j + 1] or (s[i + 1] == s[j + 1] and s[i + 2] > s[j + 2])

    def _bad(self, i, best):
        st = self._slots[5 * i]
        return st == _GARBAGE or (st == _DAMAGED and (best < 0 or self._newer(i, best)))

    def _scan(self, f, count):
        """CRC and DO_JUMP count of a slot's first `count` records (into _staged_crc and
        staged_jumps: no tuple on the commit path); False if the file is short."""
        rec = self._rec
        crc = 0xFFFF
        self.staged_jumps = 0
        f.seek(HEADER_SIZE)
        while count:
            if f.readinto(rec) != RECORD_SIZE:
                return False
            crc = crc16(rec, 0, RECORD_SIZE, crc)
            if rec[28] == _CMD_DO_JUMP and rec[29] == 0:
                self.staged_jumps += 1
            count -= 1
        self._staged_crc = crc
        return True

    # --- the plan in force ----------------------------------------------------------

    def read(self, seq, rec):
        """Copy record seq of the plan in force into rec (32 bytes); False if out of range."""
        if seq < 0 or seq >= self.count:
            return False
        f = self._files[self._active]
        f.seek(HEADER_SIZE + seq * RECORD_SIZE)
        return f.readinto(rec) == RECORD_SIZE

    @property
    def plan_id(self):
        """Identifies the plan in force (MAVLink opaque_id): changes with every commit, never 0.
        On the protocol's paths put_plan_id() writes its bytes instead."""
        return (self.gen_lo << 16 | self.crc) or 1

    def put_plan_id(self, buf, o):
        """Write plan_id at buf[o] (u32, little endian) without making the int."""
        c = self.crc
        g = self.gen_lo
        if not (c or g):
            c = 1
        buf[o] = c & 0xFF
        buf[o + 1] = c >> 8
        buf[o + 2] = g & 0xFF
        buf[o + 3] = g >> 8

    # --- staging a new plan ---------------------------------------------------------

    def _safely(self, f):
        """Write _hdr at the start of f -> done; a storage error (full, read-only,
        gone) makes the store read-only rather than escape into a message handler."""
        if f is None:  # no slot file (read-only storage that had none)
            return self._failed()
        try:
            f.seek(0)
            if f.write(self._hdr) != HEADER_SIZE:
                return False
            f.flush()
            return True
        except OSError:
            return self._failed()

    def begin(self, keep=0):
        """Start a new plan in the spare slot, with the first `keep` items of the plan in
        force -> False when storage cannot take it (the plan in force stands)."""
        if not self.writable:
            return False
        zero(self._hdr, 0, HEADER_SIZE)
        if not self._safely(self._files[1 - self._active]):
            return False
        try:
            return self._keep(keep)
        except OSError:
            return self._failed()

    def _keep(self, keep):
        spare = self._files[1 - self._active]
        src = self._files[self._active]
        keep = keep if keep < self.count else self.count
        o = HEADER_SIZE
        while keep:
            src.seek(o)
            src.readinto(self._rec)
            spare.seek(o)
            spare.write(self._rec)
            o += RECORD_SIZE
            keep -= 1
        return True

    def put(self, seq, rec):
        """Write record seq of the staged plan -> done."""
        # A bare except: `except OSError` would take this per-item frame past the limit
        # (docs/design.md). Whatever failed, the staged plan cannot be trusted and the
        # store refuses it.
        try:
            return self._put(seq, rec)
        except:  # noqa: E722
            return self._failed()

    def _failed(self):
        self.writable = False
        return False

    def _put(self, seq, rec):
        spare = self._files[1 - self._active]
        spare.seek(HEADER_SIZE + seq * RECORD_SIZE)
        return spare.write(rec) == RECORD_SIZE

    def seal(self, count):
        """Read the staged plan back: its CRC and DO_JUMP count (staged_jumps); False if short."""
        self._staged_count = count
        try:
            return self._seal(count)
        except OSError:
            return self._failed()

    def _seal(self, count):
        spare = self._files[1 - self._active]
        spare.flush()
        return self._scan(spare, count)

    def commit(self):
        """Make the sealed plan the plan in force: one header write."""
        lo = (self.gen_lo + 1) & 0xFFFF  # the u32 generation + 1, carried by halves
        hi = (self.gen_hi + 1) & 0xFFFF if lo == 0 else self.gen_hi
        h = self._hdr
        h[0] = _MAGIC0
        h[1] = _MAGIC1
        h[2] = _MAGIC2
        h[3] = _MAGIC3
        h[4] = self.mission_type
        h[5] = RECORD_SIZE
        h[6] = self._staged_count & 0xFF
        h[7] = self._staged_count >> 8
        h[8] = lo & 0xFF
        h[9] = lo >> 8
        h[10] = hi & 0xFF
        h[11] = hi >> 8
        h[12] = self._staged_crc & 0xFF
        h[13] = self._staged_crc >> 8
        v = crc16(h, 0, 14, 0xFFFF)
        h[14] = v & 0xFF
        h[15] = v >> 8
        if not self._safely(self._files[1 - self._active]):
            return False
        self._active = 1 - self._active
        self.gen_hi = hi
        self.gen_lo = lo
        self.count = self._staged_count
        self.crc = self._staged_crc
        return True

    def close(self):
        for f in self._files:
            if f is not None:
                f.close()
