"""Mission, fence and rally plans in flash: fixed-size records, two slots, atomic commit.

A plan is never held in RAM. Each item is a 32-byte record laid out like the start of
a MISSION_ITEM_INT payload, so a download copies bytes and an item costs one seek
and one read:
    0 param1..param4 (float32 bits)  16 x (int32)  20 y (int32)  24 z (float32 bits)
   28 command (u16)  30 frame (u8)  31 autocontinue (u8)
A store keeps two slot files, NAME.0 and NAME.1, both open for its lifetime. The
plan in force lives in one; a new plan is written into the other and becomes the
plan in force when its 16-byte header is written, last:
    0 magic  4 mission_type  5 record size  6 count (u16)  8 generation (u32)
   12 CRC of the records  14 CRC of header bytes 0..13
Before staging starts the spare slot's header is zeroed, so a process killed at any
point leaves the old plan (spare header zero or stale) or the new one (header
written), never a mix. At boot the valid slot with the higher generation wins; a slot
with a damaged header or records that is not provably older than the winner makes
the store corrupt: it is reported, wiped, and the vehicle starts with an empty plan
(never silently with an older plan the operator had replaced).
Staging and commit allocate nothing (the files stay open), so a transfer runs under
micropython.heap_lock().
"""
from ..compat import const
from ..kernels import crc16

RECORD_SIZE = const(32)
HEADER_SIZE = const(16)
_MAGIC0 = const(0x4D)  # b"MSN\x01"
_MAGIC1 = const(0x53)
_MAGIC2 = const(0x4E)
_MAGIC3 = const(0x01)
_CMD_DO_JUMP = const(177)

EMPTY = const(0)  # slot states at boot
VALID = const(1)
DAMAGED = const(2)  # header checks out, records do not: its generation is known
GARBAGE = const(3)  # header itself is wrong


