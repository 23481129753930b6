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
from a generic autopilot) or, with PARAM_ENCODING = "c_cast", converted to floats.

A list goes out paced to half the link's capacity, so telemetry and commands keep
flowing; lists, reads and their pacing allocate nothing. PARAM_SET is checked (type,
range, NaN, read-only, operator control) and always answered with the value in force;
a refusal also gets a STATUSTEXT saying why, a change is sent on every link.
Values persist in storage file "params": MAV_CMD_PREFLIGHT_STORAGE (param1 1 save,
0 reload, 2/4 defaults) or PARAM_AUTOSAVE_MS after the last change.

Application side: `i = params.index("WP_SPEED")` once, then `params.value(i)`;
`params.get(name)`, `params.set(name, value)`; `params.on_change = f(name, value)`
hears changes made by ground stations, commands and reloads.
"""
import struct

from ..compat import const, ticks_diff
from ..fields import i16, cstr_len
from ..kernels import copy
from .param_table import ParamTable, ID_LEN
from .param_table import UINT8, INT8, UINT16, INT16, UINT32, INT32, REAL32, READ_ONLY, REBOOT  # noqa: F401
from .param_table import UINT64, INT64, REAL64  # noqa: F401  (declaring one is an error)

_MSG_PARAM_REQUEST_READ = const(20)
_MSG_PARAM_REQUEST_LIST = const(21)
_MSG_PARAM_VALUE = const(22)
_MSG_PARAM_SET = const(23)

_CMD_DO_SET_PARAMETER = const(180)
_CMD_PREFLIGHT_STORAGE = const(245)

_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_UNSUPPORTED = const(3)
_RESULT_FAILED = const(4)

_SEVERITY_ERROR = const(3)
_SEVERITY_WARNING = const(4)
_SEVERITY_NOTICE = const(5)
_SEVERITY_INFO = const(6)

_CAP_PARAM_ENCODE_BYTEWISE = const(16)
_CAP_PARAM_ENCODE_C_CAST = const(131072)

# Pacing: credit in thousandths of a byte; a link earns bytes_per_s / 2 of them a ms.
_BURST = const(128000)  # at most ~3 frames banked
_MAX_DT_MS = const(100)
_MAX_PER_TICK = const(4)

_FILE = "params"


class Params(ParamTable):
    NAME = "params"

    def __init__(self, table, encoding="bytewise", autosave_ms=0, sysid_param=None):
        if encoding not in ("bytewise", "c_cast"):
            raise ValueError("PARAM_ENCODING is 'bytewise' or 'c_cast'")
        super().__init__(table, encoding == "c_cast")
        self.autosave_ms = autosave_ms
        self.sysid_param = sysid_param
        self.on_change = None  # on_change(name, value)
        self.dirty = False  # changed since the last save or load
        self._changed_at = 0
        self.ep = None
        # Per link: the PARAM_VALUEs it is owed (a byte a parameter), how many, where
        # the scan resumes, its pacing credit and when that was last earned.
        self._want = []
        self._pending = []
        self._cursor = []
        self._credit = []
        self._last = []

    def attach(self, ep):
        self.ep = ep
        ep.on(_MSG_PARAM_REQUEST_LIST, self._on_list)
        ep.on(_MSG_PARAM_REQUEST_READ, self._on_read)
        ep.on(_MSG_PARAM_SET, self._on_set)
        ep.capabilities |= _CAP_PARAM_ENCODE_C_CAST if self.c_cast else _CAP_PARAM_ENCODE_BYTEWISE
        ep.commands[_CMD_DO_SET_PARAMETER] = self._do_set_parameter
        # A service attached later that also answers PREFLIGHT_STORAGE (missions: param2)
        # wraps this entry the same way.
        self._storage_next = ep.commands.get(_CMD_PREFLIGHT_STORAGE)
        ep.commands[_CMD_PREFLIGHT_STORAGE] = self._preflight_storage
        for link in ep.links:
            self._link_state(link)
        self._load(True)
        if self.sysid_param:
            self.put(self.index(self.sysid_param), ep.sysid)

    def _link_state(self, link):
        while len(self._want) <= link.index:
            self._want.append(bytearray(self.count))
            self._pending.append(0)
            self._cursor.append(0)
            self._credit.append(_BURST)
            self._last.append(self.ep.now)

    # --- sending, paced ------------------------------------------------------------
    def tick(self, now):
        for link in self.ep.links:
            li = link.index
            if li < len(self._pending) and self._pending[li]:
                self._pace(li, link, now)
        if self.dirty and self.autosave_ms and ticks_diff(now, self._changed_at) >= self.autosave_ms:
            self.save()

    def _pace(self, li, link, now):
        dt = ticks_diff(now, self._last[li])
        self._last[li] = now
        rate = link.bytes_per_s >> 1 if link.bytes_per_s else 0
        credit = self._credit[li]
        if rate == 0:
            credit = _BURST
        elif dt > 0:
            credit += (dt if dt < _MAX_DT_MS else _MAX_DT_MS) * rate
            if credit > _BURST:
                credit = _BURST
        want = self._want[li]
        n = self.count
        i = self._cursor[li]
        sent = 0
        while credit > 0 and sent < _MAX_PER_TICK and self._pending[li]:
            # The next owed index at or after the cursor, wrapping: a list goes in order.
            for _ in range(n):
                if i >= n:
                    i = 0
                if want[i]:
                    break
                i += 1
            before = link.tx_bytes
            if not self._send(link, i):
                break  # the transport is full: a later tick retries
            credit -= (link.tx_bytes - before) * 1000
            want[i] = 0
            self._pending[li] -= 1
            i += 1
            sent += 1
        self._cursor[li] = i
        self._credit[li] = credit

    def _send(self, link, i):
        """One PARAM_VALUE for parameter i, copied straight from the table."""
        off = link.begin()
        buf = link.txbuf
        copy(buf, self._wire, off | (4 * i) << 10, 4)
        struct.pack_into("<HH", buf, off + 4, self.count, i)
        copy(buf, self._names, (off + 8) | (ID_LEN * i) << 10, ID_LEN)
        buf[off + 24] = self._types[i]
        return link.send(_MSG_PARAM_VALUE)

    def _reply(self, link, i):
        """Send at once (an answer), charged to the link's pacing credit."""
        self._link_state(link)
        li = link.index
        before = link.tx_bytes
        self._send(link, i)
        credit = self._credit[li] - (link.tx_bytes - before) * 1000
        self._credit[li] = credit if credit > -_BURST else -_BURST

    def _announce(self, i, skip=None):
        """Owe parameter i to every link but skip, paced like a list."""
        for link in self.ep.links:
            if link is skip:
                continue
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
        want = self._want[li]
        for i in range(self.count):
            want[i] = 1
        self._pending[li] = self.count
        self._cursor[li] = 0  # a new request starts over

    def _on_read(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        i = i16(p, 0)
        if i < 0:  # -1: by name
            i = self.find(p, 4, cstr_len(p, 4, ID_LEN))
            if i < 0:
                self._unknown(p, 4)
                return
        elif i >= self.count:
            self.ep.statustext(_SEVERITY_WARNING, b"param index unknown")
            return
        self._reply(link, i)

    def _on_set(self, link, p):
        if not self.ep.for_us(p[4], p[5]):
            return
        i = self.find(p, 6, cstr_len(p, 6, ID_LEN))
        if i < 0:
            self._unknown(p, 6)
            return
        t = self._types[i]
        ptype = p[22]
        if not self.ep.allows(link):
            why = "not in control"
        elif self._flags[i] & READ_ONLY:
            why = "read-only"
        elif ptype != t and not (self.c_cast and ptype == REAL32):
            # Bytewise, the type says how to read the bytes: another one would misread them.
            why = "type %d, expected %d" % (ptype, t)
        else:
            why = self.accept(i, p, 0, self.c_cast or t == REAL32)
        self._reply(link, i)
        if why is not None:
            self._refused(i, why)
            return
        self._announce(i, link)
        self._changed_by_gcs(i)

    def _do_set_parameter(self, cmd):
        """MAV_CMD_DO_SET_PARAMETER: param1 the parameter's index, param2 its value."""
        if cmd.nan(1):
            return _RESULT_DENIED
        i = cmd.int(1)
        if not 0 <= i < self.count:
            self.ep.statustext(_SEVERITY_WARNING, "param index %d unknown (%d params)" % (i, self.count))
            return _RESULT_DENIED
        if not self.ep.allows(cmd.link):
            why = "not in control"
        elif self._flags[i] & READ_ONLY:
            why = "read-only"
        else:
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
        if action not in (0, 2, 4):
            # 3 resets sensor calibration only: there is none here.
            return _RESULT_UNSUPPORTED if action == 3 else _RESULT_DENIED
        if link is not None and not self.ep.allows(link):
            return _RESULT_DENIED
        if action == 0:
            return _RESULT_ACCEPTED if self._load(False) else _RESULT_FAILED
        self._take(self._defaults, False)
        self.ep.statustext(_SEVERITY_NOTICE, "params reset to defaults")
        return _RESULT_ACCEPTED

    def _unknown(self, p, o):
        text = bytearray(b"unknown param ")
        for k in range(cstr_len(p, o, ID_LEN)):
            c = p[o + k]
            text.append(c if 0x20 < c < 0x7F else 0x3F)  # '?' for what cannot be shown
        self.ep.statustext(_SEVERITY_WARNING, text)

    def _refused(self, i, why):
        self.ep.statustext(_SEVERITY_WARNING, "%s not set: %s" % (self.name(i), why))

    def _changed_by_gcs(self, i):
        if not self.changed:
            return
        self._touch()
        if self._flags[i] & REBOOT:
            self.ep.statustext(_SEVERITY_NOTICE, "%s applies after reboot" % self.name(i))
        if self.on_change is not None:
            self.on_change(self.name(i), self.value(i))

    def _touch(self):
        self.dirty = True
        self._changed_at = self.ep.now

    def _take(self, values, saved):
        """A whole set of values (reload, defaults): sent and reported where changed."""
        changed = self.adopt(values)
        for i in changed:
            self._announce(i)
        if changed and not saved:
            self._touch()
        if self.on_change is not None:
            for i in changed:
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

    # --- storage ---------------------------------------------------------------------
    def save(self):
        """Write every value to storage "params", atomically -> success."""
        storage = getattr(self.ep, "storage", None)
        if storage is None:
            return False
        try:
            f = storage.open_new(_FILE)
            try:
                f.write(self.pack())
            finally:
                f.close()
            storage.commit(_FILE)
        except OSError as e:
            self.ep.statustext(_SEVERITY_ERROR, "params not saved: %s" % e)
            return False
        self.dirty = False
        return True

    def _load(self, boot):
        """Read storage "params" -> success. At boot an unusable file means defaults;
        a reload keeps the values in force."""
        storage = getattr(self.ep, "storage", None)
        data = None
        why = "no storage"
        if storage is not None:
            if boot:
                storage.discard_new(_FILE)  # a save cut short: the old file stands
            try:
                f = storage.open(_FILE)
                try:
                    data = f.read()
                finally:
                    f.close()
            except OSError:
                why = "none stored"
        values, bad = (None, 0) if data is None else self.unpack(data)
        if values is None:
            if data is not None:
                why = "stored file corrupt"
            if boot:
                sev = _SEVERITY_INFO if data is None else _SEVERITY_WARNING
                self.ep.statustext(sev, "params: %s, using defaults" % why)
            else:
                self.ep.statustext(_SEVERITY_WARNING, "params not reloaded: %s" % why)
            return False
        if boot:
            self.adopt(values)
        else:
            self._take(values, True)
        self.dirty = False
        if bad:
            self.ep.statustext(_SEVERITY_NOTICE, "params: %d stored values invalid, defaults used" % bad)
        return True


def create(ep):
    params = Params(
        getattr(getattr(ep, "board", None), "PARAMS", ()),
        ep.setting("PARAM_ENCODING", "bytewise"),
        ep.setting("PARAM_AUTOSAVE_MS", 0),
        ep.setting("PARAM_SYSID"),
    )
    return ep.add(params)
