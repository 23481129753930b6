"""Flight modes: the board's mode table (FLIGHT_MODES), the number each ground station
reads a mode by (ArduPilot's or PX4's, per link: conventions.py), the ways ground stations
ask for a mode (SET_MODE, DO_SET_STANDARD_MODE; DO_SET_MODE comes through
vehicle_commands.py) and the mode state machine: a request is found in the table, vetted
by the application's hooks and applied to the status service's state (mode, custom_mode,
flight_mode, hil), then told to the application (on_flight_mode) before it is answered.
A board without a table keeps flag-only modes. AVAILABLE_MODES and CURRENT_MODE where the
dialect has them. Made by the status service (status.modes).
Reference: docs/services/status.md
"""
from struct import pack_into

from ...compat import const
from ...fields import u32
from ...statustext import CRITICAL

_NUMBER = const(0)
_NAME = const(1)
_FLAGS = const(2)

_UNKNOWN = const(0)  # conventions.py
_PX4 = const(2)
_PX4_MANUAL = const(1)  # PX4's MANUAL main mode: a multicopter's is stabilized
_PX4_STABILIZED = const(7)
_PX4_AUTO = const(4)  # AUTO needs a sub mode: the others stand alone
_PX4_LAST_MAIN = const(8)  # RATTITUDE, the last PX4 main mode a station may ask for
_FLAG_CHOICE = const(0x5C)  # MANUAL_INPUT | STABILIZE | GUIDED | AUTO: what picks a row
_NOT_USER_SELECTABLE = const(2)  # MAV_MODE_PROPERTY
_AUTO_OR_GUIDED = const(12)

_MSG_SET_MODE = const(11)
_MSG_AVAILABLE_MODES = const(435)
_MSG_CURRENT_MODE = const(436)
_CMD_DO_SET_STANDARD_MODE = const(262)
_CMD_REQUEST_MESSAGE = const(512)
_ACCEPTED = const(0)
_DENIED = const(2)
_UNSUPPORTED = const(3)
_WARNING = const(4)  # MAV_SEVERITY
# MAV_MODE_FLAG
_MODE_HIL = const(32)
_MODE_CUSTOM = const(1)
_FLAGS_DEFAULT = const(0x5D)  # MANUAL_INPUT | STABILIZE | GUIDED | AUTO | CUSTOM_MODE


