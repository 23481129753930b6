"""Flight modes: the board's mode table, the number each ground station reads a mode by,
and the ways ground stations set one (the status service owns the current mode and
calls in here).

The table (the board's FLIGHT_MODES), one row a mode:

    (number, "NAME", MAV_MODE_FLAG bits, px4_main, px4_sub, MAV_STANDARD_MODE)

MAV_AUTOPILOT_GENERIC defines no custom modes, so every ground station reads
HEARTBEAT.custom_mode by the convention of the autopilot it assumes:
- ArduPilot's (MAVProxy, Mission Planner, pymavlink's mode names for anything but PX4):
  `number`, as ArduCopter numbers its modes (STABILIZE 0, AUTO 3, GUIDED 4 ...);
- PX4's (MAVSDK for anything but ArduPilot): px4_main in bits 16-23, px4_sub in bits
  24-31 (AUTO.LOITER is main 4, sub 3).
So each link reports the mode the way its ground station reads it. With MODE_NUMBERING
"auto" (the default) a link starts with ArduPilot's numbers and changes to PX4's when its
ground station shows itself as MAVSDK: a ground-station heartbeat from system id 245
(MAVSDK's own), or a SET_MODE whose custom mode is PX4-encoded. "ardupilot" or "px4"
fix the choice. Rows may share a number (ArduCopter takes off and follows setpoints in
GUIDED: TAKEOFF and OFFBOARD are shown as GUIDED there); a number set picks its first row.

Setting a mode, whichever way it comes, ends in status.set_mode -> find():
- a custom mode (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED): below 65536 a row's number, from
  65536 up a PX4 encoding (never ambiguous: a PX4 main mode is at least 1);
  MAV_CMD_DO_SET_MODE carries PX4's main and sub mode in param2 and param3, so on a
  link in PX4's convention they are read that way;
- base-mode flags alone: the row whose flags match (AUTO, GUIDED, STABILIZE ...); so is
  custom mode 0 with AUTO or GUIDED among the flags (what a generic station sends for
  "AUTO"; ArduPilot's convention names STABILIZE with the custom flag alone);
- MAV_CMD_DO_SET_STANDARD_MODE: the row of that MAV_STANDARD_MODE.
Anything else is refused. A board without a table keeps flag-only modes.
Where the dialect has them, AVAILABLE_MODES (all, or one by index: REQUEST_MESSAGE
param2) and CURRENT_MODE (on change and on request) describe the table.
"""
from struct import pack_into

from ...compat import const

_NUMBER = const(0)
_NAME = const(1)
_FLAGS = const(2)

_ARDUPILOT = const(0)
_PX4 = const(1)
_MAVSDK_SYSID = const(245)  # MAVSDK's ground-station system id
_MAV_TYPE_GCS = const(6)
_PX4_MANUAL = const(1)  # PX4's MANUAL main mode: a multicopter's is stabilized
_PX4_STABILIZED = const(7)
_FLAG_CHOICE = const(0x5C)  # MANUAL_INPUT | STABILIZE | GUIDED | AUTO: what picks a row
_NOT_USER_SELECTABLE = const(2)  # MAV_MODE_PROPERTY
_AUTO_OR_GUIDED = const(12)

_MSG_HEARTBEAT = const(0)
_MSG_AVAILABLE_MODES = const(435)
_MSG_CURRENT_MODE = const(436)
_CMD_DO_SET_STANDARD_MODE = const(262)
_CMD_REQUEST_MESSAGE = const(512)
_DENIED = const(2)
_UNSUPPORTED = const(3)


