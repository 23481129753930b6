"""The peripheral service: mavstack as one component on a vehicle (a rangefinder, a
camera, a gimbal) rather than its autopilot. Its HEARTBEAT says MAV_AUTOPILOT_INVALID
with the board's MAV_TYPE and component id; with SYSID "follow" it takes the system id
of the first autopilot HEARTBEAT heard and sends nothing before (follow.py); the
application sends its data through slots made once (output.py: DISTANCE_SENSOR,
NAMED_VALUE_FLOAT/INT). Listed instead of status, with params and commands as needed.
Reference: docs/services/peripheral.md
"""
from ...compat import const, ticks_diff, ticks_add
from ...link import RANK_VITAL, RANK_AUTO
from .follow import Follow
from .output import DistanceSensor, NamedValue

INSTEAD_OF = ("status",)  # the HEARTBEAT of a component, not of a vehicle

_MSG_HEARTBEAT = const(0)
_MAV_AUTOPILOT_INVALID = const(8)
_MAV_STATE_BOOT = const(1)
_MAV_STATE_ACTIVE = const(4)
_MAVLINK_VERSION = const(3)
_PERIOD_MS = const(1000)


class Peripheral:
    NAME = "peripheral"

    def __init__(self, mav_type=0):
        self.mav_type = mav_type
        self.state = _MAV_STATE_BOOT  # MAV_STATE: ACTIVE after the first tick; the application may set it
        self.follow = None  # with SYSID "follow" (follow.py)
        self._next = 0
        self._started = False

    def attach(self, ep):
        self.ep = ep
        self._next = ep.now
        ep.producers[_MSG_HEARTBEAT] = self.send_heartbeat
        if ep.sysid == 0:  # SYSID "follow" (main.py)
            self.follow = Follow(ep, ep.setting("SYSID_FALLBACK", 1), ep.setting("SYSID_WAIT_MS", 0))

    @property
    def sysid_known(self):
        return self.ep.sysid != 0

    def tick(self, now):
        if not self._started:
            self._started = True
            if self.state == _MAV_STATE_BOOT:
                self.state = _MAV_STATE_ACTIVE
        if self.follow is not None:
            self.follow.tick(now)
        if ticks_diff(now, self._next) < 0:
            return
        self._next = ticks_add(self._next, _PERIOD_MS)
        if ticks_diff(now, self._next) >= 0:  # fell behind: keep the rate, not the backlog
            self._next = ticks_add(now, _PERIOD_MS)
        links = self.ep.links
        i = 0  # by index: see docs/design.md
        while i < len(links):
            links[i].rank = RANK_VITAL
            self.send_heartbeat(links[i])
            links[i].rank = RANK_AUTO
            i += 1

    def send_heartbeat(self, link):
        off = link.begin()
        buf = link.txbuf
        buf[off] = buf[off + 1] = buf[off + 2] = buf[off + 3] = 0  # custom_mode
        buf[off + 4] = self.mav_type
        buf[off + 5] = _MAV_AUTOPILOT_INVALID  # not an autopilot: ground stations and MAVSDK pass it over
        buf[off + 6] = 0  # base_mode
        buf[off + 7] = self.state
        buf[off + 8] = _MAVLINK_VERSION
        return link.send(_MSG_HEARTBEAT)

    # --- the application's output (made once, at start-up) ---------------------------
    def distance_sensor(self, min_cm, max_cm, kind=0, sensor_id=0, orientation=25):
        """A DISTANCE_SENSOR slot: send(distance_cm[, quality]) to every link; also what
        REQUEST_MESSAGE(132) answers with. kind: MAV_DISTANCE_SENSOR; orientation:
        MAV_SENSOR_ORIENTATION (25: pointing down)."""
        slot = DistanceSensor(self.ep, min_cm, max_cm, kind, sensor_id, orientation)
        if self.ep.has(slot.MSGID):
            self.ep.producers[slot.MSGID] = slot.send_to
        return slot

    def named_float(self, name):
        """A NAMED_VALUE_FLOAT slot for one name (up to 10 characters): send(value)."""
        return NamedValue(self.ep, name, False)

    def named_int(self, name):
        """A NAMED_VALUE_INT slot: send(value), an int below 2^30 (docs/design.md)."""
        return NamedValue(self.ep, name, True)


def create(ep):
    return ep.add(Peripheral(ep.setting("MAV_TYPE", 0)))
