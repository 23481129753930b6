"""The parameter table: names, types, ranges and values in a few flat buffers.

Declared once, as a tuple of rows or a block made from them (block.py; the format:
docs/services/params.md): names, types and limits are read in place from the block,
which a frozen board keeps in flash. Each value takes 4 bytes, as it travels in
PARAM_VALUE (encoding.py); names are found through a crc16 of the id's bytes and one
compare, so a lookup from a received frame allocates nothing. Values are checked on their
keys (encoding.py), taken one at a time (accept) or as a whole set (adopt), and packed
into and read from the parameter file's image, which stores them by name in one buffer
made at start-up.

Reference: docs/services/params.md
"""
import struct

from ...compat import const
from ...fields import u16, f32_is_nan, cstr_len
from ...kernels import crc16
from .encoding import FRACTION, key, unkey, cast_unkey, not_finite, get_int, put_int
from .encoding import cmp4, copy4, move, put16
from . import block
from .block import INT_RANGE as _INT_RANGE

# MAV_PARAM_TYPE
UINT8 = const(1)
INT8 = const(2)
UINT16 = const(3)
INT16 = const(4)
UINT32 = const(5)
INT32 = const(6)
UINT64 = const(7)
INT64 = const(8)
REAL32 = const(9)
REAL64 = const(10)

# flags
READ_ONLY = const(1)  # the application sets it; ground stations only read it
REBOOT = const(2)  # takes effect after a reboot

ID_LEN = const(16)  # a name's room: param_id's
_MAGIC = b"MSPR"
_FILE_VERSION = const(1)
_HEADER = const(8)  # magic, version, reserved, count (u16)

