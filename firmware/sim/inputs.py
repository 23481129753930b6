"""The simulated vehicle's pilot: turns the inputs service's records into motion demands
for the flight pilot (demand(mode, dt): a velocity, a point, or None to hold), vets
OFFBOARD (mode_check), and trips the simulator's failsafe when the inputs a mode flies
by stop. Reference: docs/sim.md.
"""
import math

from mavstack.services import inputs as _inputs

from .motion import EARTH_RADIUS, HOME_ALT, HOME_LAT, HOME_LON

MANUAL_MODES = ("STABILIZE", "ALT_HOLD", "POSITION")
OFFBOARD = "OFFBOARD"
_DEADBAND = 0.05
_UNUSED = 32767  # MANUAL_CONTROL: INT16_MAX, the axis is not sent
_TILT_FULL = 0.6  # rad: an attitude target's tilt that asks for full speed
_YAW_GAIN = 2.0  # 1/s: a yaw target turned into a yaw rate
# MAV_FRAME
_LOCAL_NED = 1
_LOCAL_OFFSET_NED = 7
_BODY_NED = 8
_BODY_OFFSET_NED = 9
_BODY_FRD = 12
_LOCAL_FRD = 20
_GLOBAL_RELATIVE = (3, 6, 10, 11)  # relative to home (terrain frames: as relative)
_FAR = 1e7  # m, m/s, rad, rad/s: a demand beyond it (or NaN, or infinite) is no demand


class PilotInputs:
    def __init__(self, sim):
        self.sim = sim
        self.ep = sim.ep
        self.inputs = self.ep.services.get("inputs")
        self.mode = None  # the mode of the last demand(): what a loss means
        self.failsafes = 0
        if self.inputs is not None:
            self.inputs.on_input_lost = self._lost

    # --- limits -----------------------------------------------------------------
    def _param(self, name, option, default):
        opts = getattr(self.ep, "options", None) or {}
        if opts.get(option):
            return float(opts[option])
        params = self.ep.services.get("params")
        if params is not None:
            try:
                v = params.get(name)
                if v is not None and v > 0:
                    return float(v)
            except Exception:
                pass
        return default

    def limits(self):
        """(horizontal m/s, climb m/s, sink m/s, yaw rad/s)"""
        return (self._param("WP_SPEED", "sim_speed", 5.0), self._param("WP_SPEED_UP", "sim_climb", 2.5),
                self._param("WP_SPEED_DN", "sim_climb", 1.5), math.radians(self._param("PILOT_YAW_RATE", "sim_yaw_rate", 90.0)))

    # --- the demand ---------------------------------------------------------------
    def demand(self, mode_name, dt):
        self.mode = mode_name
        if self.inputs is None:
            return None
        if mode_name in MANUAL_MODES:
            sticks = self.sticks()
            return None if sticks is None else self._from_sticks(*sticks)
        if mode_name == OFFBOARD:
            return self._offboard()
        return None

    def sticks(self):
        """(forward, right, up, yaw) each -1..1 from the freshest manual input, or None."""
        m = self.inputs.manual
        rc = self.inputs.rc
        if m is not None and m.fresh() and (rc is None or not rc.fresh() or m.stamp_newer(rc)):
            return _axis(m.x()), _axis(m.y()), _throttle(m.z()), _axis(m.r())
        if rc is not None and rc.fresh() and _any_override(rc):
            return (_pwm(rc.channel(2), -1), _pwm(rc.channel(1), 1), _pwm(rc.channel(3), 1), _pwm(rc.channel(4), 1))
        if m is not None and m.fresh():
            return _axis(m.x()), _axis(m.y()), _throttle(m.z()), _axis(m.r())
        return None

    def _from_sticks(self, fwd, right, up, yaw):
        vmax, climb, sink, yaw_max = self.limits()
        h = self.sim.heading
        c, s = math.cos(h), math.sin(h)
        fwd, right = fwd * vmax, right * vmax
        vd = -up * (climb if up > 0 else sink)
        return ("vel", fwd * c - right * s, fwd * s + right * c, vd, yaw * yaw_max)

    def _offboard(self):
        best = None
        for r in (self.inputs.position_local, self.inputs.position_global, self.inputs.attitude):
            if r is not None and r.fresh() and (best is None or r.stamp_newer(best)):
                best = r
        if best is None:
            return None
        if best is self.inputs.attitude:
            return _sane(self._attitude(best))
        return _sane(self._target(best, best is self.inputs.position_global))

    def _target(self, r, is_global):
        frame = r.frame()
        sim = self.sim
        if r.uses_position():
            yaw = r.f(40) if r.uses_yaw() else None
            if frame in (_BODY_NED, _BODY_OFFSET_NED, _BODY_FRD) and yaw is not None:
                yaw += sim.heading
            if is_global:
                alt = r.f(12)
                if frame in _GLOBAL_RELATIVE:
                    alt += self._home_alt()
                return ("pos", r.lat_e7() / 1e7, r.lon_e7() / 1e7, alt, yaw)
            n, e, d = r.f(4), r.f(8), r.f(12)
            if frame in (_BODY_NED, _BODY_OFFSET_NED, _BODY_FRD):
                n, e = _rotate(n, e, sim.heading)
            if frame in (_LOCAL_OFFSET_NED, _BODY_NED, _BODY_OFFSET_NED, _BODY_FRD):
                return ("pos",) + _offset(sim.lat, sim.lon, sim.alt, n, e, d) + (yaw,)
            lat0, lon0, alt0 = self._origin()
            return ("pos",) + _offset(lat0, lon0, alt0, n, e, d) + (yaw,)
        if r.uses_velocity():
            vn, ve, vd = r.f(16), r.f(20), r.f(24)
            if frame in (_BODY_NED, _BODY_OFFSET_NED, _BODY_FRD):
                vn, ve = _rotate(vn, ve, sim.heading)
            return ("vel", vn, ve, vd, self._yaw_rate(r))
        return None

    def _yaw_rate(self, r):
        if r.uses_yaw_rate():
            return r.f(44)
        if r.uses_yaw() and math.isfinite(r.f(40)):  # (an infinite yaw is none: sin raises)
            err = math.atan2(math.sin(r.f(40) - self.sim.heading), math.cos(r.f(40) - self.sim.heading))
            yaw_max = self.limits()[3]
            return max(-yaw_max, min(yaw_max, err * _YAW_GAIN))
        return 0.0

    def _attitude(self, r):
        # Tilt asks for speed, thrust above or below 0.5 for climb or sink.
        vmax, climb, sink, yaw_max = self.limits()
        roll = pitch = 0.0
        yaw_rate = 0.0
        if r.uses_attitude():
            w, x, y, z = r.f(4), r.f(8), r.f(12), r.f(16)
            roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
            pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
            yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            err = math.atan2(math.sin(yaw - self.sim.heading), math.cos(yaw - self.sim.heading))
            yaw_rate = max(-yaw_max, min(yaw_max, err * _YAW_GAIN))
        if r.uses_rate(2):
            yaw_rate = r.f(28)
        up = (r.f(32) - 0.5) * 2 if r.uses_thrust() else 0.0
        up = max(-1.0, min(1.0, up))
        fwd = max(-1.0, min(1.0, -pitch / _TILT_FULL)) * vmax
        right = max(-1.0, min(1.0, roll / _TILT_FULL)) * vmax
        vn, ve = _rotate(fwd, right, self.sim.heading)
        return ("vel", vn, ve, -up * (climb if up > 0 else sink), yaw_rate)

    def _origin(self):
        # LOCAL_POSITION_NED's origin: the simulator's home.
        return HOME_LAT, HOME_LON, HOME_ALT

    def _home_alt(self):
        status = self.ep.services.get("status")
        if status is not None and status.home_set:
            return status.home_alt / 1000.0
        return self._origin()[2]

    # --- mode vetting and failsafe ----------------------------------------------------
    def mode_check(self, name):
        """For status.flight_mode_check: OFFBOARD is entered only with a setpoint streaming."""
        if name == OFFBOARD and self.inputs is not None and self._offboard() is None:
            return "no offboard setpoint"
        return None

    def _lost(self, kind):
        mode = self.mode
        status = self.ep.services.get("status")
        if status is not None and status.flight_mode is not None:
            mode = status.flight_mode
        if mode in MANUAL_MODES and kind in (_inputs.MANUAL, _inputs.RC):
            if self.sticks() is None:
                self._failsafe("Manual control lost")
        elif mode == OFFBOARD and kind in (_inputs.POSITION_LOCAL, _inputs.POSITION_GLOBAL, _inputs.ATTITUDE):
            if self._offboard() is None:
                self._failsafe("Offboard setpoints lost")

    def _failsafe(self, reason):
        self.failsafes += 1
        fs = getattr(self.sim, "failsafe", None)
        if fs is not None:
            fs(reason)
            return
        # A simulator without its own: hold, and say why.
        status = self.ep.services.get("status")
        if status is not None:
            status.set_flight_mode("LOITER")
        self.ep.statustext(2, "Failsafe: " + reason)


