"""The simulated vehicle behind boards/unix.py: a simple kinematic model that flies
the mission in AUTO mode and feeds telemetry, so a ground station sees a live vehicle.

It is an application like any other: it reads and writes the endpoint's services
and allocates freely (it stands in for real sensors and control code).
"""
import math

from mavstack.compat import ticks_diff

HOME_LAT = 47.397742  # a field where ground stations' maps have tiles
HOME_LON = 8.545594
HOME_ALT = 488.0
EARTH_RADIUS = 6378137.0
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
        self._last = None
        self._status_hooks()

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
        status.on_gcs_lost = self._gcs_lost
        status.on_gcs_regained = self._gcs_regained
        veto = getattr(self.ep, "options", {}).get("arm_veto")
        if veto:  # --set arm_veto=1 refuses arming (DENIED), =2 asks to retry later
            self._veto = 2 if veto == "2" else 1
            status.arm_check = self._arm_check

    def position_e7(self):
        return round(self.lat * 1e7), round(self.lon * 1e7), round(self.alt * 1000)

    def _arm_check(self, arm):
        if not arm:
            return None
        if self._veto == 2:
            return 1, "simulated sensors warming up"  # MAV_RESULT_TEMPORARILY_REJECTED
        return "simulated pre-arm check failed"

    def _gcs_lost(self, link):
        # A real vehicle would fail safe here (return to launch, land).
        self.ep.statustext(4, "GCS lost on " + link.name)

    def _gcs_regained(self, link):
        self.ep.statustext(6, "GCS heard on " + link.name)

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
        """Advance the model: in AUTO and armed, fly toward the current mission item."""
        pilot = getattr(self, "_pilot", None)
        if pilot is None:
            pilot = self._pilot = MissionPilot(self)
        pilot.step(dt)

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
                           round(self.vn * 100), round(self.ve * 100), round(self.vd * 100), round(hdg * 100) % 36000)
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
        press = 1013.25 * (1.0 - 2.25577e-5 * self.alt) ** 5.25588
        temp = 15.0 - 0.0065 * self.alt
        tm.scaled_pressure(press, 0.0, round(temp * 100))
        tm.raw_pressure(round(press * 10) & 0x7FFF, 0, 0, round(temp * 100))
        tm.highres_imu(ax * 0.00980665, ay * 0.00980665, az * 0.00980665, p, q, r, mx / 1000, my / 1000, mz / 1000,
                       press, 0.0, self.alt, temp, 0x1FFF)
        tm.optical_flow(0, 0, 0, self.vn, self.ve, 255 if rel > 0.3 else 0, max(rel, 0.0))

        pub["gps_age"] += dt
        if pub["gps_age"] >= 0.2:  # a GPS receiver reports at 5 Hz
            pub["gps_age"] = 0.0
            tm.gps_raw(3, lat_e7, lon_e7, round(self.alt * 1000), 80, 120, round(speed * 100),
                       round(cog * 100) % 36000 if speed > 0.2 else 0xFFFF, len(_SATS),
                       round((self.alt + 47.0) * 1000), 1200, 1800, 150)
            tm.gps_status(len(_SATS), [s[0] for s in _SATS], [1] * len(_SATS),
                          [s[1] for s in _SATS], [s[2] * 256 // 360 for s in _SATS], [s[3] for s in _SATS])

        self._publish_rc(tm, armed)
        self._publish_battery(tm, dt, armed)
        landed = 1
        if rel > 0.5 or (armed and self.vd < -0.2):
            landed = 3 if self.vd < -0.5 and rel < 5 else 4 if self.vd > 0.5 and rel < 5 else 2
        tm.extended_sys_state(0, landed)
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
        """Move by metres north, east and down."""
        self.lat += math.degrees(dn / EARTH_RADIUS)
        self.lon += math.degrees(de / (EARTH_RADIUS * math.cos(math.radians(self.lat))))
        self.alt -= dd


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


class MissionPilot:
    """Flies the mission for the simulator: the current item from the mission runner,
    carried out with a kinematic model (horizontal speed, climb rate, turn rate).

    Speeds and the default acceptance radius are the parameters WP_SPEED, WP_SPEED_UP,
    WP_SPEED_DN, WP_ACCEPT_RAD and SIM_YAW_RATE, read at each new item;
    `--set sim_speed=M/S` (and sim_climb) override them, beyond their ranges, for
    tests that fly a whole mission in a second. A NAV_WAYPOINT is reached within its
    param2 (WP_ACCEPT_RAD when 0) and held there for param1 seconds.

    Today's planners' commands: NAV_DELAY holds for param1 seconds (or until the UTC
    time of day in param2-4); DO_CHANGE_SPEED changes the speed (param1: 0/1
    horizontal, 2 climb, 3 descent; param2 -1 no change, -2 back to the parameter) until
    the mission starts over; NAV_LOITER_TO_ALT flies to its position, then to its
    altitude; a takeoff, land or loiter without a position (x, y unset or 0) happens
    where the vehicle is. A region of interest (DO_SET_ROI_LOCATION, DO_SET_ROI with
    mode 3, NAV_ROI) turns the vehicle's nose to it until DO_SET_ROI_NONE; the camera
    and gimbal commands are kept on the simulator (sim.roi, sim.gimbal, sim.photos,
    sim.trigger_dist, sim.video) as a payload would act on them; DO_LAND_START only
    marks where a landing sequence begins.
    """

    def __init__(self, sim):
        self.sim = sim
        ep = sim.ep
        self.options = getattr(ep, "options", None) or {}
        self.params = ep.services.get("params")
        self.missions = ep.services.get("missions")
        self.status = ep.services.get("status")
        self._settings()
        self._seq = -1
        self._started = None
        self._arrived = 0.0  # seconds spent at the item's position
        self._yaw_target = None
        self._changed = {}  # DO_CHANGE_SPEED's speeds ("speed", "climb", "sink") until a restart
        self._wait = None  # NAV_DELAY: seconds to wait
        self._travel = 0.0  # metres flown since the last distance-triggered photo

    def step(self, dt):
        runner = self.missions.runner if self.missions is not None else None
        status = self.status
        flying = status is not None and status.armed and status.auto
        if runner is None or not flying:
            if runner is not None and runner.running:
                runner.pause()
            self.sim.target = None
            self._hold()
            return
        if not runner.run() or runner.waiting or runner.item is None:
            self._hold()
            return
        item = runner.item
        if item.seq != self._seq or runner.started_ms != self._started:
            self._seq = item.seq
            self._started = runner.started_ms
            self._arrived = 0.0
            self._yaw_target = None
            self._wait = None
            if item.seq == 0:
                self._changed.clear()  # the mission starts over: speeds from the parameters
                self.sim.roi = None
            self._settings()
        if self._do(item, dt):
            runner.reached()

    def _settings(self):
        def setting(option, param, default):
            if option in self.options:
                return float(self.options[option])
            if self.params is not None:
                try:
                    return float(self.params.get(param))
                except (KeyError, ValueError):
                    pass
            return default

        self.speed = setting("sim_speed", "WP_SPEED", 5.0)
        self.climb = setting("sim_climb", "WP_SPEED_UP", 2.5)
        self.sink = setting("sim_climb", "WP_SPEED_DN", 1.5)
        self.radius = setting("sim_accept_radius", "WP_ACCEPT_RAD", 2.0)
        self.turn_rate = setting("sim_yaw_rate", "SIM_YAW_RATE", 90.0)
        for name, value in getattr(self, "_changed", {}).items():
            setattr(self, name, value)

    # --- one item -----------------------------------------------------------------
    def _do(self, item, dt):
        """Carry out the item for dt seconds -> True once it is done."""
        sim = self.sim
        cmd = item.command
        if cmd in (16, 17, 18, 19):  # WAYPOINT, LOITER_UNLIM, LOITER_TURNS, LOITER_TIME
            lat, lon, alt = self._position(item)
            radius = item.param2 if cmd == 16 and item.param2 > 0 else self.radius
            if not self._go(lat, lon, alt, dt, radius):
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
            lat, lon, alt = self._home()
            if not self._go(lat, lon, max(sim.alt, alt), dt, self.radius):
                return False
            return self._go(lat, lon, alt, dt, 0.5)
        if cmd == 21:  # LAND, at the item's position or here
            lat, lon, alt = self._position(item)
            if not self._go(lat, lon, sim.alt, dt, self.radius):
                return False
            ground = self._home()[2] if math.isnan(item.z) else alt
            return self._go(lat, lon, ground, dt, 0.2)
        if cmd == 22:  # TAKEOFF, straight up
            return self._go(sim.lat, sim.lon, self._position(item)[2], dt, 0.5)
        if cmd == 112:  # CONDITION_DELAY
            self._hold()
            self._arrived += dt
            return self._arrived >= item.param1
        if cmd == 113:  # CONDITION_CHANGE_ALT, at param1 m/s
            rate = abs(item.param1) or self.climb
            return self._go(sim.lat, sim.lon, self._position(item)[2], dt, 0.5, climb=rate)
        if cmd == 114:  # CONDITION_DISTANCE: on toward the next NAV item until that close
            nxt = self.missions.runner.next_nav()
            if nxt is None:
                return True
            lat, lon, alt = self._position(nxt)
            return self._go(lat, lon, alt, dt, max(item.param1, self.radius))
        if cmd == 115:  # CONDITION_YAW: param1 deg, param2 deg/s, param3 direction, param4 relative
            if self._yaw_target is None:
                base = math.degrees(sim.heading) if item.param4 == 1 else 0.0
                sign = -1.0 if item.param4 == 1 and item.param3 < 0 else 1.0
                self._yaw_target = (base + sign * item.param1) % 360.0
            self._hold()
            return self._turn(self._yaw_target, item.param2 or self.turn_rate, dt)
        if cmd == 178:  # DO_CHANGE_SPEED
            self._change_speed(item)
            return True
        if cmd == 93:  # NAV_DELAY
            return self._delay(item, dt)
        if cmd == 31:  # NAV_LOITER_TO_ALT: there at the altitude it has, then to the item's
            lat, lon, alt = self._position(item)
            if self._arrived == 0.0 and not self._go(lat, lon, sim.alt, dt, self.radius):
                return False
            self._arrived += dt
            return self._go(lat, lon, alt, dt, 0.5)
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

    def _home(self):
        status = self.status
        if status is not None and status.home_set:
            return status.home_lat / 1e7, status.home_lon / 1e7, status.home_alt / 1000.0
        return HOME_LAT, HOME_LON, HOME_ALT

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
            alt += self._home()[2]
        return lat, lon, alt

    def _change_speed(self, item):
        # param1: 0 airspeed, 1 ground speed (both the horizontal speed here), 2 climb,
        # 3 descent; param2: the speed, -1 no change, -2 back to the parameter's.
        name = ("speed", "speed", "climb", "sink")[int(item.param1)] if 0 <= item.param1 < 4 else "speed"
        if item.param2 == -2:
            self._changed.pop(name, None)
            self._settings()
        elif 0 < item.param2 < 1e6:  # (a finite speed, whatever a plan says)
            self._changed[name] = item.param2
            setattr(self, name, item.param2)

    def _delay(self, item, dt):
        """NAV_DELAY: hold for param1 s, or (param1 -1) until hour:minute:second UTC in
        param2-4 (-1: any hour, any minute)."""
        self._hold()
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
            self._travel = 0.0
            sim.photos = sim.photos + (1 if item.param3 == 1 and item.param1 > 0 else 0)
        elif cmd == 214:  # DO_SET_CAM_TRIGG_INTERVAL
            sim.trigger_dist = 0.0
        elif cmd == 2000:  # IMAGE_START_CAPTURE: one photo (the interval's are not simulated)
            sim.photos = sim.photos + 1
        elif cmd == 2001:
            sim.trigger_dist = 0.0
        else:  # VIDEO_START_CAPTURE / VIDEO_STOP_CAPTURE
            sim.video = cmd == 2500

    # --- motion -------------------------------------------------------------------
    def _go(self, lat, lon, alt, dt, radius, climb=None):
        """Move toward a point for dt seconds -> True once within radius."""
        sim = self.sim
        sim.target = (lat, lon, alt)
        dn = math.radians(lat - sim.lat) * EARTH_RADIUS
        de = math.radians(lon - sim.lon) * EARTH_RADIUS * math.cos(math.radians(sim.lat))
        du = alt - sim.alt
        dist = math.sqrt(dn * dn + de * de)
        if math.sqrt(dist * dist + du * du) <= radius:
            self._hold()
            return True
        step = min(self.speed * dt, dist)
        vstep = min((climb or (self.climb if du > 0 else self.sink)) * dt, abs(du))
        mn = dn / dist * step if dist > 0 else 0.0
        me = de / dist * step if dist > 0 else 0.0
        md = -vstep if du > 0 else vstep
        sim.vn, sim.ve, sim.vd = mn / dt, me / dt, md / dt
        if sim.trigger_dist > 0:  # DO_SET_CAM_TRIGG_DIST: a photo every so many metres
            self._travel += step
            if self._travel >= sim.trigger_dist:
                shots = int(self._travel // sim.trigger_dist)
                sim.photos += shots
                self._travel -= shots * sim.trigger_dist
        if sim.roi is not None:
            sim.heading = _bearing(sim, sim.roi)  # the nose on the region of interest
        elif dist > 0.5:
            sim.heading = math.atan2(de, dn)
        # Lean into the motion: a quadrotor tilts to accelerate and hold speed.
        speed_share = step / (self.speed * dt) if self.speed > 0 else 0.0
        sim.pitch = -0.25 * speed_share
        sim.roll = 0.0
        sim.throttle = 0.55 + (0.15 if du > 0 else -0.1 if du < 0 else 0.0)
        sim.move(mn, me, md)
        return False

    def _turn(self, target_deg, rate, dt):
        sim = self.sim
        now = math.degrees(sim.heading) % 360.0
        err = (target_deg - now + 180.0) % 360.0 - 180.0
        turn = rate * dt
        if abs(err) <= turn:
            sim.heading = math.radians(target_deg)
            return True
        sim.heading = math.radians(now + (turn if err > 0 else -turn))
        return False

    def _hold(self):
        sim = self.sim
        sim.vn = sim.ve = sim.vd = 0.0
        sim.pitch = sim.roll = 0.0
        status = self.status
        airborne = status is not None and status.armed
        sim.throttle = 0.5 if airborne else 0.0



def _bearing(sim, point):
    """Radians from north from the simulated vehicle to (lat, lon, ...)."""
    dn = math.radians(point[0] - sim.lat) * EARTH_RADIUS
    de = math.radians(point[1] - sim.lon) * EARTH_RADIUS * math.cos(math.radians(sim.lat))
    return math.atan2(de, dn) if dn or de else sim.heading


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
