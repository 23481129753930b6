"""The seed's file transfer: FILE_TRANSFER_START / _DIR_LIST / _RES (#110-#112, seed2012).

A small file service over the storage folder, with the rules of files.py and the seed's
result codes (0 OK, 1 not permitted, 2 bad path, 3 no space). The seed defines no data
message, so data travels in 240-byte chunks in the path fields, numbered in `flags`,
every message of a transfer carrying its transfer_uid; FILE_TRANSFER_RES is its final
word. A write (up to 255 chunks) replaces the file atomically once every chunk is in.
One outgoing transfer (a listing or a read) and one incoming (a write) at a time; chunks
go out from tick() at the streams' rank.
Reference (the exchange, message by message): docs/services/ftp.md.
"""
import os

from ...compat import const, heap_open, heap_close
from ...kernels import copy, zero
from ...link import RANK_BULK, RANK_AUTO
from .files import Folder, read_into, write_from, size_of, OK, BAD, IS_PROTECTED

_MSG_START = const(110)
_MSG_DIR_LIST = const(111)
_MSG_RES = const(112)
_START_LEN = const(254)  # '<QI240sBB': uid, file_size, dest_path, direction, flags
_LIST_LEN = const(249)  # '<Q240sB': uid, dir_path, flags
_RES_LEN = const(9)
_CHUNK = const(240)
_MAX_CHUNKS = const(255)
MAX_FILE = const(61200)

RESULT_OK = const(0)
RESULT_NOT_PERMITTED = const(1)
RESULT_BAD_PATH = const(2)
RESULT_NO_SPACE = const(3)

_IDLE = const(0)
_LISTING = const(1)
_READING = const(2)
_FRAME = const(270)
_PER_TICK = const(4)
_WARNING = const(4)


