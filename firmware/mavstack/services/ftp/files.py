"""The storage folder as the file services (ftp/__init__.py, ftp/seed.py) show it to
ground stations, with one set of rules for both protocols: nothing outside the folder is
reached (`..`, links and the like are refused), the stack's own files (PROTECTED, plus a
board's FTP_PROTECTED) are never served, and FTP_SPACE caps what the other files hold.

Everything here runs on rare events (opening, listing, removing, checksumming a file)
and may allocate; the callers open a locked heap around it (compat.heap_open). Reading
and writing an open file (read_into, write_from) allocate nothing.
Reference: docs/services/ftp.md.
"""
import os

from ...compat import MICROPYTHON
from ...fields import cstr_text

# Files of params (params/store.py's FILE), missions (their _NAMES: NAME.0, NAME.1) and
# signing (signing.py's _FILE), by the part of their name before the first dot.
PROTECTED = ("params", "mission", "fence", "rally", "signing_key")

OK = 0
BAD = -1  # `..`, a link, a malformed name: outside the folder as far as we are concerned
MISSING = -2
IS_PROTECTED = -3

_S_IFMT = 0xF000
_S_IFDIR = 0x4000
_S_IFREG = 0x8000
_S_IFLNK = 0xA000
_MAX_DEPTH = 8
ENOSPC = 28


if MICROPYTHON:
    def read_into(f, buf, n):
        """Read up to n bytes into buf (a memoryview made once) without a slice."""
        return f.readinto(buf, n)

    def write_from(f, buf, n):
        return f.write(buf, n)
else:
    def read_into(f, buf, n):
        return f.readinto(buf[:n])

    def write_from(f, buf, n):
        return f.write(buf[:n])


def _kind(parent, name):
    """S_IFDIR / S_IFREG / S_IFLNK (or another type) of parent/name, 0 if absent,
    without following a link."""
    if not MICROPYTHON:
        try:
            return os.lstat(parent + "/" + name)[0] & _S_IFMT
        except OSError:
            return 0
    try:
        for entry in os.ilistdir(parent):
            if entry[0] == name:
                return entry[1] & _S_IFMT
    except OSError:
        pass
    return 0


class Folder:
    def __init__(self, root, protected=(), space=0):
        self.root = root.rstrip("/") or "/"
        self.protected = PROTECTED + tuple(protected)
        self.space = space

    def is_protected(self, name):
        return name.split(".")[0] in self.protected

    def parts(self, raw, absolute_ok):
        """The names of a path (bytes, NUL-terminated or not) -> list, or BAD (not UTF-8 too).

        absolute_ok: a leading "/" is the folder itself (MAVLink FTP's root), else an
        absolute path is refused (the seed's "bad path")."""
        end = raw.find(b"\0")
        if end >= 0:
            raw = raw[:end]
        path = cstr_text(raw, 0, len(raw))
        if path.encode() != raw:  # not UTF-8 (replaced): refused, not renamed
            return BAD
        if path.startswith("/") and not absolute_ok:
            return BAD
        if "\\" in path:
            return BAD
        names = [p for p in path.split("/") if p and p != "."]
        if ".." in names or len(names) > _MAX_DEPTH:
            return BAD
        return names

    def resolve(self, raw, absolute_ok=True, want=_S_IFREG):
        """The host path of a file (want=S_IFREG), a directory (S_IFDIR) or a name to
        create (0) -> (code, path): code OK, BAD, MISSING or IS_PROTECTED."""
        names = self.parts(raw, absolute_ok)
        if names == BAD:
            return BAD, None
        if len(names) == 1 and self.is_protected(names[0]):
            return IS_PROTECTED, None
        path = self.root
        kind = _S_IFDIR
        last = len(names) - 1
        for i in range(len(names)):
            kind = _kind(path, names[i])
            if kind == _S_IFLNK:
                return BAD, None
            path = path + "/" + names[i]
            if i < last and kind != _S_IFDIR:
                return MISSING, None
        if want == 0:  # a file to create: absent or a file, in a folder that exists
            return (OK if names and kind in (0, _S_IFREG) else MISSING), path
        return (OK, path) if kind == want else (MISSING, None)

    def entries(self, path, at_root):
        """[(name, is_dir, size)] of a folder in a stable order, without the protected
        files (at the root) and links."""
        out = []
        try:
            listing = sorted(e[0] for e in os.ilistdir(path)) if MICROPYTHON else sorted(os.listdir(path))
        except OSError:
            return out
        for name in listing:
            if at_root and self.is_protected(name):
                continue
            kind = _kind(path, name)
            if kind == _S_IFDIR:
                out.append((name, True, 0))
            elif kind == _S_IFREG:
                out.append((name, False, size_of(path + "/" + name)))
        return out

    def used(self):
        """Bytes held by the folder's files but the stack's own, for FTP_SPACE."""
        total = _tree_size(self.root)
        for name in os.listdir(self.root):
            if self.is_protected(name) and _kind(self.root, name) == _S_IFREG:
                total -= size_of(self.root + "/" + name)
        return total

    def room(self):
        """Bytes a ground station may still add (a large number without FTP_SPACE)."""
        if not self.space:
            return 0x3FFFFFFF
        left = self.space - self.used()
        return left if left > 0 else 0


def _tree_size(path):
    total = 0
    try:
        names = [e[0] for e in os.ilistdir(path)] if MICROPYTHON else os.listdir(path)
    except OSError:
        return 0
    for name in names:
        kind = _kind(path, name)
        if kind == _S_IFDIR:
            total += _tree_size(path + "/" + name)
        elif kind == _S_IFREG:
            total += size_of(path + "/" + name)
    return total


def size_of(path):
    try:
        return os.stat(path)[6]
    except OSError:
        return 0


try:
    from binascii import crc32 as _zcrc
except ImportError:
    try:
        from zlib import crc32 as _zcrc
    except ImportError:
        _zcrc = None


def crc32(f, buf):
    """CRC-32 of an open file, as ArduPilot's crc_crc32 and MAVProxy's `crclocal` count
    it (the reflected 0xEDB88320 table, seed 0, no final inversion), read through buf."""
    crc = 0
    while True:
        n = f.readinto(buf)
        if not n:
            return crc
        crc = _crc_update(crc, buf, n)


def _crc_update(crc, buf, n):
    if _zcrc is not None:  # zlib's form inverts before and after: undo both
        return _zcrc(bytes(buf[:n]), crc ^ 0xFFFFFFFF) ^ 0xFFFFFFFF
    for i in range(n):
        crc ^= buf[i]
        for _ in range(8):
            crc = (crc >> 1) ^ (0xEDB88320 if crc & 1 else 0)
    return crc
