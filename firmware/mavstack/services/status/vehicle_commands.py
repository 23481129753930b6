"""The vehicle's own commands, answered from the status service's state:
COMPONENT_ARM_DISARM, DO_SET_MODE, PREFLIGHT_REBOOT_SHUTDOWN,
REQUEST_AUTOPILOT_CAPABILITIES, GET_HOME_POSITION and DO_SET_HOME; and the two messages
they answer with, AUTOPILOT_VERSION and HOME_POSITION. Installed by the status service
(the commands service sends the ACKs); those that change the vehicle need operator control.
Reference: docs/services/status.md
"""
from struct import pack_into

from ... import VERSION
from ...compat import const, heap_open, heap_close, ticks_diff
from ...statustext import CRITICAL, WARNING
from .conventions import shows_px4

_ACCEPTED = const(0)
_TEMPORARILY_REJECTED = const(1)
_DENIED = const(2)

_CMD_DO_SET_MODE = const(176)
_CMD_DO_SET_HOME = const(179)
_CMD_PREFLIGHT_REBOOT_SHUTDOWN = const(246)
_CMD_COMPONENT_ARM_DISARM = const(400)
_CMD_GET_HOME_POSITION = const(410)
_CMD_REQUEST_AUTOPILOT_CAPABILITIES = const(520)
_MSG_AUTOPILOT_VERSION = const(148)
_MSG_HOME_POSITION = const(242)

_FORCE_ARM = const(21196)  # COMPONENT_ARM_DISARM param2: skip the checks
_FORCE_REBOOT = const(20190226)  # REBOOT_SHUTDOWN_CONDITIONS: even when armed
_REBOOT = const(1)
_SHUTDOWN = const(2)
# MAV_FRAME of a COMMAND_INT position
_FRAME_GLOBAL = const(0)
_FRAME_GLOBAL_RELATIVE_ALT = const(3)
_FRAME_GLOBAL_INT = const(5)
_FRAME_GLOBAL_RELATIVE_ALT_INT = const(6)
_FIRMWARE_VERSION_TYPE_DEV = const(0)
_ACK_WAIT_MS = const(3000)  # a reboot waits this long at most for held-back ACKs


def reboot_due(ep, at, now):
    """Is the reboot due at `at` to go now? Once ACKs the link's budget held back (its own
    among them) are sent, or _ACK_WAIT_MS later: ACCEPTED reaches the ground station."""
    late = ticks_diff(now, at)
    if late < 0:
        return False
    commands = ep.services.get("commands")
    return commands is None or commands.holding() == 0 or late >= _ACK_WAIT_MS