class MissionStore:
    """One plan type (0 mission, 1 fence, 2 rally) with room for `capacity` items."""

    def __init__(self, storage, name, mission_type, capacity):
        self.mission_type = mission_type
        self.capacity = capacity
        self.count = 0  # items in the plan in force
        self.gen = 0  # its generation (0: nothing committed yet)
        self.crc = 0xFFFF  # CRC of its records
        self.corrupt = False  # found corrupt at boot (and wiped)
        self.staged_jumps = 0  # DO_JUMP items in the staged plan, after seal()
        self._staged_crc = 0xFFFF  # and its CRC (also the scratch of _scan)
        self._staged_count = 0
        self._rec = bytearray(RECORD_SIZE)
        self._hdr = bytearray(HEADER_SIZE)
        self._files = [self._open(storage, name + ".0"), self._open(storage, name + ".1")]
        self._active = 0
        self._load()

    @staticmethod
    def _open(storage, fname):
        if not storage.exists(fname):
            f = storage.open(fname, "wb")
            f.write(bytearray(HEADER_SIZE))
            f.close()
        return storage.open(fname, "r+b")

    # --- boot -------------------------------------------------------------------

    def _load(self):
        states = [0, 0]
        gens = [0, 0]
        info = [None, None]
        for i in range(2):
            states[i], gens[i], info[i] = self._check(self._files[i])
        best = -1
        for i in range(2):
            if states[i] == VALID and (best < 0 or gens[i] > gens[best]):
                best = i
        newest = gens[best] if best >= 0 else 0
        for i in range(2):
            # A damaged slot that is provably older than the winner is a harmless leftover.
            if states[i] == GARBAGE or (states[i] == DAMAGED and (best < 0 or gens[i] > newest)):
                self.corrupt = True
        top = max(gens[0], gens[1])
        if self.corrupt:
            for f in self._files:
                f.seek(0)
                f.write(bytearray(HEADER_SIZE))
                f.flush()
            self.gen = top
            self._active = 0
            return
        if best >= 0:
            self._active = best
            self.gen = gens[best]
            self.count, self.crc = info[best]
        else:
            self.gen = top

    def _check(self, f):
        """(state, generation, (count, crc)) of one slot file."""
        hdr = self._hdr
        f.seek(0)
        n = f.readinto(hdr)
        if not n:
            return EMPTY, 0, None
        zero = True
        for i in range(n):
            if hdr[i]:
                zero = False
        if zero:
            return EMPTY, 0, None
        if (n < HEADER_SIZE or hdr[0] != _MAGIC0 or hdr[1] != _MAGIC1 or hdr[2] != _MAGIC2
                or hdr[3] != _MAGIC3 or crc16(hdr, 0, 14, 0xFFFF) != hdr[14] | hdr[15] << 8
                or hdr[4] != self.mission_type or hdr[5] != RECORD_SIZE):
            return GARBAGE, 0, None
        count = hdr[6] | hdr[7] << 8
        gen = hdr[8] | hdr[9] << 8 | hdr[10] << 16 | hdr[11] << 24
        want = hdr[12] | hdr[13] << 8
        if count > self.capacity:
            return DAMAGED, gen, None
        if not self._scan(f, count) or self._staged_crc != want:
            return DAMAGED, gen, None
        return VALID, gen, (count, want)

    def _scan(self, f, count):
        """CRC and DO_JUMP count of a slot's first `count` records (into _staged_crc and
        staged_jumps: no tuple on the commit path); False if the file is short."""
        rec = self._rec
        crc = 0xFFFF
        jumps = 0
        f.seek(HEADER_SIZE)
        for _ in range(count):
            if f.readinto(rec) != RECORD_SIZE:
                return False
            crc = crc16(rec, 0, RECORD_SIZE, crc)
            if rec[28] | rec[29] << 8 == _CMD_DO_JUMP:
                jumps += 1
        self._staged_crc = crc
        self.staged_jumps = jumps
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
        """Identifies the plan in force (MAVLink opaque_id): changes with every commit, never 0."""
        return ((self.gen & 0xFFFF) << 16 | self.crc) or 1

    # --- staging a new plan ---------------------------------------------------------

    def begin(self, keep=0):
        """Start a new plan in the spare slot, with the first `keep` items of the plan in force."""
        spare = self._files[1 - self._active]
        hdr = self._hdr
        for i in range(HEADER_SIZE):
            hdr[i] = 0
        spare.seek(0)
        spare.write(hdr)
        spare.flush()
        rec = self._rec
        if keep > self.count:
            keep = self.count
        src = self._files[self._active]
        for i in range(keep):
            src.seek(HEADER_SIZE + i * RECORD_SIZE)
            src.readinto(rec)
            spare.seek(HEADER_SIZE + i * RECORD_SIZE)
            spare.write(rec)

    def put(self, seq, rec):
        """Write record seq of the staged plan."""
        spare = self._files[1 - self._active]
        spare.seek(HEADER_SIZE + seq * RECORD_SIZE)
        return spare.write(rec) == RECORD_SIZE

    def seal(self, count):
        """Read the staged plan back: its CRC and DO_JUMP count (staged_jumps); False if short."""
        spare = self._files[1 - self._active]
        spare.flush()
        self._staged_count = count
        return self._scan(spare, count)

    def commit(self):
        """Make the sealed plan the plan in force: one header write."""
        spare_i = 1 - self._active
        spare = self._files[spare_i]
        gen = (self.gen + 1) & 0xFFFFFFFF
        count = self._staged_count
        crc = self._staged_crc
        h = self._hdr
        h[0] = _MAGIC0
        h[1] = _MAGIC1
        h[2] = _MAGIC2
        h[3] = _MAGIC3
        h[4] = self.mission_type
        h[5] = RECORD_SIZE
        h[6] = count & 0xFF
        h[7] = count >> 8
        h[8] = gen & 0xFF
        h[9] = (gen >> 8) & 0xFF
        h[10] = (gen >> 16) & 0xFF
        h[11] = gen >> 24
        h[12] = crc & 0xFF
        h[13] = crc >> 8
        c = crc16(h, 0, 14, 0xFFFF)
        h[14] = c & 0xFF
        h[15] = c >> 8
        spare.seek(0)
        if spare.write(h) != HEADER_SIZE:
            return False
        spare.flush()
        self._active = spare_i
        self.gen = gen
        self.count = count
        self.crc = crc
        return True

    def clear(self):
        """Commit an empty plan."""
        self.begin()
        self.seal(0)
        return self.commit()

    def close(self):
        for f in self._files:
            f.close()