class Modes:
    def __init__(self, table, numbering="auto", flags_supported=_FLAGS_DEFAULT):
        if numbering not in ("auto", "ardupilot", "px4"):
            raise ValueError("MODE_NUMBERING is 'auto', 'ardupilot' or 'px4'")
        self.numbering = numbering
        self.flags_supported = flags_supported  # the board's MODE_FLAGS
        self.set_table(table)
        self.row = -1  # the current mode's row in the table, -1: none (flag-only modes)
        self.intended = -1  # the row a ground station last asked for
        self.changed = False  # a new row since CURRENT_MODE was last announced
        self._index = 0  # AVAILABLE_MODES asked for: 0 all, else one (1-based)
        self._request = None  # the REQUEST_MESSAGE handler wrapped (wrap_request_message)
        self.status = None  # the status service, once attached

    def set_table(self, table):
        self.table = table
        # Per row, made once: the PX4 encoding (a small int: docs/design.md) and
        # the standard mode (0: none); 3-field rows (number, name, flags) have neither.
        self.px4 = [(r[3] << 16 | r[4] << 24) if len(r) > 4 else 0 for r in table]
        self.standard = bytes(r[5] if len(r) > 5 else 0 for r in table)

    def attach(self, ep, status):
        self.status = status
        ep.on(_MSG_SET_MODE, self._on_set_mode)
        if self.table:
            ep.commands[_CMD_DO_SET_STANDARD_MODE] = self._set_standard_mode
        if ep.has(_MSG_AVAILABLE_MODES):
            ep.producers[_MSG_AVAILABLE_MODES] = self.send_available_modes
        if ep.has(_MSG_CURRENT_MODE):
            ep.producers[_MSG_CURRENT_MODE] = self.send_current_mode

    def wrap_request_message(self):
        # Once all services are in: AVAILABLE_MODES needs REQUEST_MESSAGE's param2 (which
        # mode), so the built-in handler is wrapped to note it first.
        commands = self.status.ep.commands
        if _MSG_AVAILABLE_MODES in self.status.ep.producers and self._request is None:
            self._request = commands.get(_CMD_REQUEST_MESSAGE)
            if self._request is not None:
                commands[_CMD_REQUEST_MESSAGE] = self._request_message

    # --- numbering, per link ----------------------------------------------------------
    def px4_link(self, link):
        """Does link's ground station read and set modes PX4's way (MODE_NUMBERING)?"""
        if self.numbering == "auto":
            return self.status.conventions.of(link) == _PX4
        return self.numbering == "px4"

    def undecided(self, link):
        """Has link's ground station not shown yet which numbers it means ("auto")?"""
        return self.numbering == "auto" and self.status.conventions.of(link) == _UNKNOWN

    def either(self, number):
        """DO_SET_MODE's param2 from a station whose convention is not known yet (param3 0):
        an ArduPilot number, or a PX4 main mode that needs no sub mode -> the custom mode,
        or -1 when the two readings come to different modes (refused, and said why)."""
        if number < _PX4_MANUAL or number > _PX4_LAST_MAIN or number == _PX4_AUTO:
            return number
        if not max(self.px4, default=0):
            return number  # a table without PX4 encodings: no PX4 reading means anything here
        ardupilot = self.by_number(number)
        px4 = self._by_px4(number << 16)
        if ardupilot == px4:
            return number
        status = self.status
        status.reason = "ArduPilot or PX4 number?"
        try:
            text = "Mode %d: ArduPilot %s or PX4 %s? Refused" % (number, self._name(ardupilot), self._name(px4))
        except MemoryError:  # a board may lock its heap
            text = b"Mode: ArduPilot or PX4 number? Refused"
        status.statustext(_WARNING, text)
        return -1

    def _name(self, row):
        return self.table[row][_NAME] if row >= 0 else "(none)"

    def custom_for(self, link, row, number):
        """HEARTBEAT.custom_mode of mode `row` (-1: none) as this link reads it."""
        if row >= 0 and self.px4_link(link):
            return self.px4[row]
        return number

    # --- finding a row --------------------------------------------------------------
    def find(self, flags, custom):
        """-> the row a request comes to, -1 if none (and -2 where the board has no table:
        flag-only modes)."""
        table = self.table
        if not table:
            return -2
        if flags & 1 and (custom or not flags & _AUTO_OR_GUIDED):  # CUSTOM_MODE_ENABLED
            return self._by_px4(custom) if custom >= 0x10000 else self.by_number(custom)
        return self._by_flags(flags & _FLAG_CHOICE)

    def by_number(self, number):
        i = 0
        while i < len(self.table):
            if self.table[i][_NUMBER] == number:
                return i
            i += 1
        return -1

    def _by_px4(self, custom):
        if custom >> 16 & 0xFF == _PX4_MANUAL and not custom >> 24:
            custom = _PX4_STABILIZED << 16
        i = 0
        while i < len(self.px4):
            if self.px4[i] == custom:
                return i
            i += 1
        return -1

    def _by_flags(self, flags):
        # The row with just these flags, else the first with the weightiest one asked for.
        i = 0
        while i < len(self.table):
            if self.table[i][_FLAGS] & _FLAG_CHOICE == flags:
                return i
            i += 1
        bit = 4  # AUTO, GUIDED, STABILIZE, MANUAL_INPUT
        while bit <= 64:
            if flags & bit:
                i = 0
                while i < len(self.table):
                    if self.table[i][_FLAGS] & bit:
                        return i
                    i += 1
            bit <<= 1
        return self.by_number(0) if not flags else -1

    def by_name(self, name):
        i = 0
        while i < len(self.table):
            if self.table[i][_NAME] == name:
                return i
            i += 1
        return -1

    def by_standard(self, standard):
        i = 0
        while i < len(self.standard):
            if standard and self.standard[i] == standard:
                return i
            i += 1
        return -1

    # --- the mode state machine ------------------------------------------------------
    def set_mode(self, base_mode, custom_mode=0, link=None):
        """A ground station's request (status.set_mode; link: where it came from, if
        known) -> MAV_RESULT. (self.status throughout: few locals, docs/design.md)"""
        self.status.reason = None
        if base_mode & _MODE_HIL and not self.flags_supported & _MODE_HIL:
            self.status.reason = "HIL not supported"
            self.status.statustext(_WARNING, b"Mode: HIL not supported")
            return _DENIED
        row = self.find(base_mode & 0x5F, custom_mode)
        if row >= 0:
            result = self.enter(row, link or True)
        elif row == -1 or custom_mode:
            self.status.reason = "no such mode"  # a constant: a board may lock its heap
            self.status.statustext(_WARNING, b"Mode: no such mode")
            return _DENIED
        else:
            result = self._flag_mode(base_mode & 0x5E)
        if result == _ACCEPTED and bool(base_mode & _MODE_HIL) != self.status.hil:
            self._toggle_hil()
        return result

    def _toggle_hil(self):
        # HIL_ENABLED goes with any mode; the application blocks (or frees) its actuators.
        status = self.status
        status.hil = not status.hil
        status.update_state()
        if status.on_hil is not None:
            status.on_hil(status.hil)

    def _flag_mode(self, flags):
        # A board without a mode table: the flags alone.
        status = self.status
        if flags & ~self.flags_supported:
            status.reason = "mode flags not supported"  # constants: a board may lock its heap
            status.statustext(_WARNING, b"Mode: flags not supported")
            return _DENIED
        if status.mode_check is not None:
            result = veto(status, status.mode_check(flags, 0), b"Mode: ")
            if result != _ACCEPTED:
                return result
        status.mode = flags
        status.custom_mode = 0
        status.update_state()
        return _ACCEPTED

    def enter(self, row, asked):
        """Into mode `row` of the table. asked (True, or the link of the ground station
        that asked) goes through the vetoes and is told to the application
        (on_flight_mode) before it is answered; the application's own change
        (set_flight_mode, asked False) is neither."""
        if asked:
            result = self._vet(row)
            if result != _ACCEPTED:
                return result
            self.intended = row
            if asked is not True:
                self.status.conventions.took(asked)
        self._apply(row)
        if asked and self.status.on_flight_mode is not None:
            self.status.on_flight_mode(self.table[row][_NAME])
        return _ACCEPTED

    def _vet(self, row):
        status = self.status
        entry = self.table[row]
        flags = entry[_FLAGS] & 0x7E | _MODE_CUSTOM
        if flags & ~self.flags_supported:
            status.reason = "mode flags not supported"
            status.statustext(_WARNING, b"Mode: flags not supported")
            return _DENIED
        if status.mode_check is not None:
            answer = status.mode_check(flags, entry[_NUMBER])
            if answer is not None:
                return veto(status, answer, b"Mode: ")
        if status.flight_mode_check is not None:
            answer = status.flight_mode_check(entry[_NAME])
            if answer is not None:
                return veto(status, answer, b"Mode: ")
        return _ACCEPTED

    def _apply(self, row):
        entry = self.table[row]
        status = self.status
        if row != self.row:
            self.changed = True
            status.ep.wake()  # announced on the next pass
        status.mode = entry[_FLAGS] & 0x7E | _MODE_CUSTOM
        status.custom_mode = entry[_NUMBER]
        self.row = row
        status.flight_mode = entry[_NAME]
        status.update_state()

    def announce(self):
        # CURRENT_MODE after a change, where the dialect has it (a rare event).
        self.changed = False
        self.status.send_all(_MSG_CURRENT_MODE)

    # --- incoming ---------------------------------------------------------------------
    def _on_set_mode(self, link, p):
        if p[4] != self.status.ep.sysid:
            return
        if not self.status.ep.allows(link):
            self.status.statustext(_WARNING, b"Mode: GCS not in control")
            return
        # (a PX4 encoding taught the link: conventions.py). No mode is numbered 2^30 or
        # more (PX4's sub modes are small): such a number stays a small int, and no mode.
        self.set_mode(p[5], u32(p, 0) if p[3] < 0x40 else 0x3FFFFFFF, link)

    def _set_standard_mode(self, cmd):
        # param1: MAV_STANDARD_MODE. One the vehicle does not have is not supported.
        if not cmd.finite(1):
            return _DENIED
        row = self.by_standard(cmd.int(1))
        if row < 0:
            self.status.statustext(_WARNING, b"Mode: no such standard mode")
            return _UNSUPPORTED
        if not self.status.ep.allows(cmd.link):
            self.status.statustext(_WARNING, b"Mode: GCS not in control")
            return _DENIED
        return self.enter(row, cmd.link)

    def _request_message(self, cmd):
        self._index = 0
        if cmd.finite(1) and cmd.int(1) == _MSG_AVAILABLE_MODES and cmd.finite(2):
            self._index = cmd.int(2)
            if self._index < 0 or self._index > len(self.table):
                return _DENIED
        return self._request(cmd)

    # --- producers ------------------------------------------------------------------
    def send_available_modes(self, link):
        if not self.table:
            return False
        if self._index:
            return self._send_mode(link, self._index - 1)
        i = 0
        while i < len(self.table):
            self._send_mode(link, i)
            i += 1
        return True

    def _send_mode(self, link, i):
        row = self.table[i]
        off = link.tx.clear(link.tx.crc_len[_MSG_AVAILABLE_MODES] >> 16)
        buf = link.txbuf
        px4 = self.px4_link(link)
        pack_into("<I", buf, off, self.px4[i] if px4 else row[_NUMBER])
        # A mode that shares its number with an earlier one cannot be set by it.
        shadowed = not px4 and self.by_number(row[_NUMBER]) != i
        buf[off + 4] = _NOT_USER_SELECTABLE if shadowed else 0
        buf[off + 8] = len(self.table)
        buf[off + 9] = i + 1
        buf[off + 10] = self.standard[i]
        if not self.standard[i]:  # a standard mode goes by its standard name
            name = row[_NAME]
            j = 0
            while j < len(name) and j < 34:
                buf[off + 11 + j] = ord(name[j])
                j += 1
        return link.send(_MSG_AVAILABLE_MODES)

    def send_current_mode(self, link):
        row = self.row
        off = link.tx.clear(link.tx.crc_len[_MSG_CURRENT_MODE] >> 16)
        buf = link.txbuf
        pack_into("<I", buf, off, self.custom_for(link, row, self.status.custom_mode))
        intended = self.intended
        if intended >= 0:
            pack_into("<I", buf, off + 4, self.custom_for(link, intended, self.table[intended][_NUMBER]))
        buf[off + 8] = self.standard[row] if row >= 0 else 0
        return link.send(_MSG_CURRENT_MODE)


def veto(status, answer, prefix):
    """A status hook's answer (None | reason | (MAV_RESULT, reason)) -> MAV_RESULT; a refusal
    is kept in status.reason and said in a STATUSTEXT starting with prefix."""
    if answer is None:
        return _ACCEPTED
    if isinstance(answer, tuple):
        result, reason = answer
    else:
        result, reason = _DENIED, answer
    if result == _ACCEPTED:
        return _ACCEPTED
    status.reason = reason
    if reason:
        status.statustext(CRITICAL, prefix.decode() + reason)
    return result
