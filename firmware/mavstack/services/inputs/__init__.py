"""The inputs service: what pilots, joysticks, companion computers and HIL simulators send
to steer the vehicle, kept for the application to read without allocating.

Each message it takes (MANUAL_CONTROL, RC_CHANNELS_OVERRIDE, the SET_*_TARGET setpoints,
HIL and vision messages; the seed's setpoints) has an input record (record.py) at
inputs.<name> (KINDS below), None where the dialect lacks it. inputs.on(kind, fn) calls
fn on each arrival, inputs.on_input_lost(kind) once when an input stops arriving. A
message is stored only when addressed to this vehicle and, under operator control, sent
by the station in control. Setpoints are echoed back and, in HIL, HIL_CONTROLS reported
(echo.py). Reference: docs/services/inputs.md.
"""
from ...compat import const, ticks_add, ticks_diff
from . import record as rec
from .echo import Echo, ECHOES, HilControls

USES = ("geography", "status")  # the safety area; HIL and operator control

# Kinds
MANUAL = const(0)
RC = const(1)
MANUAL_SETPOINT = const(2)
POSITION_LOCAL = const(3)
POSITION_GLOBAL = const(4)
ATTITUDE = const(5)
HIL_STATE = const(6)
HIL_RC = const(7)
HIL_SENSOR = const(8)
GLOBAL_VISION = const(9)
VISION = const(10)
VISION_SPEED = const(11)
VICON = const(12)
FLOW = const(13)
SEED_LOCAL = const(14)
SEED_GLOBAL = const(15)
SEED_RPYT = const(16)
SEED_RPY_SPEED = const(17)
SEED_MOTORS = const(18)
SEED_SWARM = const(19)
SEED_SWARM_LED = const(20)
SEED_8DOF = const(21)
SEED_6DOF = const(22)

# kind, attribute, message id, class, target_system offset, target_component offset,
# crc_extra the message must have (-1: any; the seed's ids 50 and 149 mean other
# messages in today's set)
KINDS = (
    (MANUAL, "manual", 69, rec.ManualInput, 10, -1, -1),
    (RC, "rc", 70, rec.RcOverride, 16, 17, -1),
    (MANUAL_SETPOINT, "manual_setpoint", 81, rec.Input, -1, -1, -1),
    (POSITION_LOCAL, "position_local", 84, rec.PositionTarget, 50, 51, -1),
    (POSITION_GLOBAL, "position_global", 86, rec.PositionTarget, 50, 51, -1),
    (ATTITUDE, "attitude", 82, rec.AttitudeTarget, 36, 37, -1),
    (HIL_STATE, "hil_state", 90, rec.Input, -1, -1, -1),
    (HIL_RC, "hil_rc", 92, rec.Input, -1, -1, -1),
    (HIL_SENSOR, "hil_sensor", 107, rec.Input, -1, -1, -1),
    (GLOBAL_VISION, "global_vision", 101, rec.Input, -1, -1, -1),
    (VISION, "vision", 102, rec.Input, -1, -1, -1),
    (VISION_SPEED, "vision_speed", 103, rec.Input, -1, -1, -1),
    (VICON, "vicon", 104, rec.Input, -1, -1, -1),
    (FLOW, "flow", 100, rec.Input, -1, -1, -1),
    (SEED_LOCAL, "seed_local", 50, rec.Input, 16, 17, 0xD6),
    (SEED_GLOBAL, "seed_global", 53, rec.Input, -1, -1, 0x21),
    (SEED_RPYT, "seed_rpyt", 56, rec.Input, 16, 17, 0x64),
    (SEED_RPY_SPEED, "seed_rpy_speed", 57, rec.Input, 16, 17, 0x18),
    (SEED_MOTORS, "seed_motors", 60, rec.Input, 8, -1, 0x1E),
    (SEED_SWARM, "seed_swarm", 61, rec.Input, -1, -1, 0xF0),
    (SEED_SWARM_LED, "seed_swarm_led", 63, rec.Input, -1, -1, 0x82),
    (SEED_8DOF, "seed_8dof", 148, rec.Input, 32, -1, 0xF1),
    (SEED_6DOF, "seed_6dof", 149, rec.Input, 24, -1, 0x0F),
)
NAMES = tuple(k[1] for k in KINDS)  # by kind: inputs.NAMES[kind] -> "manual" ...

