"""Which autopilot's conventions each link's ground station assumes, learned from what it
does and never from its system id: ArduPilot's (MAVProxy, Mission Planner, pymavlink's
tools) or PX4's (MAVSDK, QGroundControl). The mode numbers each link reads and sets
(modes.py, vehicle_commands.py), the parameter service's "auto" integer encoding and the
application's flight rules go by it; `last` is the convention of the ground station
whose request (a mode, arming) the vehicle last took. Made by the status service
(status.conventions); each frame it hears allocates nothing.
Reference: docs/services/status.md
"""
from ...compat import const
from ...fields import f32_is_nan

UNKNOWN = const(0)  # nothing heard yet
ARDUPILOT = const(1)
PX4 = const(2)

_MSG_SET_MODE = const(11)
_MSG_REQUEST_DATA_STREAM = const(66)
_MSG_COMMAND_INT = const(75)
_MSG_COMMAND_LONG = const(76)
_CMD_DO_SET_MODE = const(176)
_CMD_REQUEST_MESSAGE = const(512)
_CMD_REQUEST_AUTOPILOT_CAPABILITIES = const(520)


class Conventions:
    def __init__(self):
        self.links = bytearray(0)  # per link (its index): UNKNOWN, ARDUPILOT or PX4
        self.last = UNKNOWN
        self.ep = None

    def attach(self, ep):
        # Before the commands service: a command's own signs are learned before it runs.
        self.ep = ep
        ep.on(_MSG_REQUEST_DATA_STREAM, self._heard_streams)
        ep.on(_MSG_COMMAND_LONG, self._heard_command)
        ep.on(_MSG_COMMAND_INT, self._heard_command)
        ep.on(_MSG_SET_MODE, self._heard_set_mode)

    def links_changed(self, links):
        # Rare (start-up, a link added): a byte a link.
        if len(self.links) < len(links):
            grown = bytearray(len(links))
            grown[:len(self.links)] = self.links
            self.links = grown

    # --- reading and telling --------------------------------------------------------
    def of(self, link):
        """The convention of link's ground station: UNKNOWN, ARDUPILOT or PX4."""
        i = link.index
        return self.links[i] if i < len(self.links) else UNKNOWN

    def learn(self, link, convention):
        i = link.index
        if i < len(self.links):
            self.links[i] = convention

    def took(self, link):
        """The vehicle took a request from link's ground station (a mode, arming, a
        flight command): it flies by that station's rules from now on (`last`)."""
        self.last = self.of(link)

    # --- what ground stations do ----------------------------------------------------
    def _heard_streams(self, link, p):
        # REQUEST_DATA_STREAM: ArduPilot's way to ask for telemetry (PX4 ignores it).
        if self.ep.for_us(p[2], p[3]):
            self.learn(link, ARDUPILOT)

    def _heard_command(self, link, p):
        # COMMAND_LONG / COMMAND_INT: the command at 28, the target at 30, 31.
        if not self.ep.for_us(p[30], p[31]):
            return
        c = p[29] << 8 | p[28]
        if shows_px4(p, c):
            self.learn(link, PX4)
        elif c == _CMD_REQUEST_AUTOPILOT_CAPABILITIES or (c == _CMD_REQUEST_MESSAGE and _is_148(p)):
            # Asking for AUTOPILOT_VERSION tells PX4's stations what to read; ArduPilot's
            # ask too, so it only decides a link that has shown nothing else.
            if self.of(link) == UNKNOWN:
                self.learn(link, PX4)

    def _heard_set_mode(self, link, p):
        # SET_MODE (custom_mode at 0, target at 4) with a PX4-encoded custom mode.
        if p[4] == self.ep.sysid and (p[2] or p[3]):
            self.learn(link, PX4)


def shows_px4(p, command):
    """A COMMAND_LONG or COMMAND_INT payload p says it follows PX4's convention: NaN in
    param4 and param7 (MAVSDK fills the parameters a command does not use with NaN,
    ArduPilot's stations with 0), or DO_SET_MODE with a PX4 sub mode in param3."""
    if f32_is_nan(p, 12) and f32_is_nan(p, 24):
        return True
    if command != _CMD_DO_SET_MODE:
        return False
    # param3 a number other than 0: some bit but the sign's set, the exponent not all ones
    if not (p[8] | p[9] | p[10] | p[11] & 0x7F):
        return False
    return (p[11] & 0x7F) != 0x7F or not p[10] & 0x80


def _is_148(p):
    """param1 (p[0:4]) is 148.0, AUTOPILOT_VERSION's id, as a float."""
    return p[0] == 0 and p[1] == 0 and p[2] == 0x14 and p[3] == 0x43