class Modes:
    def __init__(self, table, numbering="auto"):
        if numbering not in ("auto", "ardupilot", "px4"):
            raise ValueError("MODE_NUMBERING is 'auto', 'ardupilot' or 'px4'")
        self.numbering = numbering
        self.set_table(table)
        self._conv = bytearray(0)  # per link: _ARDUPILOT or _PX4
        self._index = 0  # AVAILABLE_MODES asked for: 0 all, else one (1-based)
        self._request = None  # the REQUEST_MESSAGE handler wrapped (wrap_request_message)
        self.ep = None
        self.status = None

    def set_table(self, table):
        self.table = table
        # Per row, made once: the PX4 encoding (below 2^30: a small int on any board) and
        # the standard mode (0: none); 3-field rows (number, name, flags) have neither.
        self.px4 = [(r[3] << 16 | r[4] << 24) if len(r) > 4 else 0 for r in table]
        self.standard = bytes(r[5] if len(r) > 5 else 0 for r in table)

    def attach(self, ep, status):
        self.ep = ep
        self.status = status
        ep.on(_MSG_HEARTBEAT, self._on_heartbeat)
        if self.table:
            ep.commands[_CMD_DO_SET_STANDARD_MODE] = self._set_standard_mode
        if ep.has(_MSG_AVAILABLE_MODES):
            ep.producers[_MSG_AVAILABLE_MODES] = self.send_available_modes
        if ep.has(_MSG_CURRENT_MODE):
            ep.producers[_MSG_CURRENT_MODE] = self.send_current_mode

    def links_changed(self, links):
        fixed = _PX4 if self.numbering == "px4" else _ARDUPILOT
        while len(self._conv) < len(links):
            self._conv = self._conv + bytes((fixed,))

    def wrap_request_message(self):
        # Once all services are in: AVAILABLE_MODES needs REQUEST_MESSAGE's param2 (which
        # mode), so the built-in handler is wrapped to note it first.
        if _MSG_AVAILABLE_MODES in self.ep.producers and self._request is None:
            self._request = self.ep.commands.get(_CMD_REQUEST_MESSAGE)
            if self._request is not None:
                self.ep.commands[_CMD_REQUEST_MESSAGE] = self._request_message

    # --- conventions ----------------------------------------------------------------
    def px4_link(self, link):
        i = link.index
        return i < len(self._conv) and self._conv[i] == _PX4

    def _learn_px4(self, link):
        if self.numbering == "auto" and link.index < len(self._conv):
            self._conv[link.index] = _PX4

    def _on_heartbeat(self, link, p):
        if p[4] == _MAV_TYPE_GCS and link.rx.sysid == _MAVSDK_SYSID:
            self._learn_px4(link)

    def heard_custom(self, link, custom):
        """A SET_MODE's custom mode: PX4-encoded ones show the station's convention."""
        if custom >= 0x10000 and link is not None:
            self._learn_px4(link)

    def custom_for(self, link, row, number):
        """HEARTBEAT.custom_mode of mode `row` (-1: none) as this link reads it."""
        if row >= 0 and self.px4_link(link):
            return self.px4[row]
        return number

    def custom(self, link):
        """The current mode's custom_mode for this link (the status service's HEARTBEAT)."""
        return self.custom_for(link, self.status.mode_row, self.status.custom_mode)

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

    # --- commands -------------------------------------------------------------------
    def _set_standard_mode(self, cmd):
        # param1: MAV_STANDARD_MODE. One the vehicle does not have is not supported.
        if not cmd.finite(1):
            return _DENIED
        row = self.by_standard(cmd.int(1))
        if row < 0:
            self.status.statustext(4, b"Mode: no such standard mode")
            return _UNSUPPORTED
        if not self.ep.allows(cmd.link):
            self.status.statustext(4, b"Mode: GCS not in control")
            return _DENIED
        return self.status.enter(row, True)

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
        status = self.status
        row = status.mode_row
        off = link.tx.clear(link.tx.crc_len[_MSG_CURRENT_MODE] >> 16)
        buf = link.txbuf
        pack_into("<I", buf, off, self.custom_for(link, row, status.custom_mode))
        intended = status.intended_row
        if intended >= 0:
            pack_into("<I", buf, off + 4, self.custom_for(link, intended, self.table[intended][_NUMBER]))
        buf[off + 8] = self.standard[row] if row >= 0 else 0
        return link.send(_MSG_CURRENT_MODE)

