"""MAVLink FTP's rare events: opening, creating, listing, removing and checksumming
files, closing and resetting sessions (ftp/__init__.py answers the rest).

They allocate (paths are strings, files are objects, listings are lists), so they run
with the heap open (compat.heap_open) even on a board that locked it.
Reference: docs/services/ftp.md.
"""
import os

from ...compat import const, heap_open, heap_close
from .files import OK, BAD, IS_PROTECTED, crc32, size_of

_SESSION = const(5)
_SIZE = const(7)
_DATA = const(15)
_DATA_MAX = const(239)

_TERMINATE = const(1)
_RESET = const(2)
_LIST = const(3)
_OPEN_RO = const(4)
_CREATE = const(6)
_REMOVE = const(8)
_CRC32 = const(14)
_ACK = const(128)

FAIL = const(1)
FAIL_ERRNO = const(2)
INVALID_SESSION = const(4)
NO_SESSIONS = const(5)
EOF = const(6)
FILE_PROTECTED = const(9)
FILE_NOT_FOUND = const(10)

_FREE = const(0)
_READING = const(1)
_WRITING = const(2)
_WARNING = const(4)


class FtpRare:
    """The rare half of Ftp (ftp/__init__.py; a mixin: it works on Ftp's buffers and
    sessions)."""

    def _rare_event(self, op):
        depth = heap_open()
        try:
            self._rare(op)
        finally:
            heap_close(depth)

    def _rare(self, op):
        if op == _TERMINATE:
            slot = self._slot(self._req[_SESSION], _READING)
            if slot < 0:
                slot = self._slot(self._req[_SESSION], _WRITING)
            if slot < 0:
                self._nak(INVALID_SESSION, 0)
                return
            self._close(slot)
            self._ack(0)
        elif op == _RESET:
            for slot in range(len(self._files)):
                self._close(slot)
            self._ack(0)
        elif op == _LIST:
            self._list()
        elif op == _OPEN_RO or op == _CRC32:
            self._open_ro(op)
        elif op == _CREATE:
            self._create()
        elif op == _REMOVE:
            self._remove()

    def _path(self, want):
        """The request's path resolved -> host path, or None with the NAK made."""
        q = self._req
        code, path = self.folder.resolve(bytes(q[_DATA:_DATA + q[_SIZE]]), True, want)
        if code == OK:
            return path
        if code == IS_PROTECTED:
            self._nak(FILE_PROTECTED, 0)
            self._say("FTP: the stack's own file, not served")
        elif code == BAD:
            self._nak(FAIL, 0)
            self._say("FTP: path leaves the storage folder")
        else:
            self._nak(FILE_NOT_FOUND, 0)
        return None

    def _say(self, text):
        self.ep.statustext(_WARNING, text)

    def _allowed(self):
        if self.ep.allows(self._link):
            return True
        self._nak(FAIL, 0)
        self._say("FTP: not in control, files unchanged")
        return False

    def _list(self):
        path = self._path(0x4000)
        if path is None:
            return
        entries = self.folder.entries(path, path == self.folder.root)
        i = self._offset(self._req)
        if i < 0 or i >= len(entries):
            self._nak(EOF, 0)
            return
        r = self._reply
        n = 0
        while i < len(entries):
            name, is_dir, size = entries[i]
            text = ("D" + name if is_dir else "F%s\t%d" % (name, size)).encode() + b"\0"
            if n + len(text) > _DATA_MAX:
                break
            r[_DATA + n:_DATA + n + len(text)] = text
            n += len(text)
            i += 1
        if n == 0:  # a name too long for one reply
            self._nak(FAIL, 0)
            return
        self._head(_ACK, n)  # (after the data: it zeroes only past it)

    def _session_slot(self, sid):
        """A slot for session sid: its own (closed first), else a free one, else -1."""
        for mode in (_READING, _WRITING):
            slot = self._slot(sid, mode)
            if slot >= 0:
                self._close(slot)
                return slot
        for slot in range(len(self._mode)):
            if self._mode[slot] == _FREE:
                return slot
        return -1

    def _close(self, slot):
        f = self._files[slot]
        self._files[slot] = None
        self._mode[slot] = _FREE
        self._b_left[slot] = 0
        self._b_link[slot] = None
        if self._wf is f:
            self._wf = None
        if f is not None:
            try:
                f.close()
                if self._full[slot]:
                    os.remove(self._paths[slot])  # an upload the store had no room for
            except OSError:
                pass
        self._full[slot] = 0
        self._paths[slot] = None

    def _open_ro(self, op):
        path = self._path(0x8000)
        if path is None:
            return
        if op == _CRC32:
            with open(path, "rb") as f:
                crc = crc32(f, self._rdata)
            self._ack(4)
            _put_u32(self._reply, _DATA, crc)
            return
        slot = self._session_slot(self._req[_SESSION])
        if slot < 0:
            self._nak(NO_SESSIONS, 0)
            return
        self._files[slot] = open(path, "rb")
        self._paths[slot] = path
        self._fsize[slot] = size = size_of(path)
        self._sid[slot] = self._req[_SESSION]
        self._mode[slot] = _READING
        self._ack(4)
        _put_u32(self._reply, _DATA, size)

    def _create(self):
        if not self._allowed():
            return
        path = self._path(0)
        if path is None:
            return
        slot = self._session_slot(self._req[_SESSION])
        if slot < 0:
            self._nak(NO_SESSIONS, 0)
            return
        had = size_of(path)
        try:
            f = open(path, "wb")
        except OSError as e:
            self._nak(FAIL_ERRNO, e.args[0] if e.args else 0)
            return
        self._files[slot] = f
        self._paths[slot] = path
        self._fsize[slot] = 0
        self._sid[slot] = self._req[_SESSION]
        self._mode[slot] = _WRITING
        self._room = self.folder.room() + had if self.folder.space else self.folder.room()
        self._ack(0)

    def _remove(self):
        if not self._allowed():
            return
        path = self._path(0x8000)
        if path is None:
            return
        try:
            os.remove(path)
        except OSError as e:
            self._nak(FAIL_ERRNO, e.args[0] if e.args else 0)
            return
        self._ack(0)


def _put_u32(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = (v >> 8) & 0xFF
    b[o + 2] = (v >> 16) & 0xFF
    b[o + 3] = (v >> 24) & 0xFF
