"""Parameter protocol: ground stations list, read, set and store the vehicle's parameters.

A board (or application) declares its parameters once, as a tuple of rows:

    from mavstack.services.params import REAL32, INT32, UINT8, READ_ONLY, REBOOT
    PARAMS = (
        # name (<= 16 chars), MAV_PARAM_TYPE, default, min, max, flags  (min..flags optional)
        ("WP_SPEED", REAL32, 5.0, 0.5, 30.0),
        ("FS_GCS_ENABLE", UINT8, 1, 0, 2),
        ("SERIAL1_BAUD", INT32, 57600, 1200, 921600, REBOOT),
    )

Any 8/16/32-bit integer type and REAL32. param_value is a 4-byte field, so UINT64,
INT64 and REAL64 cannot travel and are refused at start-up. Integers travel bytewise
(MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE, what QGroundControl and MAVSDK expect
from a generic autopilot), with PARAM_ENCODING = "c_cast" converted to floats (what
MAVProxy and Mission Planner expect), or with "auto" each link as its ground station
assumes (see _heard_heartbeat). A PARAM_SET typed REAL32 for an integer parameter is
a float holding the value in any encoding; refusals also get PARAM_ERROR where the
dialect has it (MAVSDK's answer to a set or get that failed).

A list goes out at the link budget's RANK_FILL (link.py): whatever HEARTBEAT, the
answers to ground stations and the telemetry streams leave of the link, so they keep
flowing and the list takes the rest. A list asked for again while it is going out
continues (every value still owed is sent once, wrapping to the start) rather than
starting over, so repeated requests, from one ground station or a flood of them,
cost one list. A read or a PARAM_SET is answered at once; if the budget cannot pay
for the answer then, it is owed ahead of the list and sent as soon as it can.
Lists, reads and their pacing allocate nothing. PARAM_SET is checked (type,
range, NaN, read-only, operator control) and always answered with the value in force;
a refusal also gets a STATUSTEXT saying why, a change is sent on every link.
Values persist in storage file "params" (param_store.py): MAV_CMD_PREFLIGHT_STORAGE
(param1 1 save, 0 reload, 2/4 defaults) or PARAM_AUTOSAVE_MS after the last change.

Lists, reads, accepted sets, saves and reloads allocate nothing, on 32-bit boards too
(no value of 2**30 or more is ever a Python int: see param_table.py); the file is
written from and read into one buffer made at start-up. Refusals and errors format
their STATUSTEXTs (they are rare); with the heap locked they say less, from a buffer,
and the answer still goes out.

Application side: `i = params.index("WP_SPEED")` once, then `params.value(i)`;
`params.get(name)`, `params.set(name, value)`; `params.on_change = f(name, value)`
hears changes made by ground stations, commands and reloads.
"""
from ...compat import const, ticks_diff
from ...fields import i16, cstr_len
from ...kernels import zero
from ...link import RANK_BULK, RANK_FILL, RANK_AUTO
from .table import ParamTable, ID_LEN
from .store import ParamStore, Guard, FILE
from .table import _copy4, _move, _put16  # byte moves whose frames fit the C stack
from .table import UINT8, INT8, UINT16, INT16, UINT32, INT32, REAL32, READ_ONLY, REBOOT  # noqa: F401
from .table import UINT64, INT64, REAL64  # noqa: F401  (declaring one is an error)

_MSG_HEARTBEAT = const(0)
_MSG_PARAM_REQUEST_READ = const(20)
_MSG_PARAM_REQUEST_LIST = const(21)
_MSG_PARAM_VALUE = const(22)
_MSG_PARAM_SET = const(23)
_MSG_REQUEST_DATA_STREAM = const(66)
_MSG_COMMAND_INT = const(75)
_MSG_COMMAND_LONG = const(76)
_MSG_PARAM_ERROR = const(345)
_PARAM_ERROR_LEN = const(21)

_CMD_REQUEST_AUTOPILOT_CAPABILITIES = const(520)
_MAV_TYPE_GCS = const(6)
_MAVPROXY_COMPID = const(230)  # MAVProxy's own component id (its source_component)

# _casts: a link's encoding ("auto": what its ground station was seen to assume)
_BYTEWISE = const(0)  # nothing heard yet
_CAST = const(1)
_TOLD = const(2)  # bytewise: it asked for AUTOPILOT_VERSION
_CMD_REQUEST_MESSAGE = const(512)