def _axis(v):
    if v == _UNUSED or v == -_UNUSED:
        return 0.0
    f = max(-1.0, min(1.0, v / 1000.0))
    return 0.0 if -_DEADBAND < f < _DEADBAND else f


def _throttle(z):
    # MANUAL_CONTROL z: 0..1000, 500 holds height (-1000..1000 readers see it the same way
    # around the middle); not sent: hold.
    if z == _UNUSED or z == -_UNUSED:
        return 0.0
    f = max(-1.0, min(1.0, (z - 500) / 500.0))
    return 0.0 if -_DEADBAND < f < _DEADBAND else f


def _pwm(v, sign):
    if not v:
        return 0.0  # not overridden: centred
    f = max(-1.0, min(1.0, (v - 1500) / 500.0)) * sign
    return 0.0 if -_DEADBAND < f < _DEADBAND else f


def _any_override(rc):
    return rc.overridden(1) or rc.overridden(2) or rc.overridden(3) or rc.overridden(4)


def _rotate(fwd, right, heading):
    c, s = math.cos(heading), math.sin(heading)
    return fwd * c - right * s, fwd * s + right * c


def _sane(demand):
    """The demand, if its numbers are finite and not absurd and a point is on the globe;
    else None (hold): an infinity flown into made the model's position NaN."""
    if demand is None:
        return None
    for v in demand[1:]:
        if v is not None and not -_FAR < v < _FAR:
            return None
    if demand[0] == "pos" and not (-90.0 <= demand[1] <= 90.0 and -180.0 <= demand[2] <= 180.0):
        return None
    return demand


def _offset(lat, lon, alt, n, e, d):
    lat2 = lat + math.degrees(n / EARTH_RADIUS)
    lon2 = lon + math.degrees(e / (EARTH_RADIUS * math.cos(math.radians(lat))))
    return (lat2, lon2, alt - d)
