"""Parameters in storage, a part of Params: the file "params", PREFLIGHT_STORAGE and
whole sets of values taken (a reload, the defaults).

The file is written new and renamed over the old one, and read back at start-up and on
PREFLIGHT_STORAGE 0; its image (records by name, checksummed) is table.py's. A save or a
reload asks the heap for nothing: the file goes through one buffer made at start-up, or,
in RAM storage (IN_PLACE), is packed and read where it lies; under a Guard instead of try.

Reference: docs/services/params.md
"""
from ...compat import const, ticks_diff, heap_open, heap_close, to_grid
from ...link import RANK_BULK, RANK_FILL

FILE = "params"

_SEVERITY_ERROR = const(3)
_SEVERITY_WARNING = const(4)
_SEVERITY_NOTICE = const(5)
_SEVERITY_INFO = const(6)

_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_UNSUPPORTED = const(3)
_RESULT_FAILED = const(4)
_IDLE_MS = const(1000)  # the tick with nothing owed and nothing to save
VALUE_FRAME = const(37)  # bytes of a MAVLink 2 PARAM_VALUE (unsigned), asked of the budget
_LIST_BATCH = const(3)  # values of a list a pass sends (see _ready)


class ParamStore:
    """Storage for Params (which has the table, self.ep, self._guard, self.dirty,
    self.autosave_ms and _announce)."""

    def _attach_storage(self, storage):
        """At start-up: the file's buffer (unless storage is read and written in place),
        the stored values, and the file's room (the first save then allocates nothing)."""
        if storage is not None and not getattr(storage, "IN_PLACE", False):
            self.image()
        self._load(True)
        if storage is not None:
            storage.reserve(FILE, self.size)

    def _preflight_storage(self, cmd):
        result = _RESULT_ACCEPTED
        if not cmd.nan(1):
            result = self.persist(cmd.int(1), cmd.link)
        if self._storage_next is not None:
            other = self._storage_next(cmd)
            if result == _RESULT_ACCEPTED:
                result = other
        return result

    def persist(self, action, link=None):
        """PREFLIGHT_STORAGE param1: 0 reload, 1 save, 2 and 4 defaults -> MAV_RESULT."""
        if action == 1:
            return _RESULT_ACCEPTED if self.save() else _RESULT_FAILED
        if action != 0 and action != 2 and action != 4:
            # 3 resets sensor calibration only: there is none here.
            return _RESULT_UNSUPPORTED if action == 3 else _RESULT_DENIED
        if link is not None and not self.ep.allows(link):
            return _RESULT_DENIED
        if action == 0:
            return _RESULT_ACCEPTED if self._load(False) else _RESULT_FAILED
        self._take(self._defaults, False)
        self.ep.statustext(_SEVERITY_NOTICE, b"params reset to defaults")
        return _RESULT_ACCEPTED

    def save(self):
        """Write every value to storage "params", atomically -> success."""
        if getattr(self.ep, "storage", None) is None:
            return False
        with self._guard:
            self._write()
        e = self._guard.error
        if e is not None:
            self._say(_SEVERITY_ERROR, "params not saved: %s", e, b"params not saved")
            return False
        self.dirty = False
        return True

    def _write(self):
        storage = self.ep.storage
        # size: RAM storage gives a file its room when first made.
        f = self._guard.file = storage.open_new(FILE, size=self.size)
        n = self._pack_in(f) if getattr(storage, "IN_PLACE", False) else f.write(self.pack())
        self._guard.file = None
        f.close()  # before commit: a file system flushes it here
        if n != self.size:
            raise OSError(28)  # ENOSPC: the file's room is smaller (made by another firmware)
        storage.commit(FILE)

    def _pack_in(self, f):
        """The file packed straight into storage's memory -> its length, 0 if no room."""
        if f.room() < self.size:
            return 0
        self.pack(f.memory(), f.offset())
        f.wrote(self.size)
        return self.size

    def _load(self, boot):
        """Read storage "params" -> success. At boot an unusable file means defaults;
        a reload keeps the values in force."""
        storage = getattr(self.ep, "storage", None)
        n = -1
        if storage is not None:
            if boot:
                storage.discard_new(FILE)  # a save cut short: the old file stands
            n = self._read(storage)
        bad = -1 if n < 0 else self._unpack_read(n)
        if bad < 0:
            self._not_loaded(boot, storage, n)
            return False
        if boot:
            self.adopt(self._loaded)
        else:
            self._take(self._loaded, True)
        self.dirty = False
        if bad:
            self._say(_SEVERITY_NOTICE, "params: %d stored values invalid, defaults used", bad,
                      b"params: stored values invalid, defaults used")
        return True

    def _unpack_read(self, n):
        """unpack() what _read read (apart: small frames, docs/design.md)."""
        return self.unpack(self._data, n, self._at)

    def _read(self, storage):
        """The stored file into self._data -> its length, -1 if there is none."""
        with self._guard:
            return self._read_file(storage)
        return -1  # an OSError: no file, or one that cannot be read

    def _read_file(self, storage):
        f = self._guard.file = storage.open(FILE, "rb")
        if getattr(storage, "IN_PLACE", False):  # read where it is
            self._data = f.memory()
            self._at = f.offset()
            n = f.seek(0, 2)
        else:
            self._at = 0
            n = f.readinto(self._room(f))
        self._guard.file = None
        f.close()
        return n

    def _room(self, f):
        """A buffer for file f: the file image's, unless f is bigger (a file another
        firmware wrote: a rare buffer of its own)."""
        n = f.seek(0, 2)
        f.seek(0, 0)
        self._data = self.image() if n <= self.size else bytearray(n)
        return self._data

    def _not_loaded(self, boot, storage, n):
        if storage is None:
            why = "no storage"
        else:
            why = "none stored" if n < 0 else "stored file corrupt"
        if boot:
            sev = _SEVERITY_INFO if n < 0 else _SEVERITY_WARNING
            self.ep.statustext(sev, "params: %s, using defaults" % why)
        else:
            self._say(_SEVERITY_WARNING, "params not reloaded: %s", why, b"params not reloaded")

    def _touch(self):
        """A value changed: dirty, saved PARAM_AUTOSAVE_MS from now if that is set."""
        self.dirty = True
        self._changed_at = self.ep.now

    def _tell(self, i):
        """on_change(name, value): made for the application, a rare event, so on a board
        that locks its heap the lock is opened for it."""
        depth = heap_open()
        try:
            self.on_change(self.name(i), self.value(i))
        finally:
            heap_close(depth)

    def _autosave(self, now):
        """Save when PARAM_AUTOSAVE_MS have passed since the last change -> ms to the
        next work (that save, or values still owed to a link)."""
        if not self.autosave_ms:
            return self._wait(now)
        ms = self.autosave_ms - ticks_diff(now, self._changed_at)
        if ms <= 0:
            self.save()
        wait = self._wait(now)
        return wait if ms <= 0 or ms > wait else ms

    def _wait(self, now):
        """ms to the next work: while values are owed to a link, until its budget has
        room for the next (waking a pass at a time to find none cost more than the
        sends), else the next second on the loop's grid."""
        pending = self._pending
        ms = _IDLE_MS
        i = 0
        while i < len(pending):
            if pending[i]:
                ms = self._ready(i, ms)
            i += 1
        return ms if ms < _IDLE_MS else to_grid(now, _IDLE_MS)

    def _ready(self, i, ms):
        # (apart from _wait: small frames, docs/design.md) The rank as _send_next's. A
        # list waits for room for _LIST_BATCH values (or what is left of it), sent on one
        # pass: a pass a value cost more than the value. Answers wait for one.
        if self._answers[i]:
            r = self.ep.links[i].ready_in(VALUE_FRAME, RANK_BULK)
        else:
            r = self.ep.links[i].ready_in(VALUE_FRAME * (
                self._pending[i] if self._pending[i] < _LIST_BATCH else _LIST_BATCH), RANK_FILL)
        return r if r < ms else ms

    def _take(self, values, saved):
        """A whole set of values (reload, defaults): sent and reported where changed."""
        if not self.adopt(values):
            return
        mark = self._mark
        for i in range(self.count):
            if mark[i]:
                self._announce(i)
        if not saved:
            self._touch()
        if self.on_change is not None:
            self._report()

    def _report(self):
        """on_change for every value adopt() changed (allocates: names, values)."""
        for i in range(self.count):
            if self._mark[i]:
                self.on_change(self.name(i), self.value(i))

    def _say(self, severity, fmt, arg, plain):
        """STATUSTEXT fmt % arg, or plain (bytes) if that cannot be made."""
        try:
            text = fmt % arg
        except MemoryError:
            text = plain
        self.ep.statustext(severity, text)


class Guard:
    """`with guard:` around work on a storage file: an OSError raised in the block ends
    there, kept in guard.error, and guard.file, if the block left one open, is closed.

    It is what try/except OSError as e and try/finally would do, in frames small enough
    for the C stack (docs/design.md, "Function frames"), and without the file's own
    __exit__ (RamFile's takes *exc: a tuple on every call).
    """

    def __init__(self):
        self.error = None
        self.file = None

    def __enter__(self):
        self.error = None
        return self

    def __exit__(self, kind, e, tb):
        f = self.file
        if f is not None:
            self.file = None
            f.close()
        self.error = e
        return isinstance(e, OSError)