class ParamTable:
    def __init__(self, table, c_cast=False):
        """table: rows (compiled here) or a block (block.py) read in place."""
        if not isinstance(table, (bytes, bytearray)):
            table = block.compile(table)
        n, nb = block.count(table)
        o = block.parts(n, nb)
        b = memoryview(table)
        self.count = n
        self.c_cast = c_cast
        self.changed = False  # set by accept(): the value changed
        self._names = b[o[0] : o[1]]  # as param_id
        self._lens = b[o[1] : o[2]]
        self._types = b[o[2] : o[3]]
        self._flags = b[o[3] : o[4]]
        self._defaults = b[o[4] : o[5]]
        self._lo = b[o[5] : o[6]]  # ranges, as keys
        self._hi = b[o[6] : o[7]]
        self._buckets = b[o[7] : o[8]]  # crc16 of a name -> first index + 1 with that hash
        self._chain = b[o[8] : o[9]]  # -> next index + 1 with the same hash
        self._mask = nb - 1
        self._values = bytearray(4 * n)
        # C-cast: integers travel as floats, so the wire copy differs from the values.
        self._wire = bytearray(4 * n) if c_cast else self._values
        self._k = bytearray(4)  # the key being checked
        self._scratch = bytearray(4)
        self._mark = bytearray(n)  # adopt(): which values changed
        self._loaded = bytearray(4 * n)  # unpack(): the values of a file
        self._bad = 0
        size = _HEADER + 2
        for i in range(n):
            size += 6 + self._lens[i]
        self.size = size  # of the file image
        self._image = None  # image(): where pack() writes the file, made on first use
        self.adopt(self._defaults)

    def find(self, src, o, n):
        """Index of the parameter named src[o:o+n], else -1 (allocates nothing)."""
        if n == 0:
            return -1
        i = crc16(src, o, o + n, 0xFFFF) & self._mask
        i = u16(self._buckets, 2 * i) - 1
        while i >= 0 and not self._named(i, src, o, n):
            i = u16(self._chain, 2 * i) - 1
        return i

    def find_id(self, p, o):
        """Index of the parameter whose param_id (NUL-padded) is at p[o:], else -1."""
        return self.find(p, o, cstr_len(p, o, ID_LEN))

    def _named(self, i, src, o, n):
        if self._lens[i] != n:
            return False
        names = self._names
        d = ID_LEN * i - o  # names[k + d] is the name's byte for src[k]
        end = o + n
        while o < end and names[o + d] == src[o]:
            o += 1
        return o == end

    # --- checks (allocate nothing, whatever the value) --------------------------------
    def _key(self, i, src, o, cast):
        """self._k := src[o:o+4] as parameter i's key -> 0, else why not (FRACTION, ...)
        (cast: the bytes are a float holding the value)."""
        return key(self._types[i], src, o, cast, self._k)

    def _inside(self, i):
        """self._k is within parameter i's min..max."""
        o = 4 * i
        return cmp4(self._k, 0, self._lo, o) >= 0 and cmp4(self._k, 0, self._hi, o) <= 0

    def valid(self, i, src, o):
        """src[o:o+4], in the parameter's own encoding, is a value it may take."""
        if self._types[i] == REAL32 and not_finite(src, o):
            return False
        self._key(i, src, o, False)
        return self._inside(i)

    def accept(self, i, src, o, cast):
        """Store src[o:o+4] into parameter i if it is a value it may take -> None,
        else why not. self.changed tells whether the value changed."""
        self.changed = False
        if (self._types[i] == REAL32 or cast) and not_finite(src, o):
            return "NaN" if f32_is_nan(src, o) else "not finite"
        if self._key(i, src, o, cast) == 0 and self._inside(i):
            self._store(i)
            return None
        return self._why_not(i, src, o, cast)

    def _why_not(self, i, src, o, cast):
        """Why accept() refused a finite value (the rare path: it allocates, but not
        with the heap locked)."""
        if self._key(i, src, o, cast) == FRACTION:
            return "not a whole number"
        try:
            return "out of range %s..%s" % (self._show(i, self._lo), self._show(i, self._hi))
        except MemoryError:  # the heap is locked (the emulated boards): without the limits
            return "out of range"

    def _store(self, i):
        """Parameter i := the value whose key is in self._k; sets self.changed."""
        t = self._types[i]
        v = self._scratch
        unkey(t, self._k, v)
        self.changed = cmp4(self._values, 4 * i, v, 0) != 0
        copy4(self._values, 4 * i, v, 0)
        if self.c_cast:
            self._cast(i, t)

    def _cast(self, i, t):
        """The C-cast wire copy of parameter i: floats as they are, integers converted."""
        if t == REAL32:
            copy4(self._wire, 4 * i, self._values, 4 * i)
        else:
            cast_unkey(t, self._k, self._wire, 4 * i)

    def _show(self, i, keys):
        """Parameter i's limit in keys, for a message (allocates: refusals only)."""
        b = self._scratch
        copy4(self._k, 0, keys, 4 * i)
        t = self._types[i]
        unkey(t, self._k, b)
        if t != REAL32:
            return get_int(b, 0, t)
        return "%g" % struct.unpack_from("<f", b, 0)[0]

    def adopt(self, values):
        """Take a whole set of checked values -> how many changed; self._mark[i] is 1
        for those."""
        n = 0
        for i in range(self.count):
            c = self._adopt(i, values)
            self._mark[i] = c
            n += c
        return n

    def _adopt(self, i, values):
        vo = 4 * i
        if not self.c_cast and cmp4(values, vo, self._values, vo) == 0:
            return 0
        self._key(i, values, vo, False)
        self._store(i)
        return 1 if self.changed else 0

    # --- for the application ---------------------------------------------------------
    def index(self, name):
        """Index of a parameter by name (look it up once); KeyError if not declared."""
        raw = name.encode()
        i = self.find(raw, 0, len(raw))
        if i < 0:
            raise KeyError(name)
        return i

    def name(self, i):
        o = ID_LEN * i
        return bytes(self._names[o : o + self._lens[i]]).decode()

    def type(self, i):
        return self._types[i]

    def flags(self, i):
        return self._flags[i]

    def value(self, i):
        """Parameter i's value, an int or a float (made for the caller: it may allocate)."""
        t = self._types[i]
        if t == REAL32:
            return struct.unpack_from("<f", self._values, 4 * i)[0]
        return get_int(self._values, 4 * i, t)

    def get(self, name):
        return self.value(self.index(name))

    def put(self, i, value):
        """Parameter i := value (read-only ones too) -> changed; ValueError if it may not."""
        b = self._scratch  # read into self._k before anything is stored
        t = self._types[i]
        if t == REAL32:
            struct.pack_into("<f", b, 0, value)
        else:
            if value != int(value):
                raise ValueError("%s: not a whole number" % self.name(i))
            v = int(value)
            lo, hi = _INT_RANGE[t]
            if not lo <= v <= hi:
                raise ValueError("%s: %d does not fit its type" % (self.name(i), v))
            put_int(b, 0, t, v)
        why = self.accept(i, b, 0, False)
        if why is not None:
            raise ValueError("%s: %s" % (self.name(i), why))
        return self.changed

    # --- file image --------------------------------------------------------------------
    def pack(self, img=None, at=0):
        """The values as a file: header, (name, type, value) records, crc16. Written
        whole into img from at (a storage's memory: in place), else into one buffer (the
        same each time: send it before the next pack) -> img."""
        if img is None:
            img = self.image()
        _head(img, at, self.count)
        _seal(img, at, self._pack_all(img, at + _HEADER))
        return img

    def _pack_all(self, img, o):
        """The records into img from o -> where they end (small frames: docs/design.md)."""
        for i in range(self.count):
            o = self._pack(img, o, i)
        return o

    def image(self):
        """The file image's buffer, made on first use (a board that saves with the heap
        locked makes it at start-up, or writes its storage in place: store.py)."""
        if self._image is None:
            self._image = bytearray(self.size)
        return self._image

    def _pack(self, img, o, i):
        n = self._lens[i]
        img[o] = n
        move(img, o + 1, self._names, ID_LEN * i, n)
        o += 1 + n
        img[o] = self._types[i]
        copy4(img, o + 1, self._values, 4 * i)
        return o + 5

    def unpack(self, data, n=-1, at=0):
        """Values from a file image data[at:at+n] (n < 0: to the end of data) into
        self._loaded, defaults where it has none -> how many of its records no longer fit
        (type changed, out of range), or -1 if it is corrupt."""
        end = at + (len(data) - at if n < 0 else n) - 2
        if end < at + _HEADER or not _sound(data, at, end):
            return -1
        return self._records(data, at + _HEADER, end)

    def _records(self, data, o, end):
        self._reset_loaded()
        self._bad = 0
        n = u16(data, o - 2)  # the header's count
        while n and o >= 0:
            o = self._unpack(data, o, end)
            n -= 1
        return self._bad if o == end else -1

    def _reset_loaded(self):
        move(self._loaded, 0, self._defaults, 0, len(self._loaded))

    def _unpack(self, data, o, end):
        """Take the record at data[o:] -> where the next one starts, -1 if corrupt."""
        n = data[o] if o < end else 0
        if n == 0 or n > ID_LEN or o + 6 + n > end:
            return -1
        self._record(data, o + 1, n)
        return o + 6 + n

    def _record(self, data, o, n):
        """The value of a record whose name is data[o:o+n] (type and value follow)."""
        i = self.find(data, o, n)
        if i < 0:
            return
        o += n
        if data[o] == self._types[i] and self.valid(i, data, o + 1):
            copy4(self._loaded, 4 * i, data, o + 1)
        else:
            self._bad += 1


def _head(img, at, count):
    move(img, at, _MAGIC, 0, 4)
    img[at + 4] = _FILE_VERSION
    img[at + 5] = 0
    put16(img, at + 6, count)


def _seal(img, at, end):
    """The crc16 of img[at:end] after it."""
    put16(img, end, crc16(img, at, end, 0xFFFF))


def _sound(data, at, end):
    """data[at:end] is a file image whose crc16 follows it."""
    return _is_image(data, at) and crc16(data, at, end, 0xFFFF) == u16(data, end)


def _is_image(data, at):
    return (data[at] == _MAGIC[0] and data[at + 1] == _MAGIC[1] and data[at + 2] == _MAGIC[2]
            and data[at + 3] == _MAGIC[3] and data[at + 4] == _FILE_VERSION)
