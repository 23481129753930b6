"""The mission, as the simulated vehicle flies it in AUTO: the current item from the
mission runner (services/missions/runner.py), carried out with the kinematic model of
motion.py. The flight pilot (pilot.py) calls step() while the vehicle is armed in AUTO
and pauses the runner when it leaves AUTO. Reference: docs/sim.md.
"""
import math

from .motion import Motion


class MissionPilot(Motion):
    """Flies the mission's current item for the simulator: the motion model (Motion), its
    speeds read again at each new item. What each command does: docs/sim.md."""

    def __init__(self, sim):
        Motion.__init__(self, sim)
        self.missions = sim.ep.services.get("missions")
        self._seq = -1
        self._started = None
        self._arrived = 0.0  # seconds spent at the item's position
        self._yaw_target = None
        self._wait = None  # NAV_DELAY: seconds to wait
        self._up = False  # NAV_TAKEOFF: at its altitude (then to its position, its heading)
        self.touched_down = False  # a LAND item has just put the vehicle on the ground

    def step(self, dt):
        """Fly the current item for dt seconds (the vehicle is armed, in AUTO)."""
        runner = self.missions.runner if self.missions is not None else None
        if runner is None or not runner.run() or runner.waiting or runner.item is None:
            self.sim.target = None
            self.hold()
            return
        item = runner.item
        if item.seq != self._seq or runner.started_ms != self._started:
            # The mission starts over (at item 1 where item 0 is home): speeds from the parameters.
            over = item.seq == 0 or (item.seq == 1 and self._seq != 0)
            self._seq = item.seq
            self._started = runner.started_ms
            self._arrived = 0.0
            self._yaw_target = None
            self._wait = None
            self._up = False
            if over:
                self.sim.roi = None
                self.reset_speeds()
            else:
                self.read_speeds()
        if self._do(item, dt):
            runner.reached()

    # --- one item -----------------------------------------------------------------
    def _do(self, item, dt):
        """Carry out the item for dt seconds -> True once it is done."""
        sim = self.sim
        cmd = item.command
        if cmd in (16, 17, 18, 19):  # WAYPOINT, LOITER_UNLIM, LOITER_TURNS, LOITER_TIME
            lat, lon, alt = self._position(item)
            radius = item.param2 if cmd == 16 and item.param2 > 0 else self.radius
            if not self.go(lat, lon, alt, dt, radius):
                return False
            self._arrived += dt
            if cmd == 16:
                return self._arrived >= max(item.param1, 0.0)
            if cmd == 17:
                return False
            if cmd == 18:
                r = abs(item.param3) or 10.0
                return self._arrived >= item.param1 * 2 * math.pi * r / self.speed
            return self._arrived >= item.param1
        if cmd == 20:  # RETURN_TO_LAUNCH: home at the current altitude, then down
            lat, lon, alt = self.home()
            if not self.go(lat, lon, max(sim.alt, alt), dt, self.radius):
                return False
            return self.go(lat, lon, alt, dt, 0.5)
        if cmd == 21:  # LAND, at the item's position or here; on the ground the pilot disarms
            lat, lon, alt = self._position(item)
            if not self.go(lat, lon, sim.alt, dt, self.radius):
                return False
            ground = self.home()[2] if math.isnan(item.z) else alt
            self.touched_down = self.go(lat, lon, ground, dt, 0.2)
            return self.touched_down
        if cmd == 22:  # TAKEOFF
            return self._takeoff(item, dt)
        if cmd == 112:  # CONDITION_DELAY
            self.hold()
            self._arrived += dt
            return self._arrived >= item.param1
        if cmd == 113:  # CONDITION_CHANGE_ALT, at param1 m/s
            rate = abs(item.param1) or self.climb
            return self.go(sim.lat, sim.lon, self._position(item)[2], dt, 0.5, climb=rate)
        if cmd == 114:  # CONDITION_DISTANCE: on toward the next NAV item until that close
            nxt = self.missions.runner.next_nav()
            if nxt is None:
                return True
            lat, lon, alt = self._position(nxt)
            return self.go(lat, lon, alt, dt, max(item.param1, self.radius))
        if cmd == 115:  # CONDITION_YAW: param1 deg, param2 deg/s, param3 direction, param4 relative
            if self._yaw_target is None:
                base = math.degrees(sim.heading) if item.param4 == 1 else 0.0
                sign = -1.0 if item.param4 == 1 and item.param3 < 0 else 1.0
                self._yaw_target = (base + sign * item.param1) % 360.0
            self.hold()
            return self.turn(self._yaw_target, item.param2 or self.turn_rate, dt)
        if cmd == 178:  # DO_CHANGE_SPEED
            self.change_speed(item.param1, item.param2)
            return True
        if cmd == 93:  # NAV_DELAY
            return self._delay(item, dt)
        if cmd == 31:  # NAV_LOITER_TO_ALT: there at the altitude it has, then to the item's
            lat, lon, alt = self._position(item)
            if self._arrived == 0.0 and not self.go(lat, lon, sim.alt, dt, self.radius):
                return False
            self._arrived += dt
            return self.go(lat, lon, alt, dt, 0.5)
        if cmd in (80, 195, 197, 201):
            self._roi(item)
            return True
        if cmd in (205, 1000, 206, 214, 2000, 2001, 2500, 2501):
            self._payload(item)
            return True
        if cmd == 179 and self.status is not None:  # DO_SET_HOME
            if item.param1 == 1:
                self.status.set_home(*sim.position_e7())
            else:
                self.status.set_home(item.x, item.y, round(item.z * 1000))
            return True
        return True  # other DO / NAV commands: nothing to fly

    def _position(self, item):
        """(lat, lon, alt MSL) of an item; 0/0 means here, relative frames add home."""
        sim = self.sim
        if item.x_unset or item.y_unset or (item.x == 0 and item.y == 0):
            lat = sim.lat if item.x_unset or not item.y_unset else item.lat
            lon = sim.lon if item.y_unset or not item.x_unset else item.lon
        else:
            lat, lon = item.lat, item.lon
        alt = item.z
        if math.isnan(alt):
            alt = sim.alt
        elif item.frame in (3, 6, 10, 11):  # relative to home (terrain: no terrain data here)
            alt += self.home()[2]
        return lat, lon, alt

    def _takeoff(self, item, dt):
        """NAV_TAKEOFF: straight up to its altitude (NaN: MIS_TAKEOFF_ALT above home), then
        to its position if it has one (x, y unset or 0: here), then to its heading
        (param4, NaN: kept) -> True once done."""
        sim = self.sim
        lat, lon, alt = self._position(item)
        if math.isnan(item.z):
            alt = self.home()[2] + self.setting(None, "MIS_TAKEOFF_ALT", 10.0)
        if not self._up:
            self._up = self.go(sim.lat, sim.lon, alt, dt, 0.05)
            return False
        if not self.go(lat, lon, alt, dt, 0.05):
            return False
        return math.isnan(item.param4) or self.turn(item.param4 % 360.0, self.turn_rate, dt)

    def _delay(self, item, dt):
        """NAV_DELAY: hold for param1 s, or (param1 -1) until hour:minute:second UTC in
        param2-4 (-1: any hour, any minute)."""
        self.hold()
        if self._wait is None:
            self._wait = item.param1 if item.param1 >= 0 else _until(item.param2, item.param3, item.param4)
        self._arrived += dt
        return self._arrived >= self._wait

    def _roi(self, item):
        sim = self.sim
        cmd = item.command
        if cmd == 197 or (cmd == 201 and item.param1 == 0) or (cmd == 80 and item.param1 == 0):
            sim.roi = None  # DO_SET_ROI_NONE, ROI mode 0
        elif cmd == 195 or ((cmd == 201 or cmd == 80) and item.param1 == 3):
            lat, lon, alt = self._position(item)
            sim.roi = (lat, lon, alt)

    def _payload(self, item):
        """Camera and gimbal commands, as a payload would take them."""
        sim = self.sim
        cmd = item.command
        if cmd == 205:  # DO_MOUNT_CONTROL: pitch, roll, yaw (deg)
            sim.gimbal = (item.param1, item.param3)
        elif cmd == 1000:  # DO_GIMBAL_MANAGER_PITCHYAW: NaN keeps an angle
            pitch, yaw = sim.gimbal
            sim.gimbal = (pitch if math.isnan(item.param1) else item.param1,
                          yaw if math.isnan(item.param2) else item.param2)
        elif cmd == 206:  # DO_SET_CAM_TRIGG_DIST: a photo every param1 m (0: stop), param3 1: one now
            sim.trigger_dist = item.param1 if item.param1 >= 0.1 else 0.0  # (a camera's shortest)
            self.travel = 0.0
            sim.photos = sim.photos + (1 if item.param3 == 1 and item.param1 > 0 else 0)
        elif cmd == 214:  # DO_SET_CAM_TRIGG_INTERVAL
            sim.trigger_dist = 0.0
        elif cmd == 2000:  # IMAGE_START_CAPTURE: one photo (the interval's are not simulated)
            sim.photos = sim.photos + 1
        elif cmd == 2001:
            sim.trigger_dist = 0.0
        else:  # VIDEO_START_CAPTURE / VIDEO_STOP_CAPTURE
            sim.video = cmd == 2500


def _until(hour, minute, second):
    """Seconds from now to the next hour:minute:second UTC (an hour outside 0-23: any
    hour, a minute outside 0-59: any minute; NaN is outside)."""
    import time

    day = int(time.time()) % 86400
    hours = (int(hour),) if 0 <= hour < 24 else range(24)
    minutes = (int(minute),) if 0 <= minute < 60 else range(60)
    sec = int(second) if 0 <= second < 60 else 0
    best = 86400
    for h in hours:
        for mi in minutes:
            wait = (h * 3600 + mi * 60 + sec - day) % 86400
            if wait < best:
                best = wait
    return float(best)