_CHECK_MS = const(20)  # how often the loss check runs
_HIL_CONTROLS_MS = const(50)  # HIL_CONTROLS written at 20 Hz while in HIL


class Inputs:
    NAME = "inputs"

    def __init__(self, timeout_ms=1000, rc_timeout_ms=3000):
        self.timeout_ms = timeout_ms
        self.rc_timeout_ms = rc_timeout_ms
        self.on_input_lost = None
        self.records = ()
        self._by_kind = [None] * len(KINDS)
        self._next_check = 0
        self._next_hil = 0
        self._wired = False  # started() has run (at the first tick: every service is in)
        self.hil_controls = None
        for k in KINDS:
            setattr(self, k[1], None)

    def attach(self, ep):
        self.ep = ep
        self._next_check = self._next_hil = ep.now
        records = []
        for kind, name, msgid, cls, ts, tc, crc in KINDS:
            info = ep.dialect.CRC_LEN.get(msgid)
            if info is None or (crc >= 0 and info & 0xFF != crc):
                continue
            r = cls(self, kind, msgid, ts, tc)
            r.geo = None  # in its own dict now: set at the first tick, maybe heap-locked
            ep.on(msgid, r.deliver)
            setattr(self, name, r)
            self._by_kind[kind] = r
            records.append(r)
        self.records = tuple(records)
        for sp, target, src, dst, n, sb, db, stamp, crc in ECHOES:
            r = self._by_msgid(sp)
            if r is not None and ep.has(target) and (crc < 0 or ep.dialect.CRC_LEN[sp] & 0xFF == crc):
                r.echo = Echo(ep, target, src, dst, n, sb, db, stamp)
        if ep.has(91):
            self.hil_controls = HilControls(ep)

    def started(self):
        # Once every service is in (the first tick; the heap may be locked by then):
        # position setpoints keep to the geography service's area.
        geo = self.ep.services.get("geography")
        if self.position_local is not None:
            self.position_local.geo = geo
        if self.position_global is not None:
            self.position_global.geo = geo

    def _by_msgid(self, msgid):
        for r in self.records:
            if r.msgid == msgid:
                return r
        return None

    def record(self, kind):
        return self._by_kind[kind] if 0 <= kind < len(self._by_kind) else None

    def on(self, kind, fn):
        """fn(record) on each arrival of this kind; False where the dialect lacks it."""
        r = self.record(kind)
        if r is None:
            return False
        r.callback = fn
        return True

    @property
    def hil(self):
        status = self.ep.services.get("status")
        return status is not None and status.hil

    # --- periodic: loss of inputs, HIL_CONTROLS (allocation-free) ---------------------
    def tick(self, now):
        if not self._wired:
            self._wired = True
            self.started()
        if ticks_diff(now, self._next_check) >= 0:
            self._next_check = ticks_add(now, _CHECK_MS)
            self._check(now)
        if self.hil_controls is not None and ticks_diff(now, self._next_hil) >= 0:
            self._next_hil = ticks_add(now, _HIL_CONTROLS_MS)
            self._hil(self.ep.services.get("status"))

    def _check(self, now):
        records = self.records
        i = 0
        while i < len(records):
            r = records[i]
            if r.live and ticks_diff(now, r.stamp) > self.timeout_ms:
                r.live = False
                if self.on_input_lost is not None:
                    self.on_input_lost(r.kind)
            i += 1

    def _hil(self, status):
        if status is not None and status.hil:
            self.hil_controls.write(self.manual, status.base_mode)


def create(ep):
    return ep.add(Inputs(ep.setting("INPUT_TIMEOUT_MS", 1000), ep.setting("RC_OVERRIDE_TIMEOUT_MS", 3000)))
