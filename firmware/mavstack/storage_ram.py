"""Storage for a board without a filesystem: files in one fixed memory region.

Same face as storage.Storage (exists, open, open_new, commit, discard_new, remove,
reserve), so parameters, missions and signing keep their code. The region is a
bytearray the board hands over (on the emulated boards a RAM area outside the GC heap).
A directory of fixed entries, each file with two areas: open_new writes the one not in
use and commit flips to it, so a reader never sees half a write. Nothing here allocates
once a file exists (its handles are made with it); reserve() makes a file at start-up.
Reference (the region's layout): docs/core.md.
"""
from .compat import const
from .kernels import copy, place

_MAGIC = b"MSRS"
_HEADER = const(16)
_ENTRY = const(32)
_NAME = const(16)
DEFAULT_SIZE = const(1024)
_EXISTS = const(1)  # entry byte 31
_TWO = const(2)  # has areas A and B (made by open_new or reserve)


def _u32(b, o):
    return b[o] | b[o + 1] << 8 | b[o + 2] << 16 | b[o + 3] << 24  # offsets: below 2^24


def _u24(b, o):
    return b[o] | b[o + 1] << 8 | b[o + 2] << 16  # an area's length


def _put32(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = (v >> 8) & 0xFF
    b[o + 2] = (v >> 16) & 0xFF
    b[o + 3] = (v >> 24) & 0xFF


def _put24(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = (v >> 8) & 0xFF
    b[o + 2] = v >> 16


def _copy_out(mem, s, dst, n):
    if s < 0x100000:  # (copy's source offset: below 2^20)
        copy(dst, mem, s << 10, n)
        return
    for i in range(n):
        dst[i] = mem[s + i]


class RamFile:
    """A handle on one area of a file: seek, tell, readinto, read, write, flush, close.

    write() past the capacity writes what fits and returns the count, like a full disk.
    """

    def __init__(self, storage, entry, area):
        # Four attributes (a handle per area of every file: small on the heap): the region,
        # the place in the area, where the area starts, where its length is kept. They
        # stay put; the capacity is read from the entry, before the lengths.
        self.mem = storage.mem
        self.pos = 0
        self.base = storage.area_base(entry, area)
        self.at = storage.length_at(entry, area)

    def _capacity(self):
        return _u32(self.mem, self.at - (self.at - _HEADER) % _ENTRY + 20)

    def _grown(self):
        # The area's length is at least pos.
        if self.pos > _u24(self.mem, self.at):
            _put24(self.mem, self.at, self.pos)

    def seek(self, pos, whence=0):
        if whence == 2:
            pos += _u24(self.mem, self.at)
        self.pos = pos
        return pos

    def tell(self):
        return self.pos

    def readinto(self, buf):
        n = _u24(self.mem, self.at) - self.pos
        if n > len(buf):
            n = len(buf)
        if n < 0:
            n = 0
        _copy_out(self.mem, self.base + self.pos, buf, n)
        self.pos += n
        return n

    def read(self, n=-1):
        avail = _u24(self.mem, self.at) - self.pos
        buf = bytearray(avail if n < 0 or n > avail else n)
        self.readinto(buf)
        return bytes(buf)

    def write(self, buf):
        n = self._capacity() - self.pos
        if n > len(buf):
            n = len(buf)
        if n < 0:
            n = 0
        place(self.mem, self.base + self.pos, buf, n)
        self.pos += n
        self._grown()
        return n

    # In place (RamStorage.IN_PLACE): the area is memory()[offset():], with room() bytes
    # from here; a writer that filled it says how much (wrote). Nothing is copied.
    def memory(self):
        return self.mem

    def offset(self):
        return self.base + self.pos

    def room(self):
        return self._capacity() - self.pos

    def wrote(self, n):
        self.pos += n
        self._grown()

    def flush(self):
        pass

    def close(self):
        self.pos = 0

    def __enter__(self):
        return self

    def __exit__(self, a, b, c):
        self.close()


class RamStorage:
    IN_PLACE = True  # its files can be read and written in place (RamFile.memory)

    def __init__(self, region, max_files=12):
        self.mem = region
        self.root = "ram"
        self.max_files = max_files
        self._data = _HEADER + _ENTRY * max_files
        self._names = [None] * max_files  # entry -> name (str), as created
        self._handles = [None] * max_files  # entry -> [RamFile A, RamFile B], made once
        mem = region
        if mem[0:4] != _MAGIC or mem[4] != max_files:
            self.format()
        for e in range(mem[5]):  # files of an earlier run (a soft reset keeps the region)
            o = _HEADER + _ENTRY * e
            n = 0
            while n < _NAME and mem[o + n]:
                n += 1
            self._adopt(e, bytes(mem[o:o + n]).decode())

    def format(self):
        """Empty the region's directory (the data areas are reused from the start)."""
        mem = self.mem
        for i in range(self._data):
            mem[i] = 0
        mem[0:4] = _MAGIC
        mem[4] = self.max_files
        for e in range(self.max_files):
            self._names[e] = self._handles[e] = None

    def _adopt(self, e, name):
        self._names[e] = name
        self._handles[e] = [RamFile(self, e, 0), RamFile(self, e, 1)]

    # --- entries ------------------------------------------------------------------
    def _find(self, name):
        names = self._names
        for e in range(self.mem[5]):
            if names[e] == name:
                return e
        return -1

    def _entry(self, e):
        return _HEADER + _ENTRY * e

    def area_base(self, e, area):
        o = self._entry(e)
        return _u32(self.mem, o + 16) + area * _u32(self.mem, o + 20)

    def capacity(self, e):
        return _u32(self.mem, self._entry(e) + 20)

    def length_at(self, e, area):
        """The offset of an area's length (3 bytes) in the region."""
        return self._entry(e) + 24 + 4 * area

    def length(self, e, area):
        return _u24(self.mem, self.length_at(e, area))

    def set_length(self, e, area, n):
        _put24(self.mem, self.length_at(e, area), n)

    def _current(self, e):
        return self.mem[self._entry(e) + 27]

    def _flags(self, e):
        return self.mem[self._entry(e) + 31]

    def _set_flags(self, e, flags):
        self.mem[self._entry(e) + 31] = flags

    def used(self):
        """Bytes of the region handed out so far."""
        end = self._data
        for e in range(self.mem[5]):
            o = self._entry(e)
            top = _u32(self.mem, o + 16) + _u32(self.mem, o + 20) * (2 if self.mem[o + 31] & _TWO else 1)
            if top > end:
                end = top
        return end

    def _create(self, name, size, areas):
        mem = self.mem
        e = mem[5]
        raw = name.encode()
        base = self.used()
        if e >= self.max_files or len(raw) > _NAME or base + areas * size > len(mem):
            raise OSError(28)  # ENOSPC
        o = self._entry(e)
        for i in range(_ENTRY):
            mem[o + i] = 0
        for i in range(len(raw)):
            mem[o + i] = raw[i]
        _put32(mem, o + 16, base)
        _put32(mem, o + 20, size)
        mem[o + 31] = _TWO if areas == 2 else 0
        mem[5] = e + 1
        self._adopt(e, name)
        return e

    def _handle(self, e, area):
        h = self._handles[e][area]
        h.pos = 0
        return h

    # --- the Storage face ---------------------------------------------------------
    def path(self, name):
        return "ram:" + name

    def reserve(self, name, size):
        """Make room for a file written with open_new/commit later (at start-up: the
        first save then allocates nothing)."""
        if self._find(name) < 0:
            self._create(name, size, 2)

    def exists(self, name):
        e = self._find(name)
        return e >= 0 and self._flags(e) & _EXISTS != 0

    def open(self, name, mode="rb", size=DEFAULT_SIZE):
        e = self._find(name)
        if e < 0:
            if "r" in mode and "+" not in mode:
                raise OSError(2)  # ENOENT
            e = self._create(name, size, 1)
        elif not self._flags(e) & _EXISTS and "w" not in mode and "+" not in mode:
            raise OSError(2)  # reserved, never committed
        return self._opened(e, mode)

    def _opened(self, e, mode):
        area = self._current(e)
        h = self._handle(e, area)
        if "w" in mode:
            self.set_length(e, area, 0)
        self._set_flags(e, self._flags(e) | _EXISTS)
        return h

    def open_new(self, name, size=DEFAULT_SIZE):
        """A handle on the area not in use; commit(name) makes it the file."""
        e = self._find(name)
        if e < 0:
            e = self._create(name, size, 2)
        elif not self._flags(e) & _TWO:
            raise OSError(22)  # EINVAL: made by open(), it has one area
        return self._emptied(e, 1 - self._current(e))

    def _emptied(self, e, area):
        self.set_length(e, area, 0)
        return self._handle(e, area)

    def commit(self, name):
        e = self._find(name)
        o = self._entry(e)
        self.mem[o + 27] = 1 - self.mem[o + 27]
        self.mem[o + 31] |= _EXISTS

    def discard_new(self, name):
        e = self._find(name)
        if e >= 0:
            self.set_length(e, 1 - self._current(e), 0)

    def remove(self, name):
        e = self._find(name)
        if e >= 0:
            self.set_length(e, self._current(e), 0)
            self._set_flags(e, self._flags(e) & ~_EXISTS)
