"""Files that survive power loss: write a new file, then atomically replace the old.

A reader never sees a half-written file: the data goes to NAME.new, is flushed,
and only then renamed over NAME. On boot a leftover NAME.new is discarded.
Callers add their own header and checksum (see checksum()) to detect a corrupt file.
`size` (the most a file will hold) is for storage_ram.py, the same face for boards
without a filesystem; files ignore it. Also: CRC-sealed records (save_sealed, sealed).
Reference: docs/core.md.
"""
import os

from .compat import heap_open, heap_close
from .kernels import crc16


def _exists(path):
    try:
        os.stat(path)
        return True
    except OSError:
        return False


def makedirs(path):
    parts = path.split("/")
    cur = "" if parts[0] else "/"
    for part in parts:
        if not part:
            continue
        cur = cur + part if cur in ("", "/") else cur + "/" + part
        if not _exists(cur):
            os.mkdir(cur)


class Storage:
    # Opening, renaming and removing files make strings and file objects: rare events,
    # so each opens a heap that a board locked after start-up (compat.heap_open) and
    # locks it again, whatever the outcome. Reads and writes of an open file make nothing.
    def __init__(self, root):
        self.root = root.rstrip("/") or "/"
        makedirs(self.root)

    def path(self, name):
        return self.root + "/" + name

    def exists(self, name):
        depth = heap_open()
        try:
            return _exists(self.path(name))
        finally:
            heap_close(depth)

    def open_new(self, name, size=None):
        """Open NAME.new for writing; commit(name) makes it NAME."""
        depth = heap_open()
        try:
            return open(self.path(name) + ".new", "wb")
        finally:
            heap_close(depth)

    def reserve(self, name, size):
        """Nothing to do on a file system (storage_ram.py makes room here)."""

    def commit(self, name):
        depth = heap_open()
        try:
            new = self.path(name) + ".new"
            final = self.path(name)
            try:
                os.rename(new, final)  # atomic on POSIX and littlefs
            except OSError:
                # FAT cannot rename over a file: the one non-atomic window is here.
                os.remove(final)
                os.rename(new, final)
        finally:
            heap_close(depth)

    def discard_new(self, name):
        depth = heap_open()
        try:
            if _exists(self.path(name) + ".new"):
                os.remove(self.path(name) + ".new")
        finally:
            heap_close(depth)

    def open(self, name, mode="rb", size=None):
        depth = heap_open()
        try:
            return open(self.path(name), mode)
        finally:
            heap_close(depth)

    def remove(self, name):
        depth = heap_open()
        try:
            if _exists(self.path(name)):
                os.remove(self.path(name))
        finally:
            heap_close(depth)


def checksum(data, crc=0xFFFF):
    """CRC-16 of a bytes-like object, continuing from crc."""
    return crc16(data, 0, len(data), crc)


# A small record kept whole in one file, sealed by a CRC-16 in its last two bytes (the
# signing key, the origin and allowed area): saved by replacing the file, so that power
# lost mid-write leaves the old record or the new. Either storage (this one or
# storage_ram.py) takes it; nothing is allocated on a board's heap but by the storage.
def save_sealed(storage, name, data):
    """Seal data (a bytearray: its last two bytes take the CRC-16 of the rest) and
    replace file `name` with it."""
    n = len(data) - 2
    crc = crc16(data, 0, n, 0xFFFF)
    data[n] = crc & 0xFF
    data[n + 1] = crc >> 8
    # No `with`: RamFile.__exit__(*exc) would allocate its arguments' tuple.
    f = storage.open_new(name, n + 2)
    f.write(data)
    f.close()
    storage.commit(name)


def sealed(data, size):
    """data, read back, is a whole record of `size` bytes whose CRC-16 checks."""
    n = size - 2
    return len(data) == size and crc16(data, 0, n, 0xFFFF) == data[n] | data[n + 1] << 8
