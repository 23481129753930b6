"""How the simulated vehicle moves: a kinematic model with a horizontal speed, climb and
sink rates and a turn rate, that flies toward a point or at a velocity and never below
the ground (the home altitude: a flat field). The speeds are the WP_* parameters,
`--set sim_speed` (and the like) over them, DO_CHANGE_SPEED over both. Reference:
docs/sim.md.
"""
import math

EARTH_RADIUS = 6378137.0
HOME_LAT = 47.397742  # where the simulated vehicle starts: a field where ground stations' maps have tiles
HOME_LON = 8.545594
HOME_ALT = 488.0  # m above mean sea level
CEILING = 10000.0  # m above the ground: no target is higher (whatever a command says)


class Motion:
    def __init__(self, sim):
        self.sim = sim
        ep = sim.ep
        self.options = getattr(ep, "options", None) or {}
        self.params = ep.services.get("params")
        self.status = ep.services.get("status")
        self._changed = {}  # DO_CHANGE_SPEED's speeds ("speed", "climb", "sink")
        self.travel = 0.0  # metres flown since the last distance-triggered photo
        self.read_speeds()

    def setting(self, option, param, default):
        """An option (--set), else the parameter, else the default, as a float."""
        if option and option in self.options:
            return float(self.options[option])
        if self.params is not None:
            try:
                value = self.params.get(param)
                if value is not None:
                    return float(value)
            except (KeyError, ValueError):
                pass
        return default

    def read_speeds(self):
        """The speeds from the options and parameters, DO_CHANGE_SPEED's over them."""
        self.speed = self.setting("sim_speed", "WP_SPEED", 5.0)
        self.climb = self.setting("sim_climb", "WP_SPEED_UP", 2.5)
        self.sink = self.setting("sim_climb", "WP_SPEED_DN", 1.5)
        self.radius = self.setting("sim_accept_radius", "WP_ACCEPT_RAD", 2.0)
        self.turn_rate = self.setting("sim_yaw_rate", "SIM_YAW_RATE", 90.0)
        for name, value in self._changed.items():
            setattr(self, name, value)

    def reset_speeds(self):
        """DO_CHANGE_SPEED's speeds forgotten: the parameters' again."""
        self._changed.clear()
        self.read_speeds()

    def change_speed(self, kind, speed):
        """DO_CHANGE_SPEED: kind 0/1 horizontal (air or ground speed), 2 climb, 3 descent;
        speed -1 no change, -2 back to the parameter's -> False for a speed out of range."""
        name = ("speed", "speed", "climb", "sink")[int(kind)] if 0 <= kind < 4 else "speed"
        if speed == -2:
            self._changed.pop(name, None)
            self.read_speeds()
        elif 0 < speed < 1e6:  # (a finite speed, whatever a plan says)
            self._changed[name] = speed
            setattr(self, name, speed)
        elif speed != -1:
            return False
        return True

    def home(self):
        """(lat, lon, alt MSL) of home: the status service's, else the simulator's start."""
        status = self.status
        if status is not None and status.home_set:
            return status.home_lat / 1e7, status.home_lon / 1e7, status.home_alt / 1000.0
        return self.sim.start

    def ground(self):
        """The ground's altitude (MSL) under the vehicle: home's (a flat field)."""
        return self.home()[2]

    # --- motion -------------------------------------------------------------------
    def go(self, lat, lon, alt, dt, radius, climb=None, speed=None):
        """Move toward a point for dt seconds -> True once within radius."""
        sim = self.sim
        alt = max(self.ground(), min(alt, self.ground() + CEILING))
        sim.target = (lat, lon, alt)
        dn = math.radians(lat - sim.lat) * EARTH_RADIUS
        de = math.radians(lon - sim.lon) * EARTH_RADIUS * math.cos(math.radians(sim.lat))
        du = alt - sim.alt
        dist = math.sqrt(dn * dn + de * de)
        if math.sqrt(dist * dist + du * du) <= radius:
            self.hold()
            return True
        speed = speed or self.speed
        step = min(speed * dt, dist)
        vstep = min((climb or (self.climb if du > 0 else self.sink)) * dt, abs(du))
        mn = dn / dist * step if dist > 0 else 0.0
        me = de / dist * step if dist > 0 else 0.0
        md = -vstep if du > 0 else vstep
        if sim.roi is not None:
            sim.heading = _bearing(sim, sim.roi)  # the nose on the region of interest
        elif dist > 0.5:
            sim.heading = math.atan2(de, dn)
        self.moved(mn, me, md, dt, step / (speed * dt) if speed > 0 else 0.0)
        return False

    def velocity(self, vn, ve, vd, yaw_rate, dt):
        """Fly at a velocity (m/s NED), within the speed limits, turning at yaw_rate (rad/s)."""
        sim = self.sim
        h = math.sqrt(vn * vn + ve * ve)
        if h > self.speed > 0:
            vn, ve = vn * self.speed / h, ve * self.speed / h
        vd = max(-self.climb, min(self.sink, vd))
        if vd > 0 and sim.alt - vd * dt < self.ground():
            vd = max(0.0, (sim.alt - self.ground()) / dt)
        elif vd < 0 and sim.alt - vd * dt > self.ground() + CEILING:
            vd = 0.0
        sim.heading += yaw_rate * dt
        sim.target = None
        self.moved(vn * dt, ve * dt, vd * dt, dt, min(1.0, h / self.speed) if self.speed > 0 else 0.0)

    def moved(self, mn, me, md, dt, speed_share):
        sim = self.sim
        sim.vn, sim.ve, sim.vd = mn / dt, me / dt, md / dt
        if sim.trigger_dist > 0:  # DO_SET_CAM_TRIGG_DIST: a photo every so many metres
            self.travel += math.sqrt(mn * mn + me * me)
            if self.travel >= sim.trigger_dist:
                shots = int(self.travel // sim.trigger_dist)
                sim.photos += shots
                self.travel -= shots * sim.trigger_dist
        # Lean into the motion: a quadrotor tilts to accelerate and hold speed.
        sim.pitch = -0.25 * speed_share
        sim.roll = 0.0
        sim.throttle = 0.55 + (0.15 if md < 0 else -0.1 if md > 0 else 0.0)
        sim.move(mn, me, md)

    def turn(self, target_deg, rate, dt):
        sim = self.sim
        now = math.degrees(sim.heading) % 360.0
        err = (target_deg - now + 180.0) % 360.0 - 180.0
        turn = rate * dt
        if abs(err) <= turn:
            sim.heading = math.radians(target_deg)
            return True
        sim.heading = math.radians(now + (turn if err > 0 else -turn))
        return False

    def hold(self):
        """Stay where it is: hovering in the air, idle (or stopped) on the ground."""
        sim = self.sim
        sim.vn = sim.ve = sim.vd = 0.0
        sim.pitch = sim.roll = 0.0
        status = self.status
        armed = status is not None and status.armed
        on_ground = sim.alt - self.ground() < 0.05
        sim.throttle = (0.1 if on_ground else 0.5) if armed else 0.0


def _bearing(sim, point):
    """Radians from north from the simulated vehicle to (lat, lon, ...)."""
    dn = math.radians(point[0] - sim.lat) * EARTH_RADIUS
    de = math.radians(point[1] - sim.lon) * EARTH_RADIUS * math.cos(math.radians(sim.lat))
    return math.atan2(de, dn) if dn or de else sim.heading


def distance(lat1, lon1, lat2, lon2):
    """Metres between two points (flat earth: fine over a field)."""
    dn = math.radians(lat2 - lat1) * EARTH_RADIUS
    de = math.radians(lon2 - lon1) * EARTH_RADIUS * math.cos(math.radians(lat1))
    return math.sqrt(dn * dn + de * de)
