"""The parameter service: ground stations list, read, set and store the vehicle's parameters.

A board declares its table once (PARAMS: rows of name, type, default, min, max, flags);
this answers PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET, and
MAV_CMD_DO_SET_PARAMETER. A list goes out at what the link's budget leaves (link.py's
RANK_FILL) and continues when asked again; a read or a set is answered at once, or owed
ahead of the list. A set is checked and always answered with the value in force; a
refusal also gets PARAM_ERROR and a STATUSTEXT, a change goes out on every link. Each
link's integers travel in the encoding its ground station reads (PARAM_ENCODING; "auto"
asks the status service which conventions each link's station assumes).
Lists, reads, accepted sets, saves and reloads allocate nothing.

Parts: table.py (the table), encoding.py (how values travel, per link), store.py (storage).
Application side: params.index(name) once, then params.value(i); get, set, on_change.
Reference: docs/services/params.md
"""
from ...compat import const
from ...fields import i16, cstr_len
from ...kernels import zero
from ...link import RANK_BULK, RANK_FILL, RANK_AUTO
from .encoding import LinkEncodings, move, put16
from .table import ParamTable, ID_LEN, READ_ONLY, REBOOT
from .table import UINT8, INT8, UINT16, INT16, UINT32, INT32, REAL32  # noqa: F401
from .table import UINT64, INT64, REAL64  # noqa: F401  (declaring one is an error)
from .store import ParamStore, Guard, VALUE_FRAME

AFTER = ("status",)  # "auto": the conventions each link's ground station assumes

_MSG_PARAM_REQUEST_READ = const(20)
_MSG_PARAM_REQUEST_LIST = const(21)
_MSG_PARAM_VALUE = const(22)
_MSG_PARAM_SET = const(23)
_MSG_PARAM_ERROR = const(345)

_CMD_DO_SET_PARAMETER = const(180)
_CMD_PREFLIGHT_STORAGE = const(245)

_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)

_SEVERITY_WARNING = const(4)
_SEVERITY_NOTICE = const(5)

# MAV_PARAM_ERROR: what PARAM_ERROR tells the asker (as well as the value in force)
_ERR_DOES_NOT_EXIST = const(1)
_ERR_OUT_OF_RANGE = const(2)
_ERR_PERMISSION_DENIED = const(3)
_ERR_READ_ONLY = const(5)
_ERR_TYPE_MISMATCH = const(7)

# Pacing: the link's budget decides; a tick sends at most this many values a link.
_MAX_PER_TICK = const(8)
_OWED_LIST = const(1)  # _want: in a list, or a change to announce
_OWED_ANSWER = const(2)  # _want: an answer the budget held back: goes first

_AFTER_REBOOT = b" applies after reboot"
_UNKNOWN = b"unknown param "
_TEXT_LEN = const(50)  # STATUSTEXT's text field