_CMD_DO_SET_PARAMETER = const(180)
_CMD_PREFLIGHT_STORAGE = const(245)

_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_UNSUPPORTED = const(3)
_RESULT_FAILED = const(4)

_SEVERITY_WARNING = const(4)
_SEVERITY_NOTICE = const(5)

_CAP_PARAM_ENCODE_BYTEWISE = const(16)
_CAP_PARAM_ENCODE_C_CAST = const(131072)

# MAV_PARAM_ERROR: what PARAM_ERROR tells the asker (as well as the value in force)
_ERR_DOES_NOT_EXIST = const(1)
_ERR_OUT_OF_RANGE = const(2)
_ERR_PERMISSION_DENIED = const(3)
_ERR_READ_ONLY = const(5)
_ERR_TYPE_MISMATCH = const(7)

# Pacing: the link's budget decides; a tick sends at most this many values a link.
_MAX_PER_TICK = const(8)
_VALUE_FRAME = const(37)  # bytes of a MAVLink 2 PARAM_VALUE (unsigned), asked of the budget
_OWED_LIST = const(1)  # _want: in a list, or a change to announce
_OWED_ANSWER = const(2)  # _want: an answer the budget held back: goes first

_AFTER_REBOOT = b" applies after reboot"
_UNKNOWN = b"unknown param "
_TEXT_LEN = const(50)  # STATUSTEXT's text field


