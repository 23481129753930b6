"""The simulated vehicle's flight commands: the half of the flight pilot (pilot.py) that
answers ground stations. Each handler returns a MAV_RESULT; a refusal says why in a
STATUSTEXT. NAV_TAKEOFF and NAV_LAND answer IN_PROGRESS (again with their progress) and
finish when the flight does. Reference: docs/sim.md.
"""
import struct

ON_GROUND = 1  # MAV_LANDED_STATE
IN_AIR = 2
TAKING_OFF = 3
LANDING = 4

ACCEPTED = 0  # MAV_RESULT
DENIED = 2
FAILED = 4
IN_PROGRESS = 5
WARNING = 4  # MAV_SEVERITY
INFO = 6
_INT32_MAX = 2147483647
_RELATIVE_FRAMES = (3, 6, 10, 11)  # altitude above home (terrain frames: as above home)
_GLOBAL_FRAMES = (0, 5) + _RELATIVE_FRAMES
_MISSION_ACCEPTED = 0  # MAV_MISSION_RESULT
_MISSION_UNSUPPORTED_FRAME = 2
_MISSION_DENIED = 14
PILOT_MODES = ("STABILIZE", "ALT_HOLD", "POSITION", "OFFBOARD")
_MAX_SPEED = 100.0  # m/s: the fastest a reposition may ask for