class Params(ParamStore, LinkEncodings, ParamTable):
    NAME = "params"

    def __init__(self, table, encoding="bytewise", autosave_ms=0, sysid_param=None):
        if encoding not in ("bytewise", "c_cast", "auto"):
            raise ValueError("PARAM_ENCODING is 'bytewise', 'c_cast' or 'auto'")
        # "auto" keeps both forms of every value (the C-cast copy in self._wire).
        ParamTable.__init__(self, table, encoding != "bytewise")
        self.auto = encoding == "auto"
        self.autosave_ms = autosave_ms
        self.sysid_param = sysid_param
        self.on_change = None  # on_change(name, value)
        self.dirty = False  # changed since the last save or load
        self._changed_at = 0
        self.ep = None
        # Per link: the PARAM_VALUEs it is owed (a byte a parameter: _OWED_LIST or
        # _OWED_ANSWER), how many, how many of them answers, where the list resumes.
        self._want = []
        self._pending = []
        self._answers = []
        self._cursor = []
        self.conventions = None  # the status service's (LinkEncodings)
        self._error = 0  # the MAV_PARAM_ERROR of the refusal being answered
        self._text = bytearray(_TEXT_LEN)  # "NAME applies after reboot", made in place
        self._data = None  # what _load read the file into (or storage's memory, from _at)
        self._at = 0
        self._guard = Guard()

    def attach(self, ep):
        self.ep = ep
        ep.on(_MSG_PARAM_REQUEST_LIST, self._on_list)
        ep.on(_MSG_PARAM_REQUEST_READ, self._on_read)
        ep.on(_MSG_PARAM_SET, self._on_set)
        self._watch(ep)
        self._errors = ep.has(_MSG_PARAM_ERROR)  # not in the seed's dialect
        ep.commands[_CMD_DO_SET_PARAMETER] = self._do_set_parameter
        # A service attached later that also answers PREFLIGHT_STORAGE (missions: param2)
        # wraps this entry the same way.
        self._storage_next = ep.commands.get(_CMD_PREFLIGHT_STORAGE)
        ep.commands[_CMD_PREFLIGHT_STORAGE] = self._preflight_storage
        for link in ep.links:
            self._link_state(link)
        self._attach_storage(getattr(ep, "storage", None))
        if self.sysid_param:
            self.put(self.index(self.sysid_param), ep.sysid)

    def _link_state(self, link):
        while len(self._want) <= link.index:
            self._want.append(bytearray(self.count))
            self._pending.append(0)
            self._answers.append(0)
            self._cursor.append(0)

    # --- sending, paced ------------------------------------------------------------
    def tick(self, now):
        links = self.ep.links
        for li in range(len(self._pending)):  # a link's index is its place in ep.links
            if self._pending[li]:
                self._pace(li, links[li], now)
        return self._autosave(now) if self.dirty else self._wait(now)

    def _pace(self, li, link, now):
        sent = 0
        while sent < _MAX_PER_TICK and self._pending[li]:
            if not self._send_next(li, link):
                break  # the budget (or the transport) cannot take it now: a later tick
            sent += 1

    def _send_next(self, li, link):
        """Send the next value link li is owed, if its budget pays for it -> sent."""
        answer = self._answers[li] != 0
        # Held-back answers level with the streams: never into the reserve a flood of
        # reads could otherwise take from other ground stations' answers.
        rank = RANK_BULK if answer else RANK_FILL
        if not link.can_send(VALUE_FRAME, rank):
            return False
        i = self._owed(li, answer)
        link.rank = rank
        ok = self._send(link, i)
        link.rank = RANK_AUTO
        if not ok:
            return False
        if self._want[li][i] == _OWED_ANSWER:
            self._answers[li] -= 1
        self._want[li][i] = 0
        self._pending[li] -= 1
        if not answer:
            self._cursor[li] = i + 1
        return True

    def _owed(self, li, answer):
        """The next index link li is owed: an answer (from the start), else the list's
        next at or after its cursor, wrapping (a list goes in order)."""
        want = self._want[li]
        n = self.count
        i = 0 if answer else self._cursor[li]
        k = n
        while k:
            if i >= n:
                i = 0
            if want[i] == _OWED_ANSWER or (want[i] and not answer):
                break
            i += 1
            k -= 1
        return i

    def _send(self, link, i):
        """One PARAM_VALUE for parameter i, copied straight from the table."""
        self._fill(link.txbuf, link.begin(), i, self.cast_link(link))
        return link.send(_MSG_PARAM_VALUE)

    def _reply(self, link, i):
        """Answer at once (ranked by its asker: link.py); owed, ahead of any list, when
        the budget cannot pay for it now."""
        self._link_state(link)
        if self._send(link, i):
            return
        want = self._want[link.index]
        if want[i] != _OWED_ANSWER:
            if not want[i]:
                self._pending[link.index] += 1
            want[i] = _OWED_ANSWER
            self._answers[link.index] += 1

    def _announce(self, i, skip=None):
        """Owe parameter i to every link but skip that has heard anyone, paced like a list.
        (A station that comes later lists them, in the encoding it shows by then: one
        told first, before it could show it, might keep a value misread.)"""
        links = self.ep.links
        for li in range(len(links)):
            if links[li] is not skip and links[li].rx.frames:
                self._owe(links[li], i)

    def _owe(self, link, i):
        self._link_state(link)
        want = self._want[link.index]
        if not want[i]:
            want[i] = 1
            self._pending[link.index] += 1
            self.ep.wake(self)

    # --- protocol --------------------------------------------------------------------
    def _on_list(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        self._link_state(link)
        li = link.index
        if not self._pending[li]:
            self._cursor[li] = 0  # a new list; one going out continues
        want = self._want[li]
        for i in range(self.count):
            if not want[i]:
                want[i] = _OWED_LIST
        self._pending[li] = self.count

    def _on_read(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        i = i16(p, 0)
        if i < 0:  # -1: by name
            i = self.find_id(p, 4)
            if i < 0:
                self._unknown(p, 4)
                self._error = _ERR_DOES_NOT_EXIST
                self._deny(link, p, 4, -1)
                return
        elif i >= self.count:
            self.ep.statustext(_SEVERITY_WARNING, b"param index unknown")
            self._error = _ERR_DOES_NOT_EXIST
            self._deny(link, p, 4, i)
            return
        self._reply(link, i)

    def _on_set(self, link, p):
        if not self.ep.for_us(p[4], p[5]):
            return
        i = self.find_id(p, 6)
        if i < 0:
            self._unknown(p, 6)
            self._error = _ERR_DOES_NOT_EXIST
            self._deny(link, p, 6, -1)
            return
        why = self._try_set(link, i, p)
        if why is not None:
            self._refuse(link, p, i, why)
            return
        self._reply(link, i)
        self._announce(i, link)
        self._changed_by_gcs(i)

    def _try_set(self, link, i, p):
        """Take PARAM_SET p into parameter i -> None, else why not (and self._error)."""
        why = self._may_set(link, i, p)
        if why is None:
            why = self._accept_set(link, i, p)
        return why

    def _accept_set(self, link, i, p):
        self._error = _ERR_OUT_OF_RANGE  # if refused: NaN, a fraction, out of range
        c = self._cast_in(link, i, p)
        return self.accept(i, p, 0, c)

    def _refuse(self, link, p, i, why):
        self._deny(link, p, 6, i)  # first: MAVSDK takes it as the answer
        self._reply(link, i)  # then the value in force, for everyone else
        self._refused(i, why)

    def _may_set(self, link, i, p):
        """None if PARAM_SET p may change parameter i, else why not."""
        why = self._may_change(link, i)
        if why is None:
            why = self._type_refused(link, i, p)
            if why is not None:
                self._error = _ERR_TYPE_MISMATCH
        return why

    def _may_change(self, link, i):
        """None if a ground station on link may change parameter i, else why not."""
        if not self.ep.allows(link):
            self._error = _ERR_PERMISSION_DENIED
            return "not in control"
        if self._flags[i] & READ_ONLY:
            self._error = _ERR_READ_ONLY
            return "read-only"
        return None

    def _deny(self, link, p, o, i):
        """PARAM_ERROR self._error to the asker on link (where the dialect has it): the
        name as sent at p[o:], index i (-1: asked by name). Made in place: no heap."""
        if self._errors:
            d = self._error_head(link, i)
            _name_into(link.txbuf, d, p, o)
            link.send(_MSG_PARAM_ERROR)

    def _error_head(self, link, i):
        """PARAM_ERROR's fields but the name: index, target (the asker), error."""
        buf = link.txbuf
        d = link.begin()
        put16(buf, d, i & 0xFFFF)
        buf[d + 2] = link.rx.sysid
        buf[d + 3] = link.rx.compid
        buf[d + 20] = self._error
        return d + 4

    def _do_set_parameter(self, cmd):
        """MAV_CMD_DO_SET_PARAMETER: param1 the parameter's index, param2 its value."""
        if cmd.nan(1):
            return _RESULT_DENIED
        i = cmd.int(1)
        if not 0 <= i < self.count:
            self._index_unknown(i)
            return _RESULT_DENIED
        why = self._may_change(cmd.link, i)
        if why is None:
            # Command parameters are floats holding the value itself; param2 is at byte 4.
            why = self.accept(i, cmd.payload, 4, True)
        if why is not None:
            self._refused(i, why)
            return _RESULT_DENIED
        self._announce(i)
        self._changed_by_gcs(i)
        return _RESULT_ACCEPTED

    # Refusals and errors: a STATUSTEXT each, formatted (it allocates) or, where the heap
    # is locked, a plainer text made in self._text: the refusal is still answered.
    def _unknown(self, p, o):
        text = self._text  # made here: names this vehicle lacks cost it no heap
        move(text, 0, _UNKNOWN, 0, len(_UNKNOWN))
        zero(text, _shown(text, len(_UNKNOWN), p, o), _TEXT_LEN)
        self.ep.statustext(_SEVERITY_WARNING, text)

    def _index_unknown(self, i):
        try:
            text = "param index %d unknown (%d params)" % (i, self.count)
        except MemoryError:
            text = b"param index unknown"
        self.ep.statustext(_SEVERITY_WARNING, text)

    def _refused(self, i, why):
        try:
            text = "%s not set: %s" % (self.name(i), why)
        except MemoryError:
            text = self._named_text(i, b" not set")
        self.ep.statustext(_SEVERITY_WARNING, text)

    def _changed_by_gcs(self, i):
        if not self.changed:
            return
        self._touch()
        if self._flags[i] & REBOOT:
            self.ep.statustext(_SEVERITY_NOTICE, self._named_text(i, _AFTER_REBOOT))
        if self.on_change is not None:
            self._tell(i)  # (store.py)

    def _named_text(self, i, tail):
        """Parameter i's name and tail, as a STATUSTEXT made in a buffer (NUL-padded)."""
        n = self._lens[i]
        move(self._text, 0, self._names, ID_LEN * i, n)
        move(self._text, n, tail, 0, len(tail))
        zero(self._text, n + len(tail), _TEXT_LEN)
        return self._text

    # --- application -----------------------------------------------------------------
    def set(self, name, value):
        """Set from the application (read-only ones too); sent on every link -> changed.
        ValueError when it may not take that value."""
        i = self.index(name)
        if self.put(i, value) and self.ep is not None:
            self._touch()
            self._announce(i)
        return self.changed


def _shown(dst, d, p, o):
    """The name at p[o] into dst from d, '?' for what cannot be shown -> its end in dst."""
    n = cstr_len(p, o, ID_LEN)
    k = 0
    while k < n:
        c = p[o + k]
        dst[d + k] = c if 0x20 < c < 0x7F else 0x3F
        k += 1
    return d + n


def _name_into(buf, d, p, o):
    move(buf, d, p, o, ID_LEN)


def create(ep):
    params = Params(
        getattr(getattr(ep, "board", None), "PARAMS", ()),
        ep.setting("PARAM_ENCODING", "bytewise"),
        ep.setting("PARAM_AUTOSAVE_MS", 0),
        ep.setting("PARAM_SYSID"),
    )
    return ep.add(params)