class Params(ParamStore, ParamTable):
    NAME = "params"

    def __init__(self, table, encoding="bytewise", autosave_ms=0, sysid_param=None):
        if encoding not in ("bytewise", "c_cast", "auto"):
            raise ValueError("PARAM_ENCODING is 'bytewise', 'c_cast' or 'auto'")
        # "auto" keeps both forms of every value (the C-cast copy in self._wire) and
        # answers each link in the encoding its ground station assumes (_heard_*).
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
        self._casts = bytearray()  # per link: 1 when its PARAM_VALUEs travel C-cast
        self._error = 0  # the MAV_PARAM_ERROR of the refusal being answered
        self._text = bytearray(_TEXT_LEN)  # "NAME applies after reboot", made in place
        self._data = self._image  # what _load read the file into
        self._guard = Guard()

    def attach(self, ep):
        self.ep = ep
        ep.on(_MSG_PARAM_REQUEST_LIST, self._on_list)
        ep.on(_MSG_PARAM_REQUEST_READ, self._on_read)
        ep.on(_MSG_PARAM_SET, self._on_set)
        # "auto" tells the ground stations that ask (MAVSDK, QGroundControl) bytewise,
        # and answers them so (_heard_command).
        cast = self.c_cast and not self.auto
        ep.capabilities |= _CAP_PARAM_ENCODE_C_CAST if cast else _CAP_PARAM_ENCODE_BYTEWISE
        self._errors = ep.has(_MSG_PARAM_ERROR)  # not in the seed's dialect
        if self.auto:
            ep.on(_MSG_HEARTBEAT, self._heard_heartbeat)
            ep.on(_MSG_REQUEST_DATA_STREAM, self._heard_streams)
            ep.on(_MSG_COMMAND_LONG, self._heard_command)
            ep.on(_MSG_COMMAND_INT, self._heard_command)
        ep.commands[_CMD_DO_SET_PARAMETER] = self._do_set_parameter
        # A service attached later that also answers PREFLIGHT_STORAGE (missions: param2)
        # wraps this entry the same way.
        self._storage_next = ep.commands.get(_CMD_PREFLIGHT_STORAGE)
        ep.commands[_CMD_PREFLIGHT_STORAGE] = self._preflight_storage
        for link in ep.links:
            self._link_state(link)
        self._load(True)
        if getattr(ep, "storage", None) is not None:
            ep.storage.reserve(FILE, len(self._image))  # the first save allocates nothing
        if self.sysid_param:
            self.put(self.index(self.sysid_param), ep.sysid)

    def _link_state(self, link):
        while len(self._want) <= link.index:
            self._want.append(bytearray(self.count))
            self._pending.append(0)
            self._answers.append(0)
            self._cursor.append(0)
            self._casts.append(_CAST if self.c_cast and not self.auto else _BYTEWISE)

    # --- sending, paced ------------------------------------------------------------
    def tick(self, now):
        links = self.ep.links
        for li in range(len(self._pending)):  # a link's index is its place in ep.links
            if self._pending[li]:
                self._pace(li, links[li], now)
        if self.dirty and self.autosave_ms and ticks_diff(now, self._changed_at) >= self.autosave_ms:
            self.save()

    # (Small functions: MicroPython puts a frame with many locals on the heap.)
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
        if not link.can_send(_VALUE_FRAME, rank):
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
        self._fill(link.txbuf, link.begin(), i, self._casts[link.index])
        return link.send(_MSG_PARAM_VALUE)

    def _fill(self, buf, off, i, cast):
        _copy4(buf, off, self._wire if cast == _CAST else self._values, 4 * i)
        _put16(buf, off + 4, self.count)
        _put16(buf, off + 6, i)
        _move(buf, off + 8, self._names, ID_LEN * i, ID_LEN)
        buf[off + 24] = self._types[i]

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
        """Owe parameter i to every link but skip, paced like a list."""
        links = self.ep.links
        for li in range(len(links)):
            if links[li] is not skip:
                self._owe(links[li], i)

    def _owe(self, link, i):
        self._link_state(link)
        want = self._want[link.index]
        if not want[i]:
            want[i] = 1
            self._pending[link.index] += 1

    # --- protocol --------------------------------------------------------------------
    def _on_list(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        self._link_state(link)
        li = link.index
        if not self._pending[li]:
            self._cursor[li] = 0  # a new list; one going out continues (see the note)
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
            i = self._by_name(p, 4)
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
        i = self._by_name(p, 6)
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

    # (Small functions: past about 11 words of locals and stack MicroPython takes a
    # frame from the heap.)
    def _try_set(self, link, i, p):
        """Take PARAM_SET p into parameter i -> None, else why not (self._error: the
        MAV_PARAM_ERROR)."""
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

    def _by_name(self, p, o):
        return self.find(p, o, cstr_len(p, o, ID_LEN))

    def _may_set(self, link, i, p):
        """None if PARAM_SET p may change parameter i, else why not."""
        why = self._may_change(link, i)
        if why is None and p[22] != self._types[i] and p[22] != REAL32:
            # Another integer type: its bytes would be misread.
            self._error = _ERR_TYPE_MISMATCH
            why = _type_why(p[22], self._types[i])
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

    def _cast_in(self, link, i, p):
        """Whether PARAM_SET p holds parameter i's value as a float (C-cast) rather than
        in its type's bytes. Typed REAL32 for an integer parameter it does: the sender
        declared a float (MAVProxy, pymavlink's param_set_send), and under "auto" its
        link is answered C-cast from then on. Typed as the parameter, the link's
        encoding says (REAL32 parameters read as floats either way)."""
        self._link_state(link)
        if p[22] != REAL32 or self._types[i] == REAL32:
            return self._casts[link.index] == _CAST
        if self.auto:
            self._casts[link.index] = _CAST
        return True

    # --- which encoding a link's ground station assumes ("auto") ----------------------
    # Ground stations do not read the capability bits to decode integers: MAVSDK and
    # QGroundControl go bytewise for any autopilot but ArduPilot, MAVProxy and pymavlink's
    # mavparm C-cast for any but PX4. What a station does tells them apart, and the last
    # sign heard on a link decides: asking for AUTOPILOT_VERSION (MAVSDK, QGroundControl:
    # told bytewise), REQUEST_DATA_STREAM (ArduPilot's convention: MAVProxy, Mission
    # Planner) or a PARAM_SET typed REAL32 for an integer parameter (C-cast). Before any
    # of these, a ground station heartbeat from MAVProxy's component id makes the link
    # C-cast (MAVProxy lists parameters before it sends anything else); otherwise it is
    # bytewise until one is heard.
    def _heard_heartbeat(self, link, p):
        if p[4] == _MAV_TYPE_GCS and link.rx.compid == _MAVPROXY_COMPID:
            self._link_state(link)
            if self._casts[link.index] == _BYTEWISE:
                self._casts[link.index] = _CAST

    def _heard_streams(self, link, p):
        if self.ep.for_us(p[2], p[3]):
            self._link_state(link)
            self._casts[link.index] = _CAST

    def _heard_command(self, link, p):
        """COMMAND_LONG / COMMAND_INT (command at 28, param1 at 0): a request for
        AUTOPILOT_VERSION (REQUEST_MESSAGE 148, REQUEST_AUTOPILOT_CAPABILITIES)."""
        c = p[29] << 8 | p[28]
        if c == _CMD_REQUEST_AUTOPILOT_CAPABILITIES or (c == _CMD_REQUEST_MESSAGE and _is_148(p)):
            if self.ep.for_us(p[30], p[31]):
                self._link_state(link)
                self._casts[link.index] = _TOLD

    def _deny(self, link, p, o, i):
        """PARAM_ERROR self._error to the asker on link (where the dialect has it): the
        name as sent at p[o:], index i (-1: asked by name). Made in place, in frames
        small enough for the C stack: a refusal costs no heap."""
        if self._errors:
            d = self._error_head(link, i)
            _name_into(link.txbuf, d, p, o)
            link.send(_MSG_PARAM_ERROR)

    def _error_head(self, link, i):
        """PARAM_ERROR's fields but the name: index, target (the asker), error."""
        buf = link.txbuf
        d = link.begin()
        _put16(buf, d, i & 0xFFFF)
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

    # Refusals and errors: a STATUSTEXT each. Formatting allocates; where the heap may be
    # locked (the emulated boards run so), a MemoryError there gets a plainer text made
    # in self._text instead, so the vehicle carries on and the refusal is still answered.
    def _unknown(self, p, o):
        # Made in the text buffer (and in small frames: past about 11 words of locals
        # and stack MicroPython takes a frame from the heap), so a ground station asking
        # for names this vehicle lacks costs it no heap.
        text = self._text
        _move(text, 0, _UNKNOWN, 0, len(_UNKNOWN))
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

    def _say(self, severity, fmt, arg, plain):
        """STATUSTEXT fmt % arg, or plain (bytes) if that cannot be made."""
        try:
            text = fmt % arg
        except MemoryError:
            text = plain
        self.ep.statustext(severity, text)

    def _changed_by_gcs(self, i):
        if not self.changed:
            return
        self._touch()
        if self._flags[i] & REBOOT:
            self.ep.statustext(_SEVERITY_NOTICE, self._named_text(i, _AFTER_REBOOT))
        if self.on_change is not None:
            self.on_change(self.name(i), self.value(i))

    def _named_text(self, i, tail):
        """Parameter i's name and tail, as a STATUSTEXT made in a buffer (NUL-padded)."""
        n = self._lens[i]
        _move(self._text, 0, self._names, ID_LEN * i, n)
        _move(self._text, n, tail, 0, len(tail))
        zero(self._text, n + len(tail), _TEXT_LEN)
        return self._text

    def _touch(self):
        self.dirty = True
        self._changed_at = self.ep.now

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

    # --- application -----------------------------------------------------------------
    def set(self, name, value):
        """Set from the application (read-only ones too); sent on every link.

        True if the value changed; ValueError when it may not take that value.
        """
        i = self.index(name)
        if self.put(i, value) and self.ep is not None:
            self._touch()
            self._announce(i)
        return self.changed


def _shown(dst, d, p, o):
    """The NUL-padded name at p[o] into dst from d, '?' for what cannot be shown -> the
    end of it in dst."""
    n = cstr_len(p, o, ID_LEN)
    k = 0
    while k < n:
        c = p[o + k]
        dst[d + k] = c if 0x20 < c < 0x7F else 0x3F
        k += 1
    return d + n


def _is_148(p):
    """param1 (p[0:4]) is 148.0, AUTOPILOT_VERSION's id, as a float."""
    return p[0] == 0 and p[1] == 0 and p[2] == 0x14 and p[3] == 0x43


def _name_into(buf, d, p, o):
    _move(buf, d, p, o, ID_LEN)


def _type_why(got, want):
    try:
        return "type %d, expected %d" % (got, want)
    except MemoryError:  # the heap is locked
        return "wrong type"


def create(ep):
    params = Params(
        getattr(getattr(ep, "board", None), "PARAMS", ()),
        ep.setting("PARAM_ENCODING", "bytewise"),
        ep.setting("PARAM_AUTOSAVE_MS", 0),
        ep.setting("PARAM_SYSID"),
    )
    return ep.add(params)