class FlightCommands:
    """The command handlers of the flight pilot (pilot.FlightPilot, whose state they use,
    with its set_mode and rules), and the command under way."""

    def take_commands(self):
        """Answer the flight commands, MAVProxy's guided items and the seed's goto."""
        commands = getattr(self.ep, "commands", None)
        if commands is not None:
            commands[22] = self._cmd_takeoff
            commands[21] = self._cmd_land
            commands[20] = self._cmd_rtl
            commands[192] = self._cmd_reposition
            commands[178] = self._cmd_change_speed
            commands[17] = self._cmd_loiter
            commands[193] = self._cmd_pause_continue
            if self.runner is not None:
                commands[300] = self._cmd_mission_start  # (in place of the runner's: it flies)
        if self.missions is not None:
            self.missions.on_guided = self._guided_item
        seed = self.ep.services.get("seed_commands")
        if seed is not None:
            seed.on_goto = self._cmd_goto  # the seed's OVERRIDE_GOTO to a position

    def _cmd_takeoff(self, cmd):
        # param7: metres above home (COMMAND_INT: MSL in frames 0 and 5); NaN:
        # MIS_TAKEOFF_ALT. param4: the heading there (NaN: kept); params 5, 6: where to
        # go once up (unset or 0, 0: straight up here).
        if self.status is None or not self.status.armed:
            return self.refuse(DENIED, "Takeoff: disarmed")
        if self.landed != ON_GROUND:
            return self.refuse(FAILED, "Takeoff: already flying")
        if cmd.is_int and cmd.frame not in _GLOBAL_FRAMES:
            return self.refuse(DENIED, "Takeoff: frame %d not supported" % cmd.frame)
        ground = self.mission.ground()
        if not cmd.finite(7):
            alt = self.mission.setting(None, "MIS_TAKEOFF_ALT", 10.0)
        elif cmd.is_int and cmd.frame in (0, 5):
            alt = cmd.float(7) - ground
        else:
            alt = cmd.float(7)
        if not 0.5 <= alt <= 10000.0:
            return self.refuse(DENIED, "Takeoff: altitude %.1f m out of range" % alt)
        to = self._takeoff_point(cmd)
        if to is not None and not self._allowed(cmd):
            return DENIED
        self.status.conventions.took(cmd.link)
        self.set_mode("TAKEOFF")
        self.climb_to = ground + alt
        self.takeoff_to = to
        self.takeoff_yaw = cmd.float(4) % 360.0 if cmd.finite(4) else None
        self.ep.statustext(INFO, "Takeoff to %.1f m" % alt)
        return self.defer(cmd)

    def _takeoff_point(self, cmd):
        """NAV_TAKEOFF's (lat, lon) to go to once up, None for here (unset, or 0, 0)."""
        if cmd.is_int:
            if cmd.int(5) == _INT32_MAX or cmd.int(6) == _INT32_MAX or not (cmd.int(5) or cmd.int(6)):
                return None
        elif not (cmd.finite(5) and cmd.finite(6)) or not (cmd.float(5) or cmd.float(6)):
            return None
        point = self._point(cmd)
        return (point[0], point[1]) if point is not None else None

    def _cmd_land(self, cmd):
        status = self.status
        if status is None or not status.armed:
            return self.refuse(DENIED, "Land: disarmed")
        if self.landed == ON_GROUND:
            status.arm(False, True)
            self.ep.statustext(INFO, "Land: on the ground: disarmed")
            return ACCEPTED
        if not self._allowed(cmd):
            return DENIED
        at = self._point(cmd)
        status.conventions.took(cmd.link)
        self.set_mode("LAND")
        if at is not None and (at[0] or at[1]):
            self.land_at = (at[0], at[1])
        return self.defer(cmd)

    def _cmd_rtl(self, cmd):
        refused = self.flying("RTL")
        if refused is not None:
            return refused
        self.status.conventions.took(cmd.link)
        self.set_mode("RTL")
        return ACCEPTED

    def _cmd_reposition(self, cmd):
        # param1 speed (-1: default), param4 yaw (NaN: keep), x/y lat/lon (INT32_MAX: keep), z alt.
        refused = self.flying("Reposition")
        if refused is not None:
            return refused
        if cmd.is_int and cmd.frame not in _GLOBAL_FRAMES:
            return self.refuse(DENIED, "Reposition: frame %d not supported" % cmd.frame)
        if not self._allowed(cmd):
            return DENIED
        point = self._point(cmd)
        if point is None:
            return self.refuse(DENIED, "Reposition: position out of range")
        speed = min(cmd.float(1), _MAX_SPEED) if cmd.finite(1) and cmd.float(1) > 0 else None
        yaw = cmd.float(4) % 360.0 if cmd.finite(4) else None
        self.set_mode("GUIDED")
        self.hold_at, self.guided_speed, self.guided_yaw = point, speed, yaw
        return ACCEPTED

    def _cmd_goto(self, cmd):
        # The seed's OVERRIDE_GOTO "hold at the specified position" (the seed_commands
        # service checked the area and control): param3 the MAV_FRAME, param4 yaw (deg),
        # param5-7 the position. Flown as a reposition: GUIDED, there, holding.
        refused = self.flying("Goto")
        if refused is not None:
            return refused
        frame = cmd.int(3) if cmd.finite(3) else 0
        if frame not in _GLOBAL_FRAMES:
            return self.refuse(DENIED, "Goto: frame %d not supported" % frame)
        point = self._point(cmd)
        if point is None:
            return self.refuse(DENIED, "Goto: position out of range")
        if cmd.finite(7) and frame in _RELATIVE_FRAMES and not cmd.is_int:  # (_point did COMMAND_INT's)
            point = (point[0], point[1], point[2] + self.mission.home()[2])
        self.set_mode("GUIDED")
        self.hold_at, self.guided_speed = point, None
        self.guided_yaw = cmd.float(4) % 360.0 if cmd.finite(4) else None
        return ACCEPTED

    def _allowed(self, cmd):
        """Is the command's target inside the safety area (services/geography.py), if the
        board has one? It says why not in a STATUSTEXT."""
        geo = self.ep.services.get("geography")
        return geo is None or geo.allows_command(cmd)

    def _point(self, cmd):
        """(lat, lon, alt MSL) from params 5-7 (each kept from the hold point when unset:
        INT32_MAX or NaN), or None if out of range."""
        here = self.hold_at or (self.sim.lat, self.sim.lon, self.sim.alt)
        if cmd.is_int:
            lat = here[0] if cmd.int(5) == _INT32_MAX else cmd.float(5)
            lon = here[1] if cmd.int(6) == _INT32_MAX else cmd.float(6)
        else:
            lat = cmd.float(5) if cmd.finite(5) else here[0]
            lon = cmd.float(6) if cmd.finite(6) else here[1]
        alt = here[2]
        if cmd.finite(7):
            alt = cmd.float(7)
            if cmd.is_int and cmd.frame in _RELATIVE_FRAMES:
                alt += self.mission.home()[2]
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            return None
        return lat, lon, alt

    def _cmd_change_speed(self, cmd):
        kind = cmd.float(1) if cmd.finite(1) else 1.0
        speed = cmd.float(2) if cmd.finite(2) else -1.0
        if not self.mission.change_speed(kind, speed):
            return self.refuse(DENIED, "Speed: %.1f m/s out of range" % speed)
        self.guided_speed = None
        return ACCEPTED

    def _cmd_loiter(self, cmd):
        # NAV_LOITER_UNLIM: hold here, or at params 5-7 where given.
        refused = self.flying("Loiter")
        if refused is not None:
            return refused
        if not self._allowed(cmd):
            return DENIED
        point = self._point(cmd)
        if point is None:
            return self.refuse(DENIED, "Loiter: position out of range")
        if not cmd.is_int and not cmd.float(5) and not cmd.float(6):
            point = (self.sim.lat, self.sim.lon, point[2])  # 0, 0: here
        self.set_mode("LOITER")
        self.hold_at = point
        return ACCEPTED

    def _cmd_pause_continue(self, cmd):
        # param1 0: hold where it is; 1: continue in the mode paused.
        if cmd.finite(1) and cmd.float(1) == 0:
            refused = self.flying("Pause")
            if refused is not None:
                return refused
            if self.mode != "LOITER":
                paused = (self.mode, self.hold_at, self.guided_speed, self.guided_yaw)
                self.set_mode("LOITER")
                self.paused_mode = paused
            return ACCEPTED
        if self.paused_mode is None:
            return self.refuse(DENIED, "Continue: nothing paused")
        (mode, hold_at, speed, yaw), self.paused_mode = self.paused_mode, None
        self.set_mode(mode)
        if mode == "GUIDED":  # on to where it was going
            self.hold_at, self.guided_speed, self.guided_yaw = hold_at, speed, yaw
        return ACCEPTED

    def _cmd_mission_start(self, cmd):
        # param1: first item (in ArduPilot's convention item 0 is home: from 1), param2:
        # last item (0 as QGroundControl sends it: to the end).
        runner = self.runner
        if not self.ep.allows(cmd.link):
            return DENIED
        if runner.store.count == 0:
            return self.refuse(DENIED, "Mission: no mission")
        if self.status is None or not self.status.armed:
            return self.refuse(DENIED, "Mission: disarmed, arm first")
        self.status.conventions.took(cmd.link)
        first = max(0 if cmd.nan(1) else cmd.int(1), self.first_item())
        last = -1 if cmd.nan(2) else cmd.int(2)
        if not runner.start(first, last):
            return self.refuse(DENIED, "Mission: no item %d" % first)
        self.set_mode("AUTO")
        return ACCEPTED

    def _guided_item(self, link, p, is_int):
        """MISSION_ITEM(_INT) with current 2 (go there: ArduPilot's guided waypoint) or 3
        (change altitude), as MAVProxy's `guided` sends -> MAV_MISSION_RESULT."""
        if self.status is None or not self.status.armed or self.landed == ON_GROUND:
            self.ep.statustext(WARNING, "Guided: not flying")
            return _MISSION_DENIED
        frame = p[34]
        if frame not in _GLOBAL_FRAMES:
            self.ep.statustext(WARNING, "Guided: frame %d not supported" % frame)
            return _MISSION_UNSUPPORTED_FRAME
        x, y = struct.unpack_from("<ii" if is_int else "<ff", p, 16)
        alt = struct.unpack_from("<f", p, 24)[0]
        if is_int:
            x, y = x / 1e7, y / 1e7
        geo = self.ep.services.get("geography")
        if (geo is not None and p[35] == 2 and -90.0 <= x <= 90.0 and -180.0 <= y <= 180.0 and alt == alt
                and not geo.allows_degrees(x, y, alt)):
            self.ep.statustext(WARNING, "Guided: target outside the allowed area")
            return _MISSION_DENIED
        if frame in _RELATIVE_FRAMES:
            alt += self.mission.home()[2]
        here = self.hold_at or (self.sim.lat, self.sim.lon, self.sim.alt)
        if p[35] == 3:  # change altitude only
            x, y = here[0], here[1]
        if not (-90.0 <= x <= 90.0 and -180.0 <= y <= 180.0) or alt != alt:
            self.ep.statustext(WARNING, "Guided: position out of range")
            return _MISSION_DENIED
        self.set_mode("GUIDED")
        self.hold_at = (x, y, alt)
        return _MISSION_ACCEPTED

    # --- the command under way --------------------------------------------------------
    def report_progress(self, dt):
        # IN_PROGRESS again every half second: the ground station knows it is under way.
        if self.pending is None:
            return
        self._since_progress += dt
        if self._since_progress < 0.5:
            return
        self._since_progress = 0.0
        sim = self.sim
        ground = self.mission.ground()
        if self.pending_cmd == 22:
            done = (sim.alt - ground) / max(self.climb_to - ground, 0.1)
        else:
            done = 1.0 - (sim.alt - ground) / max(self.hold_at[2] - ground, 0.1)
        self.pending.progress(max(0, min(99, int(done * 100))))

    def refuse(self, result, text):
        self.ep.statustext(WARNING, text)
        return result

    def defer(self, cmd):
        if self.pending is not None:
            self.refuse_pending("superseded")
        self.pending = cmd.defer()
        self.pending_cmd = cmd.command
        self._since_progress = 0.0
        return IN_PROGRESS

    def finish(self, result):
        if self.pending is not None:
            pending, self.pending = self.pending, None
            pending.done(result)

    def refuse_pending(self, why):
        name = "Takeoff" if self.pending_cmd == 22 else "Land"
        self.ep.statustext(WARNING, name + ": " + why)
        self.finish(FAILED)

    def flying(self, what):
        """None if armed and in the air, else the refusal (MAV_RESULT) with its STATUSTEXT."""
        if self.status is None or not self.status.armed:
            return self.refuse(DENIED, what + ": disarmed")
        if self.landed == ON_GROUND:
            return self.refuse(DENIED, what + ": on the ground, take off first")
        return None
