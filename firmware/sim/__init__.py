"""The simulated vehicle behind boards/unix.py: its state (position, speeds, attitude,
battery, payload) and the telemetry a real vehicle's sensors and estimator would feed,
so a ground station sees a live vehicle. What it does in each flight mode is the flight
pilot's (pilot.py); how it moves, motion.py's; the mission, mission.py's; pilot inputs,
inputs.py's. It is an application like any other: it reads and writes the endpoint's
services and allocates freely (it stands in for real sensors and control code).
Reference: docs/sim.md.
"""
import math

from mavstack.compat import ticks_diff

from .motion import EARTH_RADIUS, HOME_ALT, HOME_LAT, HOME_LON
from .pilot import FlightPilot

# MAV_SYS_STATUS_SENSOR: gyro, accel, mag, baro, GPS, rate/attitude/yaw/altitude/position control, motors
SIM_SENSORS = 1 | 2 | 4 | 8 | 32 | 1024 | 2048 | 4096 | 8192 | 16384 | 32768


def _int16(x):
    return max(-32768, min(32767, round(x)))


class Simulator:
    def __init__(self, endpoint):
        self.ep = endpoint
        self.lat = HOME_LAT
        self.lon = HOME_LON
        self.alt = HOME_ALT  # metres above mean sea level
        self.vn = 0.0  # north, east, down speeds (m/s)
        self.ve = 0.0
        self.vd = 0.0
        self.heading = 0.0  # radians
        self.roll = 0.0
        self.pitch = 0.0
        self.throttle = 0.0  # 0..1
        self.battery_v = 12.6
        self.battery_remaining = 100.0  # percent
        # The payload, as mission commands set it (MissionPilot).
        self.roi = None  # (lat, lon, alt MSL) the nose points at
        self.gimbal = (0.0, 0.0)  # pitch, yaw (deg)
        self.photos = 0
        self.trigger_dist = 0.0  # m between photos, 0: off
        self.video = False
        self.start = (HOME_LAT, HOME_LON, HOME_ALT)
        self.target = None  # (lat, lon, alt MSL) flown toward, for NAV_CONTROLLER_OUTPUT
        self.landed_state = 1  # MAV_LANDED_STATE, the flight pilot's: ON_GROUND
        self._last = None
        self._status_hooks()
        self.pilot = FlightPilot(self)
        self._pilot = self.pilot.mission  # the motion model and its speeds

    # --- status: home, clock, sensors, arming checks, ground-station fail-safe ---
    def _status_hooks(self):
        status = self.ep.services.get("status")
        if status is None:
            return
        import time

        status.set_home(round(HOME_LAT * 1e7), round(HOME_LON * 1e7), round(HOME_ALT * 1000))
        status.position = self.position_e7
        status.set_clock(time.time_ns() // 1000)  # the host's clock is this vehicle's RTC
        status.set_sensors(SIM_SENSORS, SIM_SENSORS, SIM_SENSORS)
        status.set_battery(round(self.battery_v * 1000), -1, round(self.battery_remaining))
        veto = getattr(self.ep, "options", {}).get("arm_veto")
        # --set arm_veto=1 refuses arming (DENIED), =2 asks to retry later
        self._veto = (2 if veto == "2" else 1) if veto else 0

    def position_e7(self):
        return round(self.lat * 1e7), round(self.lon * 1e7), round(self.alt * 1000)

    def pre_arm_check(self):
        """The simulated sensors' answer to arming (--set arm_veto) -> None | reason | (MAV_RESULT, reason)."""
        if self._veto == 2:
            return 1, "simulated sensors warming up"  # MAV_RESULT_TEMPORARILY_REJECTED
        if self._veto:
            return "simulated pre-arm check failed"
        return None

    def failsafe(self, reason):
        """An input the vehicle flies by is lost: hold, then return (failsafe.py)."""
        self.pilot.failsafe.trip(reason)

    def failsafe_clear(self, reason):
        """The lost input is back: no return after the hold."""
        self.pilot.failsafe.clear(reason)

    def tick(self, now):
        if self._last is None:
            self._last = now
            return
        dt = ticks_diff(now, self._last) / 1000.0
        if dt < 0.02:
            return
        self._last = now
        self.fly(dt)
        self.publish(now)

    def fly(self, dt):
        """Advance the model by dt seconds, as the flight mode says."""
        self.pilot.step(dt)

    def publish(self, now):
        """Write the model's state into the telemetry slots (ep.telemetry), as a
        real vehicle's sensors and estimator would: position, attitude and its
        rates, IMU, barometer, GPS, RC inputs, motor outputs, battery."""
        tm = getattr(self.ep, "telemetry", None)
        if tm is None:
            return
        if getattr(self, "_pub", None) is None:
            self._publish_init(tm)
        pub = self._pub
        dt = ticks_diff(now, pub["last"]) / 1000.0
        pub["last"] = now
        if dt <= 0:
            dt = 0.02
        status = self.ep.services.get("status")
        armed = bool(status and status.armed)
        yaw = math.atan2(math.sin(self.heading), math.cos(self.heading))
        p, q, r = self._rates(pub, dt, yaw)
        roll, pitch = self.roll, self.pitch
        home_alt = status.home_alt / 1000.0 if status is not None and status.home_set else HOME_ALT
        rel = self.alt - home_alt
        speed = math.sqrt(self.vn * self.vn + self.ve * self.ve)
        cog = math.degrees(math.atan2(self.ve, self.vn)) % 360.0
        hdg = math.degrees(self.heading) % 360.0
        lat_e7 = round(self.lat * 1e7)
        lon_e7 = round(self.lon * 1e7)

        tm.attitude(roll, pitch, yaw, p, q, r)
        qw, qx, qy, qz = _quaternion(roll, pitch, yaw)
        tm.attitude_quaternion(qw, qx, qy, qz, p, q, r)
        tm.global_position(lat_e7, lon_e7, round(self.alt * 1000), round(rel * 1000),
                           _int16(self.vn * 100), _int16(self.ve * 100), _int16(self.vd * 100),
                           round(hdg * 100) % 36000)
        x = math.radians(self.lat - HOME_LAT) * EARTH_RADIUS
        y = math.radians(self.lon - HOME_LON) * EARTH_RADIUS * math.cos(math.radians(self.lat))
        tm.local_position(x, y, -(self.alt - HOME_ALT), self.vn, self.ve, self.vd)
        tm.vfr_hud(speed, speed, int(hdg) % 360, int(self.throttle * 100), self.alt, -self.vd)
        self._publish_nav(tm, hdg, rel)

        # IMU: gravity seen in the body frame, turn rates, the earth's field turned by heading.
        g = 1000.0
        ax = g * math.sin(pitch)
        ay = -g * math.sin(roll) * math.cos(pitch)
        az = -g * math.cos(roll) * math.cos(pitch)
        mx = 210.0 * math.cos(self.heading)
        my = -210.0 * math.sin(self.heading)
        mz = 430.0
        # Rates in mrad/s fill int16 fields: a turn made at once (a new waypoint's bearing)
        # would overflow them, so they saturate, as a real gyro's range does.
        imu = (round(ax), round(ay), round(az), _int16(p * 1000), _int16(q * 1000), _int16(r * 1000),
               round(mx), round(my), round(mz))
        tm.scaled_imu(*imu)
        tm.raw_imu(*imu)
        air = 1.0 - 2.25577e-5 * self.alt  # (none from 44 km up: a negative base's power is complex)
        press = 1013.25 * air ** 5.25588 if air > 0.0 else 0.0
        temp = 15.0 - 0.0065 * self.alt
        tm.scaled_pressure(press, 0.0, _int16(temp * 100))
        tm.raw_pressure(round(press * 10) & 0x7FFF, 0, 0, _int16(temp * 100))
        tm.highres_imu(ax * 0.00980665, ay * 0.00980665, az * 0.00980665, p, q, r, mx / 1000, my / 1000, mz / 1000,
                       press, 0.0, self.alt, temp, 0x1FFF)
        tm.optical_flow(0, 0, 0, self.vn, self.ve, 255 if rel > 0.3 else 0, max(rel, 0.0))

        pub["gps_age"] += dt
        if pub["gps_age"] >= 0.2:  # a GPS receiver reports at 5 Hz
            pub["gps_age"] = 0.0
            tm.gps_raw(3, lat_e7, lon_e7, round(self.alt * 1000), 80, 120, min(round(speed * 100), 0xFFFE),
                       round(cog * 100) % 36000 if speed > 0.2 else 0xFFFF, len(_SATS),
                       round((self.alt + 47.0) * 1000), 1200, 1800, 150)
            tm.gps_status(len(_SATS), [s[0] for s in _SATS], [1] * len(_SATS),
                          [s[1] for s in _SATS], [s[2] * 256 // 360 for s in _SATS], [s[3] for s in _SATS])

        self._publish_rc(tm, armed)
        self._publish_battery(tm, dt, armed)
        tm.extended_sys_state(0, self.landed_state)  # (not a VTOL)
        tm.named_value_float(b"sim_dt", dt)
        tm.named_value_int(b"sim_pub", pub["count"])
        tm.debug(0, self.throttle)
        tm.debug_vect(b"vel_ned", self.vn, self.ve, self.vd)
        pub["count"] += 1

    def _publish_init(self, tm):
        # Once: the state publish() keeps between calls.
        self._pub = {"last": self.ep.now, "gps_age": 1.0, "count": 0, "att": None, "consumed": 0.0}

    def _rates(self, pub, dt, yaw):
        # Body rates from the change of attitude since the last publish.
        prev = pub["att"]
        pub["att"] = (self.roll, self.pitch, yaw)
        if prev is None:
            return 0.0, 0.0, 0.0
        dy = math.atan2(math.sin(yaw - prev[2]), math.cos(yaw - prev[2]))
        return (self.roll - prev[0]) / dt, (self.pitch - prev[1]) / dt, dy / dt

    def _publish_nav(self, tm, hdg, rel):
        # Toward self.target (lat, lon, alt MSL) when fly() has one, else holding.
        target = getattr(self, "target", None)
        if target is None:
            tm.nav_controller(math.degrees(self.roll), math.degrees(self.pitch), int(hdg), int(hdg), 0, 0.0, 0.0, 0.0)
            return
        dn = math.radians(target[0] - self.lat) * EARTH_RADIUS
        de = math.radians(target[1] - self.lon) * EARTH_RADIUS * math.cos(math.radians(self.lat))
        bearing = int(math.degrees(math.atan2(de, dn)) % 360.0)
        dist = int(math.sqrt(dn * dn + de * de))
        alt_err = (target[2] - self.alt) if len(target) > 2 else 0.0
        tm.nav_controller(math.degrees(self.roll), math.degrees(self.pitch), bearing, bearing,
                          min(dist, 0xFFFF), alt_err, 0.0, 0.0)

    def _publish_rc(self, tm, armed):
        # A transmitter: sticks follow the attitude and throttle, channel 5 the flight mode.
        status = self.ep.services.get("status")
        auto = bool(status and status.auto)

        def stick(v, full):
            return max(1000, min(2000, 1500 + round(v / full * 500)))

        roll_ch = stick(self.roll, 0.6)
        pitch_ch = stick(-self.pitch, 0.6)
        thr_ch = 1000 + round(self.throttle * 1000)
        tm.rc_channels((roll_ch, pitch_ch, thr_ch, 1500, 1900 if auto else 1100, 1500, 1000, 1000), 230)
        if not armed:
            tm.servo_output((1000, 1000, 1000, 1000))
            return
        # Quad X mix: front-right, rear-left, front-left, rear-right.
        base = 1000 + self.throttle * 1000
        rl = (self.roll / 0.6) * 150
        pt = (self.pitch / 0.6) * 150
        motors = (base - rl + pt, base + rl - pt, base + rl + pt, base - rl - pt)
        tm.servo_output(tuple(max(1000, min(2000, round(m))) for m in motors))

    def _publish_battery(self, tm, dt, armed):
        # 3S 5000 mAh pack: 0.4 A of electronics, up to 25 A more with the throttle.
        pub = self._pub
        current = 0.4 + (25.0 * self.throttle if armed else 0.0)
        pub["consumed"] += current * dt / 3.6  # mAh
        self.battery_remaining = max(0.0, 100.0 - pub["consumed"] / 50.0)
        cell = 3.3 + 0.9 * self.battery_remaining / 100.0 - 0.004 * current
        self.battery_v = 3 * cell
        cells = (round(cell * 1000), round(cell * 1000) + 4, round(cell * 1000) - 3)
        left_mah = 5000.0 * self.battery_remaining / 100.0
        tm.battery(sum(cells), round(current * 100), int(self.battery_remaining), round(pub["consumed"]), cells,
                   0, round((25.0 + 5.0 * self.throttle) * 100), -1, int(left_mah / (current * 1000.0) * 3600.0))

    def move(self, dn, de, dd):
        """Move by metres north, east and down (not below the ground: the home altitude),
        but not out of the safety area (services/geography.py): a step that would cross
        its border is not taken, so the vehicle stops there, whatever flies it (sticks,
        setpoints, a mission); one that brings it back in from outside is."""
        lat = self.lat + math.degrees(dn / EARTH_RADIUS)
        lon = self.lon + math.degrees(de / (EARTH_RADIUS * math.cos(math.radians(self.lat))))
        if not self._inside(lat, lon) and self._inside(self.lat, self.lon):
            self.vn = self.ve = 0.0
            if not self._at_border:
                self._at_border = True
                self.ep.statustext(4, "Stopped at the allowed area's border")
            lat, lon = self.lat, self.lon
        else:
            self._at_border = False
        self.lat, self.lon = lat, lon
        self.alt = max(self.alt - dd, self.pilot.mission.ground())

    _at_border = False

    def _inside(self, lat, lon):
        # Horizontally: the area's altitudes are in its frame's sense (MSL or relative).
        geo = self.ep.services.get("geography")
        if geo is None or not geo.area_set:
            return True
        if not geo.area_local:
            return geo.allows_degrees(lat, lon)
        x = math.radians(lat - HOME_LAT) * EARTH_RADIUS
        y = math.radians(lon - HOME_LON) * EARTH_RADIUS * math.cos(math.radians(lat))
        return geo.allows_local(x, y)


# Satellites in view: prn, elevation (deg), azimuth (deg), snr (dB).
_SATS = ((2, 64, 45, 44), (5, 31, 120, 38), (7, 12, 200, 30), (9, 55, 300, 42), (13, 22, 80, 35),
         (15, 40, 160, 40), (18, 70, 250, 46), (20, 18, 20, 31), (24, 35, 330, 37), (27, 48, 100, 41),
         (29, 27, 230, 36), (30, 60, 10, 43))


def _quaternion(roll, pitch, yaw):
    """w, x, y, z of a roll-pitch-yaw (ZYX) attitude."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)