class VehicleCommands:
    def __init__(self, ep, status):
        self.ep = ep
        self.status = status
        self._sw_version = _version_word(VERSION, _FIRMWARE_VERSION_TYPE_DEV)
        self._os_version = _os_version()
        self._one = 1.0  # HOME_POSITION's quaternion w, made once

    def _in_control(self, cmd, text):
        # text: a whole constant (joining bytes allocates, and a board may lock its heap)
        if self.ep.allows(cmd.link):
            return True
        self.status.statustext(WARNING, text)
        return False

    def arm_disarm(self, cmd):
        # param1: 1 arm, 0 disarm; param2: 21196 forces.
        if not cmd.finite(1):
            return _DENIED
        arm = cmd.int(1)
        if arm != 0 and arm != 1:
            return _DENIED
        if not self._in_control(cmd, b"Arm: GCS not in control"):
            return _DENIED
        result = self.status.arm(arm == 1, cmd.finite(2) and cmd.int(2) == _FORCE_ARM)
        if result == _ACCEPTED:
            self.status.conventions.took(cmd.link)
        return result

    def set_mode(self, cmd):
        # param1: base mode (MAV_MODE_FLAG bits), param2: custom mode (NaN: 0), param3:
        # PX4's sub mode (docs/services/status.md: which numbers a station means).
        if not cmd.finite(1):
            return _DENIED
        base = cmd.int(1)
        custom = 0
        if not cmd.nan(2):
            if not cmd.finite(2):
                return _DENIED
            custom = cmd.int(2)
        if base < 0 or base > 255 or custom < 0:
            return _DENIED
        if custom and base & 1:
            custom = self._custom_mode(cmd, custom)
            if custom < 0:
                return _DENIED
        if not self._in_control(cmd, b"Mode: GCS not in control"):
            return _DENIED
        return self.status.modes.set_mode(base, custom, cmd.link)

    def _custom_mode(self, cmd, number):
        """DO_SET_MODE's custom mode as its station means it: PX4's main and sub mode
        (param2, param3) from a station in PX4's convention or a request that shows it,
        ArduPilot's number from one in ArduPilot's; both readings tried for a station not
        known yet -> the custom mode, or -1 (refused)."""
        modes = self.status.modes
        auto = modes.numbering == "auto"
        if modes.px4_link(cmd.link) or auto and shows_px4(cmd.payload, _CMD_DO_SET_MODE):
            sub = cmd.int(3) if cmd.finite(3) else 0
            if number > 255 or sub < 0 or sub > 63:
                return -1
            return number << 16 | sub << 24
        return modes.either(number) if modes.undecided(cmd.link) else number

    def reboot_shutdown(self, cmd):
        # param1: 0 nothing, 1 reboot, 2 shutdown, 3 reboot to bootloader; param6: conditions.
        if cmd.nan(1):
            return _ACCEPTED
        if not cmd.finite(1):
            return _DENIED
        action = cmd.int(1)
        if action == 0:
            return _ACCEPTED
        if action != _REBOOT and not (action == _SHUTDOWN and hasattr(getattr(self.ep, "board", None), "shutdown")):
            return _DENIED  # a valid request this board cannot carry out
        if not self._in_control(cmd, b"Reboot: GCS not in control"):
            return _DENIED
        if self.status.rebooting:
            # Already on its way (this one's ACK may have been lost): asked again, it keeps
            # its time rather than being put off by every repeat; the other action waits.
            return _ACCEPTED if self.status.rebooting == action else _TEMPORARILY_REJECTED
        if self.status.armed and not (cmd.finite(6) and cmd.int(6) == _FORCE_REBOOT):
            self.status.statustext(CRITICAL, b"Reboot: disarm first")
            return _DENIED
        self.status.reboot(action)
        # What must outlive the restart is stored now: a board's shutdown() may cut the
        # power before main.py's last word. (A dict look-up: the heap may be locked.)
        signing = self.ep.services.get("signing")
        if signing is not None:
            signing.stop()
        return _ACCEPTED

    def autopilot_capabilities(self, cmd):
        if _MSG_AUTOPILOT_VERSION not in self.ep.producers:
            return _DENIED
        cmd.reply = _MSG_AUTOPILOT_VERSION
        return _ACCEPTED

    def get_home(self, cmd):
        if _MSG_HOME_POSITION not in self.ep.producers:
            return _DENIED
        if not self.status.home_set:
            return _TEMPORARILY_REJECTED  # no position fix yet
        cmd.reply = _MSG_HOME_POSITION
        return _ACCEPTED

    def set_home(self, cmd):
        # param1 1: here (the application's position()); else param5-7 lat, lon, alt (AMSL).
        status = self.status
        if not self._in_control(cmd, b"Home: GCS not in control"):
            return _DENIED
        if cmd.finite(1) and cmd.int(1) == 1:
            where = status.position() if status.position is not None else None
            if where is None:
                return _TEMPORARILY_REJECTED
            status.set_home(where[0], where[1], where[2])
            return _ACCEPTED
        if not (cmd.finite(5) and cmd.finite(6) and cmd.finite(7)):
            return _DENIED
        # A rare event, with floats and ints past 2^30 (heap objects on a 32-bit board):
        # the heap opened for it, as a board may lock it.
        depth = heap_open()
        try:
            return self._set_home_at(cmd)
        finally:
            heap_close(depth)

    def _set_home_at(self, cmd):
        status = self.status
        alt = cmd.float(7)  # finite, but a float32 reaches 3.4e38: ranges before ints
        if not -2000000.0 < alt < 2000000.0:
            return _DENIED
        alt_mm = int(round(alt * 1000))
        if cmd.is_int:
            frame = cmd.frame
            lat = cmd.int(5)
            lon = cmd.int(6)
            if frame == _FRAME_GLOBAL_RELATIVE_ALT or frame == _FRAME_GLOBAL_RELATIVE_ALT_INT:
                alt_mm += status.home_alt
            elif frame != _FRAME_GLOBAL and frame != _FRAME_GLOBAL_INT:
                return _DENIED
        else:
            lat = cmd.float(5)
            lon = cmd.float(6)
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                return _DENIED
            lat = int(round(lat * 1e7))
            lon = int(round(lon * 1e7))
        if not (-900000000 <= lat <= 900000000 and -1800000000 <= lon <= 1800000000):
            return _DENIED
        if not -2000000000 < alt_mm < 2000000000:
            return _DENIED
        status.set_home(lat, lon, alt_mm)
        return _ACCEPTED

    # --- producers: send(link) -> bool, a few fields a pack_into (docs/design.md) ---
    def send_autopilot_version(self, link):
        # capabilities, uid, flight_sw_version, middleware 0, os_sw_version; board_version,
        # vendor_id, product_id and the hashes stay 0.
        off = link.tx.clear(link.tx.crc_len[_MSG_AUTOPILOT_VERSION] >> 16)
        buf = link.txbuf
        pack_into("<QQI", buf, off, self.ep.capabilities, self.status.uid, self._sw_version)
        pack_into("<I", buf, off + 24, self._os_version)
        return link.send(_MSG_AUTOPILOT_VERSION)

    def send_home_position(self, link):
        # lat, lon, alt; x, y, z 0; q = (1, 0, 0, 0); the rest 0.
        if not self.status.home_set or _MSG_HOME_POSITION not in link.tx.crc_len:
            return False  # (the seed's message set has no HOME_POSITION)
        off = link.tx.clear(link.tx.crc_len[_MSG_HOME_POSITION] >> 16)
        buf = link.txbuf
        pack_into("<iii", buf, off, self.status.home_lat, self.status.home_lon, self.status.home_alt)
        pack_into("<f", buf, off + 24, self._one)
        return link.send(_MSG_HOME_POSITION)


