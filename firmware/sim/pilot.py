"""The simulated vehicle's flight control: what it does in each flight mode, the flight
commands under way (their handlers: commands.py), the landed state and airborne flag
telemetry tells, the vetoes on mode changes and arming, the rules that differ between
ArduPilot's and PX4's conventions (as the ground station commanding it assumes), and
where the failsafes (failsafe.py) hook in. Reference: docs/sim.md.
"""
import math

from mavstack.services.inputs import POSITION_GLOBAL, POSITION_LOCAL
from mavstack.services.status.conventions import ARDUPILOT, PX4

from .commands import ACCEPTED, INFO, PILOT_MODES, IN_AIR, LANDING, ON_GROUND, TAKING_OFF, FlightCommands
from .failsafe import Failsafe
from .inputs import PilotInputs
from .mission import MissionPilot
from .motion import distance

_GROUND_M = 0.05  # this close to the ground is on it (and to a point held: there)
_HOLDING = ("LOITER", "GUIDED", "STABILIZE", "ALT_HOLD", "POSITION")  # armable, nothing to fly at once


class FlightPilot(FlightCommands):
    def __init__(self, sim):
        self.sim = sim
        ep = self.ep = sim.ep
        self.status = ep.services.get("status")
        self.missions = ep.services.get("missions")
        self.mission = MissionPilot(sim)  # also the motion model (motion.Motion)
        self.inputs = None
        if ep.services.get("inputs") is not None:
            self.inputs = PilotInputs(sim)
        self.mode = None  # the flight mode last flown
        self.hold_at = None  # (lat, lon, alt MSL): where LOITER / GUIDED hold or go
        self.guided_speed = None  # DO_REPOSITION's speed for this leg (None: the default)
        self.guided_yaw = None  # ... its heading on arrival (degrees)
        self.climb_to = None  # TAKEOFF's altitude (MSL)
        self.takeoff_to = None  # ... and (lat, lon) to go to once up there (None: here)
        self.takeoff_yaw = None  # ... and the heading (degrees) to turn to there
        self.armable = "LOITER"  # the last holding mode flown: PX4's rules go back to it on disarm
        self.rtl_leg = 0  # 0 up to rtl_alt, 1 home, 2 down
        self.rtl_alt = 0.0
        self.land_at = None  # (lat, lon) of a NAV_LAND somewhere else
        self.pending = None  # the command still IN_PROGRESS (takeoff, land)
        self.pending_cmd = 0
        self.failsafe = Failsafe(self)
        self.paused_mode = None  # DO_PAUSE_CONTINUE: (mode, hold_at, speed, yaw) to continue with
        self.landed = ON_GROUND
        self._idle_s = 0.0  # seconds armed on the ground with nothing to do
        self._airborne = None
        self._setpoint = False  # a position target arrived (flown in GUIDED, as ArduPilot does)
        self.guided_velocity = None  # (vn, ve, vd, yaw rate, seconds left) of one in GUIDED
        self._fly = {"TAKEOFF": self._fly_takeoff, "LOITER": self._fly_hold, "GUIDED": self._fly_guided,
                     "RTL": self._fly_rtl, "LAND": self._fly_land, "AUTO": self._fly_auto}
        self._hooks()
        self._update_landed()

    def _hooks(self):
        status = self.status
        if status is not None:
            status.flight_mode_check = self._mode_check
            status.on_flight_mode = self._entered  # before the ACK: the next command sees it
            status.arm_check = self._arm_check
            status.on_arm = self._arm_changed
            status.on_gcs_lost = self.failsafe.gcs_lost
            status.on_gcs_regained = self.failsafe.gcs_regained
        self.take_commands()
        inputs = self.ep.services.get("inputs")
        if inputs is not None and self.inputs is not None:
            inputs.on(POSITION_LOCAL, self._setpoint_arrived)
            inputs.on(POSITION_GLOBAL, self._setpoint_arrived)

    @property
    def runner(self):
        return self.missions.runner if self.missions is not None else None

    # --- each tick ------------------------------------------------------------------
    def step(self, dt):
        status = self.status
        mode = status.flight_mode if status is not None else None
        if mode is None:  # a board without a mode table: its AUTO flag
            mode = "AUTO" if status is not None and status.auto else "LOITER"
        if mode != self.mode:
            self._entered(mode)  # (a ground station's change was entered as it was taken)
        self.failsafe.tick(dt)
        if status is None or not status.armed:
            self._disarmed(dt)
        elif mode in self._fly:
            self._fly[mode](dt)
        elif mode in PILOT_MODES:
            self._fly_pilot(dt)
        else:
            self._fly_hold(dt)
        self._update_landed()
        self.report_progress(dt)
        self._idle_disarm(dt)

    def set_mode(self, name):
        """The vehicle's own mode change (a command, a failsafe, a takeoff done)."""
        if self.status is not None:
            self.status.set_flight_mode(name)
        self._entered(name)

    def _entered(self, mode):
        # A mode entered (a ground station's request: the same mode again starts afresh).
        prev, self.mode = self.mode, mode
        sim = self.sim
        runner = self.runner
        if prev == "AUTO" and mode != "AUTO" and runner is not None and runner.running:
            runner.pause()
        if mode == "AUTO" and runner is not None:
            self._auto_from(runner, self.first_item())
        if mode in _HOLDING:
            self.armable = mode
        if self.pending is not None and not (self.pending_cmd == 22 and mode == "TAKEOFF"
                                             or self.pending_cmd == 21 and mode == "LAND"):
            self.refuse_pending("interrupted by mode " + mode)
        if mode != "LOITER":
            self.failsafe.left = None  # a ground station took over from the failsafe
            self.paused_mode = None
        self.hold_at = (sim.lat, sim.lon, sim.alt)
        self.takeoff_to = self.takeoff_yaw = None
        self.guided_speed = self.guided_yaw = self.guided_velocity = None
        self._setpoint = False
        self.land_at = None
        # (TAKEOFF entered in the air climbs to the takeoff altitude, never down to it)
        self.climb_to = max(self.mission.ground() + self.mission.setting(None, "MIS_TAKEOFF_ALT", 10.0),
                            sim.alt if self.landed != ON_GROUND else 0.0)
        self.rtl_leg = 0
        self.rtl_alt = max(sim.alt, self.mission.home()[2] + self.mission.setting(None, "RTL_ALT", 15.0))
        sim.target = None

    def _update_landed(self):
        sim = self.sim
        rel = sim.alt - self.mission.ground()
        if rel <= _GROUND_M and sim.vd >= 0:
            landed = ON_GROUND
        elif self.landed == ON_GROUND or (self.landed == TAKING_OFF and (self.mode == "TAKEOFF" or rel < 2.0)):
            landed = TAKING_OFF
        elif sim.vd > 0.1 and self._landing():
            landed = LANDING
        else:
            landed = IN_AIR
        self.landed = sim.landed_state = landed
        airborne = landed != ON_GROUND
        if airborne != self._airborne and self.status is not None:
            self._airborne = airborne
            self.status.set_airborne(airborne)

    def _landing(self):
        mode = self.mode
        if mode == "LAND" or (mode == "RTL" and self.rtl_leg == 2):
            return True
        runner = self.runner
        if mode == "AUTO" and runner is not None and runner.state == 3:
            item = runner.item
            return item is not None and item.command in (20, 21)
        return False

    # --- the modes ----------------------------------------------------------------------
    def _disarmed(self, dt):
        sim = self.sim
        m = self.mission
        if self.pending is not None:
            self.refuse_pending("disarmed")
        runner = self.runner
        if runner is not None and runner.running:
            runner.pause()
        sim.target = None
        if sim.alt - m.ground() > _GROUND_M:  # motors stopped in the air
            m.moved(0.0, 0.0, min(5.0 * dt, sim.alt - m.ground()), dt, 0.0)
            sim.throttle = 0.0
        else:
            m.hold()

    def _fly_hold(self, dt):
        # LOITER, GUIDED: at (or to) hold_at; on the ground, stays there.
        m = self.mission
        if self.landed == ON_GROUND:
            m.hold()
            return
        lat, lon, alt = self.hold_at
        if m.go(lat, lon, alt, dt, _GROUND_M, speed=self.guided_speed) and self.guided_yaw is not None:
            m.turn(self.guided_yaw, m.turn_rate, dt)

    def _fly_guided(self, dt):
        # GUIDED also takes SET_POSITION_TARGET_* as ArduPilot does (MAVProxy's `position`,
        # `velocity`, `guided forward`): a position is latched when it arrives (a body-frame
        # offset is from where the vehicle was then); a velocity is flown for 3 s.
        if self._setpoint:
            self._setpoint = False
            demand = self.inputs.demand("OFFBOARD", dt)
            if demand is not None and demand[0] == "pos" and self.landed != ON_GROUND:
                self.hold_at = (demand[1], demand[2], demand[3])
                self.guided_speed = self.guided_velocity = None
                self.guided_yaw = math.degrees(demand[4]) % 360.0 if demand[4] is not None else None
            elif demand is not None and demand[0] == "vel" and self.landed != ON_GROUND:
                self.guided_velocity = demand[1:] + (3.0,)
        v = self.guided_velocity
        if v is not None:
            self.mission.velocity(v[0], v[1], v[2], v[3], dt)
            self.guided_velocity = v[:4] + (v[4] - dt,) if v[4] > dt else None
            self.hold_at = (self.sim.lat, self.sim.lon, self.sim.alt)
            return
        self._fly_hold(dt)

    def _setpoint_arrived(self, record):
        self._setpoint = self.mode == "GUIDED"

    def _fly_takeoff(self, dt):
        # Straight up to the altitude, then over to takeoff_to (if any), then the heading.
        m = self.mission
        if not m.go(self.hold_at[0], self.hold_at[1], self.climb_to, dt, _GROUND_M):
            return
        if self.takeoff_to is not None:
            self.hold_at = (self.takeoff_to[0], self.takeoff_to[1], self.climb_to)
            self.takeoff_to = None
            return
        if self.takeoff_yaw is not None and not m.turn(self.takeoff_yaw, m.turn_rate, dt):
            return
        self.ep.statustext(INFO, "Takeoff: at %.1f m" % (self.sim.alt - m.ground()))
        self.finish(ACCEPTED)
        self.set_mode(self.after_takeoff())

    def _fly_land(self, dt):
        sim = self.sim
        m = self.mission
        if self.land_at is not None:
            lat, lon = self.land_at
            if distance(sim.lat, sim.lon, lat, lon) > 0.3:
                m.go(lat, lon, sim.alt, dt, 0.3)
                return
        self._descend(sim.lat, sim.lon, dt)

    def _descend(self, lat, lon, dt):
        m = self.mission
        if m.go(lat, lon, m.ground(), dt, _GROUND_M) or self.sim.alt - m.ground() <= _GROUND_M:
            self._touchdown()

    def _idle_disarm(self, dt):
        # DISARM_DELAY, as ArduPilot's (PX4: COM_DISARM_PRFLT): armed on the ground, not
        # taking off and with nothing under way, the motors stop after that many seconds
        # (0: never). The pilot's throttle up, a takeoff or a mission start lift it first.
        status = self.status
        if (status is None or not status.armed or self.landed != ON_GROUND or self.pending is not None
                or self.mode == "TAKEOFF"):
            self._idle_s = 0.0
            return
        self._idle_s += dt
        delay = self.mission.setting(None, "DISARM_DELAY", 10.0)
        if 0 < delay <= self._idle_s:
            self._idle_s = 0.0
            status.arm(False, True)
            self.ep.statustext(INFO, "Disarmed: %d s on the ground, idle" % delay)

    def _touchdown(self):
        sim = self.sim
        sim.alt = self.mission.ground()
        self.mission.hold()
        self.finish(ACCEPTED)  # (first: PX4's rules leave LAND on the disarm)
        if self.status is not None and self.status.armed:
            self.status.arm(False, True)  # (forced: this is the vehicle's own decision)
            self.ep.statustext(INFO, "Landed: disarmed")

    def _fly_rtl(self, dt):
        sim = self.sim
        m = self.mission
        lat, lon, _ = m.home()
        if self.rtl_leg == 0:
            if self.landed == ON_GROUND and distance(sim.lat, sim.lon, lat, lon) <= m.radius:
                self._touchdown()  # home already, on the ground
                return
            if m.go(self.hold_at[0], self.hold_at[1], self.rtl_alt, dt, 0.5):
                self.rtl_leg = 1
        elif self.rtl_leg == 1:
            if m.go(lat, lon, self.rtl_alt, dt, m.radius):
                self.rtl_leg = 2
        else:
            self._descend(lat, lon, dt)

    def _fly_auto(self, dt):
        runner = self.runner
        if runner is None:
            self._fly_hold(dt)
            return
        before = runner.state
        self.mission.step(dt)
        if self.mission.touched_down:  # a LAND item, last or not: down and disarmed, as
            self.mission.touched_down = False  # ArduPilot and PX4 do (the mission stops)
            self._touchdown()
        elif runner.state == 5 and before != 5:  # COMPLETE
            if self.sim.alt - self.mission.ground() <= _GROUND_M:
                self._touchdown()
            else:  # at the last item (as PX4 and ArduPilot hold), not where it counted as reached
                target = self.sim.target
                self.ep.statustext(INFO, "Mission: complete, holding")
                self.set_mode("LOITER")
                if self.mode == "LOITER" and target is not None:
                    self.hold_at = target

    def _fly_pilot(self, dt):
        # STABILIZE, ALT_HOLD, POSITION, OFFBOARD: the pilot's (or offboard computer's) demand.
        demand = self.inputs.demand(self.mode, dt) if self.inputs is not None else None
        sim = self.sim
        m = self.mission
        if demand is None:
            self._fly_hold(dt)
            return
        if demand[0] == "vel":
            if self.landed == ON_GROUND and demand[3] >= 0:
                m.hold()  # on the ground until the pilot climbs
            else:
                m.velocity(demand[1], demand[2], demand[3], demand[4], dt)
        else:
            m.go(demand[1], demand[2], demand[3], dt, 0.1)
            if demand[4] is not None:
                m.turn(math.degrees(demand[4]) % 360.0, m.turn_rate, dt)
        self.hold_at = (sim.lat, sim.lon, sim.alt)

    # --- vetoes ---------------------------------------------------------------------------
    def _mode_check(self, name):
        """A ground station's mode request: AUTO needs a mission, OFFBOARD a setpoint."""
        if name == "AUTO":
            runner = self.runner
            if runner is None or runner.store.count == 0:
                return "no mission"
        if self.inputs is not None and hasattr(self.inputs, "mode_check"):
            return self.inputs.mode_check(name)
        return None

    def _arm_check(self, arm):
        if arm and self.mode in ("LAND", "RTL"):
            return "mode %s: not armable" % self.mode  # (it would land at once)
        if arm:
            return self.sim.pre_arm_check()
        if self.landed != ON_GROUND:
            return "in the air: land first (or force)"
        return None

    # --- ArduPilot's rules or PX4's: those of the station that commands it ------------------
    def rules(self):
        """ARDUPILOT, PX4 or 0 (neither known): the conventions of the ground station whose
        request (a mode, arming, a flight command) the vehicle last took."""
        return self.status.conventions.last if self.status is not None else 0

    def _arm_changed(self, armed):
        # Disarmed in LAND or RTL (landed, or by a ground station): PX4 goes back to the
        # last armable mode at once, so a station that flies again just arms; ArduPilot
        # stays (and refuses to arm there: _arm_check).
        if not armed and self.mode in ("LAND", "RTL") and self.rules() == PX4:
            self.set_mode(self.armable)

    def first_item(self):
        """The item a mission starts from: 1 in ArduPilot's convention (item 0 is home),
        else 0 (the first item, as MAVLink's mission protocol and PX4 have it)."""
        runner = self.runner
        return 1 if self.rules() == ARDUPILOT and runner is not None and runner.store.count > 1 else 0

    def _auto_from(self, runner, first):
        # AUTO entered: a mission flown to its end starts again, one not started starts
        # past home's row.
        if runner.state == 5:  # COMPLETE
            runner.start(first)
        elif runner.state == 2 and runner.current < first:  # NOT_STARTED
            runner.set_current(first)

    def after_takeoff(self):
        """The mode a takeoff ends in: GUIDED in ArduPilot's convention (ArduCopter takes
        off in it and stays), else LOITER (PX4's Hold). Both hold there."""
        return "GUIDED" if self.rules() == ARDUPILOT else "LOITER"