class SeedFiles:
    NAME = "ftp"
    CLOCK = False

    def __init__(self, protected=(), space=0):
        self._protected = protected
        self._space = space
        self.folder = None
        self.ep = None
        self._in = bytearray(_START_LEN)  # the chunk being written
        self._in_data = memoryview(self._in)[12:]
        self._out = bytearray(_START_LEN)  # chunks going out, echoes
        self._out_data = memoryview(self._out)[12:]
        self._res = bytearray(_RES_LEN)
        # Outgoing: a listing (its text) or a read (its file), chunk by chunk.
        self._send_kind = _IDLE
        self._send_uid = bytearray(8)
        self._send_link = None
        self._send_next = 0
        self._send_size = 0
        self._send_file = None
        self._send_text = b""
        # Incoming: the write in progress.
        self._w_uid = bytearray(8)
        self._w_state = _IDLE  # 1: chunks coming, 2: done (repeats are answered again)
        self._w_file = None
        self._w_path = None
        self._w_size = 0
        self._w_have = bytearray(32)  # a bit per chunk received
        self._w_count = 0

    def attach(self, ep):
        self.ep = ep
        root = getattr(getattr(ep, "storage", None), "root", None)
        if root is None or getattr(ep.storage, "mem", None) is not None:
            return
        self.folder = Folder(root, self._protected, self._space)
        ep.on(_MSG_START, self._on_start)
        ep.on(_MSG_DIR_LIST, self._on_dir_list)

    # --- answers --------------------------------------------------------------------
    def _result(self, link, uid, result):
        r = self._res
        copy(r, uid, 0, 8)
        r[8] = result
        link.send_payload(_MSG_RES, r, _RES_LEN)

    def _echo(self, link, p):
        """START(uid, file_size, "", direction, flags) back: the request taken."""
        o = self._out
        copy(o, p, 0, 12)
        zero(o, 12, _START_LEN)
        o[252] = p[252]
        o[253] = p[253]
        link.send_payload(_MSG_START, o, _START_LEN)

    def _refuse(self, link, uid, code):
        if code == IS_PROTECTED:
            self.ep.statustext(_WARNING, b"Files: the stack's own file, not served")
            self._result(link, uid, RESULT_NOT_PERMITTED)
        else:
            if code == BAD:
                self.ep.statustext(_WARNING, b"Files: path leaves the storage folder")
            self._result(link, uid, RESULT_BAD_PATH)

    # --- requests -------------------------------------------------------------------
    def _on_dir_list(self, link, p):
        depth = heap_open()
        try:
            code, path = self.folder.resolve(bytes(p[8:248]), False, 0x4000)
            if code != OK:
                self._refuse(link, p, code)
                return
            lines = []
            for name, is_dir, size in self.folder.entries(path, path == self.folder.root):
                lines.append("D%s\n" % name if is_dir else "F%s\t%d\n" % (name, size))
            self._begin_send(link, p, _LISTING, p[248])
            self._send_text = "".join(lines).encode()
            self._send_size = len(self._send_text)
        finally:
            heap_close(depth)

    def _on_start(self, link, p):
        if p[252] == 1:
            depth = heap_open()
            try:
                self._read(link, p)
            finally:
                heap_close(depth)
        elif p[252] != 0:
            self._result(link, p, RESULT_BAD_PATH)
        elif p[253] == 0:
            depth = heap_open()
            try:
                self._open_write(link, p)
            finally:
                heap_close(depth)
        else:
            self._chunk(link, p)

    def _begin_send(self, link, p, kind, first):
        self._stop_send()
        copy(self._send_uid, p, 0, 8)
        self._send_kind = kind
        self._send_link = link
        self._send_next = first

    def _stop_send(self):
        self._send_kind = _IDLE
        self._send_text = b""
        if self._send_file is not None:
            self._send_file.close()
            self._send_file = None

    def _read(self, link, p):
        code, path = self.folder.resolve(bytes(p[12:252]), False, 0x8000)
        if code != OK:
            self._refuse(link, p, code)
            return
        size = size_of(path)
        if size > MAX_FILE:
            self.ep.statustext(_WARNING, b"Files: larger than the seed's transfer carries")
            self._result(link, p, RESULT_NOT_PERMITTED)
            return
        self._begin_send(link, p, _READING, p[253])
        self._send_file = open(path, "rb")
        self._send_size = size

    # --- sending chunks ---------------------------------------------------------------
    def tick(self, now):
        if self._send_kind == _IDLE:
            return
        link = self._send_link
        k = 0
        while k < _PER_TICK and self._send_kind != _IDLE:
            if not link.can_send(_FRAME, RANK_BULK):
                return
            link.rank = RANK_BULK
            self._send_one(link)
            link.rank = RANK_AUTO
            k += 1

    def _send_one(self, link):
        """The next chunk out, or the final RES(uid, 0) once past the last."""
        k = self._send_next
        start = k * _CHUNK
        n = self._send_size - start
        if n > _CHUNK:
            n = _CHUNK
        if n < 0 or (n == 0 and (k > 0 or self._send_kind == _LISTING)):
            self._result(link, self._send_uid, RESULT_OK)
            depth = heap_open()
            self._stop_send()
            heap_close(depth)
            return
        if self._send_kind == _LISTING:
            self._list_chunk(link, k, start, n)
        else:
            self._file_chunk(link, k, start, n)
        self._send_next = k + 1

    def _list_chunk(self, link, k, start, n):
        o = self._out
        copy(o, self._send_uid, 0, 8)
        copy(o, self._send_text, start << 10 | 8, n)
        zero(o, 8 + n, _LIST_LEN)
        o[248] = k
        link.send_payload(_MSG_DIR_LIST, o, _LIST_LEN)

    def _file_chunk(self, link, k, start, n):
        o = self._out
        copy(o, self._send_uid, 0, 8)
        _put_u32(o, 8, self._send_size)
        self._send_file.seek(start)
        n = read_into(self._send_file, self._out_data, n)
        zero(o, 12 + n, _START_LEN)
        o[252] = 1
        o[253] = k
        link.send_payload(_MSG_START, o, _START_LEN)

    # --- writes -------------------------------------------------------------------------
    def _open_write(self, link, p):
        if self._w_state == 2 and _same_uid(self._w_uid, p):
            self._echo(link, p)  # the request again, after the transfer: it is done
            self._result(link, p, RESULT_OK)
            return
        if self._w_state == 1 and _same_uid(self._w_uid, p):
            self._echo(link, p)  # asked again: the echo was lost
            return
        if not self.ep.allows(link):
            self.ep.statustext(_WARNING, b"Files: not in control, files unchanged")
            self._result(link, p, RESULT_NOT_PERMITTED)
            return
        code, path = self.folder.resolve(bytes(p[12:252]), False, 0)
        if code != OK:
            self._refuse(link, p, code)
            return
        size = _u32(p, 8)
        if size > MAX_FILE or size > self.folder.room() + (size_of(path) if self.folder.space else 0):
            self.ep.statustext(_WARNING, b"Files: no space for that file")
            self._result(link, p, RESULT_NO_SPACE)
            return
        self._abandon()
        try:
            self._w_file = open(path + ".new", "wb")
        except OSError:
            self._result(link, p, RESULT_BAD_PATH)
            return
        copy(self._w_uid, p, 0, 8)
        self._w_path = path
        self._w_size = size
        zero(self._w_have, 0, 32)
        self._w_count = 0
        self._w_state = 1
        self._echo(link, p)
        if size == 0:
            self._finish(link, p)

    def _abandon(self):
        """Drop a write that never finished (its NAME.new)."""
        if self._w_state == 1 and self._w_file is not None:
            self._w_file.close()
            try:
                os.remove(self._w_path + ".new")
            except OSError:
                pass
        self._w_file = None
        self._w_state = _IDLE

    def _chunk(self, link, p):
        if self._w_state == _IDLE or not _same_uid(self._w_uid, p):
            self._result(link, p, RESULT_NOT_PERMITTED)  # no such transfer open
            return
        k = p[253] - 1
        if self._w_state == 1 and not self._w_have[k >> 3] & (1 << (k & 7)):
            if not self._store(p, k):
                return self._no_space(link, p)
        self._echo(link, p)
        if self._w_state == 2 or self._w_count == (self._w_size + _CHUNK - 1) // _CHUNK:
            self._finish(link, p)

    def _store(self, p, k):
        start = k * _CHUNK
        n = self._w_size - start
        if n > _CHUNK:
            n = _CHUNK
        if n <= 0:
            return True  # past the end: nothing to keep (still echoed)
        copy(self._in, p, 12 << 10 | 12, n)
        try:
            self._w_file.seek(start)
            if write_from(self._w_file, self._in_data, n) != n:
                return False
        except OSError:
            return False
        self._w_have[k >> 3] |= 1 << (k & 7)
        self._w_count += 1
        return True

    def _no_space(self, link, p):
        depth = heap_open()
        try:
            self._abandon()
            self.ep.statustext(_WARNING, b"Files: storage full, write dropped")
        finally:
            heap_close(depth)
        self._result(link, p, RESULT_NO_SPACE)

    def _finish(self, link, p):
        if self._w_state == 1:
            depth = heap_open()
            try:
                self._w_file.close()
                self._w_file = None
                try:
                    os.rename(self._w_path + ".new", self._w_path)
                except OSError:
                    os.remove(self._w_path)  # FAT cannot rename over a file
                    os.rename(self._w_path + ".new", self._w_path)
                self._w_state = 2
            finally:
                heap_close(depth)
        self._result(link, p, RESULT_OK)


def _same_uid(uid, p):
    i = 0
    while i < 8:
        if uid[i] != p[i]:
            return False
        i += 1
    return True


def _u32(b, o):
    if b[o + 3] >= 0x40:
        return 0x3FFFFFFF  # from 2^30 on (past the small ints: docs/design.md), and too big
    return b[o] | b[o + 1] << 8 | b[o + 2] << 16 | b[o + 3] << 24


def _put_u32(b, o, v):
    b[o] = v & 0xFF
    b[o + 1] = (v >> 8) & 0xFF
    b[o + 2] = (v >> 16) & 0xFF
    b[o + 3] = (v >> 24) & 0xFF