def board_uid(board, sysid):
    """AUTOPILOT_VERSION's uid: the profile's UID, else the chip's id, else the sysid."""
    uid = getattr(board, "UID", 0)
    if not uid:
        try:
            import machine

            uid = int.from_bytes(machine.unique_id()[:8], "little")
        except (ImportError, AttributeError):
            uid = 0
    return uid or sysid


def _version_word(v, kind):
    return v[0] << 24 | v[1] << 16 | v[2] << 8 | kind


def _os_version():
    import sys

    return _version_word(sys.implementation.version, _FIRMWARE_VERSION_TYPE_DEV)


def install(ep, status):
    vc = VehicleCommands(ep, status)
    # The layouts packed here (fields a dialect adds after them are zeroed first):
    if ep.has(_MSG_AUTOPILOT_VERSION) and ep.fmt(_MSG_AUTOPILOT_VERSION).startswith("<QQIIIIHH"):
        ep.producers[_MSG_AUTOPILOT_VERSION] = vc.send_autopilot_version
    if ep.has(_MSG_HOME_POSITION) and ep.fmt(_MSG_HOME_POSITION).startswith("<iiifff4f"):
        ep.producers[_MSG_HOME_POSITION] = vc.send_home_position
    ep.commands[_CMD_COMPONENT_ARM_DISARM] = vc.arm_disarm
    ep.commands[_CMD_DO_SET_MODE] = vc.set_mode
    ep.commands[_CMD_PREFLIGHT_REBOOT_SHUTDOWN] = vc.reboot_shutdown
    ep.commands[_CMD_REQUEST_AUTOPILOT_CAPABILITIES] = vc.autopilot_capabilities
    ep.commands[_CMD_GET_HOME_POSITION] = vc.get_home
    ep.commands[_CMD_DO_SET_HOME] = vc.set_home
    return vc
