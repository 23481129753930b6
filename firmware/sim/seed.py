"""What the simulated vehicle does with the seed's calibration, video, debugging and
state-correction messages: the application side of services/calibration.py,
seed_commands.py (DO_CONTROL_VIDEO), debug.py and geography.py (STATE_CORRECTION), and
the seed's setpoint echoes (services/seed_telemetry.py). The board composes it with the
simulator (boards/unix.py application(): compose()). Reference: docs/sim.md.
"""
import math
import struct

from mavstack.compat import ticks_diff
from mavstack.fields import cstr_text

_ACCEPTED = 0
_DENIED = 2
_FAILED = 4
_IN_PROGRESS = 5
_INFO = 6
_WARNING = 4
DEBUG_NAMES = 32  # debug values kept by name: a new name past these takes one's place
SENSORS = ("gyro", "magnetometer", "ground pressure", "radio", "accelerometer",
           "compass/motor", "airspeed")
OFFSET_SENSORS = 7


class SimCalibration:
    NAME = "sim_seed"
    CLOCK = False

    def __init__(self, step_ms=300, sim=None):
        self.step_ms = step_ms
        self.sim = sim
        self.echoes = None
        self._echo_at = 0
        self.offsets = {}
        self.calibrated = []  # names of the sensors calibrated, in order
        self._pending = None
        self._todo = []
        self._next = 0
        self._half = False

    def attach(self, ep):
        self.ep = ep
        self.step_ms = ep.setting("SIM_CAL_MS", self.step_ms)
        cal = ep.services.get("calibration")
        if cal is not None:
            cal.handler = self.handle
        seed = ep.services.get("seed_telemetry")
        if seed is not None and seed.slots and self.sim is not None:
            self.echoes = seed
        self.geo = ep.services.get("geography") if self.sim is not None else None

    def handle(self, cmd):
        if cmd.command == 242:
            sensor = cmd.int(1) if cmd.finite(1) else -1
            if not 0 <= sensor < OFFSET_SENSORS:
                self.ep.statustext(_WARNING, "Offsets refused: no sensor %d" % sensor)
                return _DENIED
            self.offsets[sensor] = tuple(cmd.float(i) if cmd.finite(i) else 0.0 for i in range(2, 8))
            self.ep.statustext(_INFO, "Offsets set: sensor %d" % sensor)
            return _ACCEPTED
        todo = [name for i, name in enumerate(SENSORS) if cmd.finite(i + 1) and cmd.int(i + 1) == 1]
        if not todo:
            self.ep.statustext(_WARNING, "Calibration: no sensor asked for")
            return _DENIED
        if self._pending is not None:
            self._pending.done(_FAILED)  # a new request replaces the one under way
        self._todo = todo
        self._pending = cmd.defer()
        self._next = self.ep.now
        self._half = False
        self.ep.statustext(_INFO, "Calibrating %s: 0%%" % todo[0])
        return _IN_PROGRESS

    def tick(self, now):
        if (self.echoes is not None or self.geo is not None) and ticks_diff(now, self._echo_at) >= 100:
            self._echo_at = now
            if self.echoes is not None:
                self._echo()
            if self.geo is not None and self.geo.origin_set:
                self._offset()
        self._calibrate(now)

    def _echo(self):
        # The seed's setpoint echoes at 10 Hz: the attitude and thrust the model flies
        # (it holds its rates: none commanded), the point it flies toward.
        sim, e = self.sim, self.echoes
        e.attitude_setpoint(sim.roll, sim.pitch, sim.heading, sim.throttle)
        e.speed_setpoint(0.0, 0.0, 0.0, sim.throttle)
        e.rates_setpoint(0.0, 0.0, 0.0, sim.throttle)
        target = getattr(sim, "target", None)
        if target is not None:
            e.global_setpoint(0, round(target[0] * 1e7), round(target[1] * 1e7), round(target[2] * 1000),
                              round(math.degrees(sim.heading) * 100) % 36000)

    def _offset(self):
        # LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET: where the local frame's origin (the
        # simulator's start, which LOCAL_POSITION_NED counts from) lies from the GPS
        # global origin, in NED metres (flat earth: fine over a few kilometres).
        lat0, lon0, alt0 = self.geo.origin()
        lat, lon, alt = self.sim.start
        north = (lat - lat0 / 1e7) * 111319.49
        east = (lon - lon0 / 1e7) * 111319.49 * math.cos(math.radians(lat))
        self.geo.local_offset(north, east, -(alt - alt0 / 1000.0), 0.0, 0.0, 0.0)

    def _calibrate(self, now):
        if self._pending is None or ticks_diff(now, self._next) < self.step_ms // 2:
            return
        self._next = now
        status = self.ep.services.get("status")
        if status is not None and status.armed:
            self.ep.statustext(_WARNING, "Calibration cancelled: armed")
            self._pending.done(_FAILED)
            self._pending = None
            return
        name = self._todo[0]
        if not self._half:
            self._half = True
            self.ep.statustext(_INFO, "Calibrating %s: 50%%" % name)
            return
        self._half = False
        self.calibrated.append(self._todo.pop(0))
        self.ep.statustext(_INFO, "Calibrating %s: 100%%" % name)
        if self._todo:
            return
        self.ep.statustext(_INFO, "Calibration done")
        self._pending.done(_ACCEPTED)
        self._pending = None


def _debug_text(msgid, p):
    """(name, value as text) of a debug message, None for one that is not."""
    if msgid == 251:
        return _name(p, 8), "%.2f" % struct.unpack_from("<f", p, 4)[0]
    if msgid == 252:
        return _name(p, 8), "%d" % struct.unpack_from("<i", p, 4)[0]
    if msgid == 254:
        return "[%d]" % p[8], "%.2f" % struct.unpack_from("<f", p, 4)[0]
    if msgid == 250:
        return _name(p, 20), "(%.2f,%.2f,%.2f)" % struct.unpack_from("<fff", p, 8)
    if msgid == 249:
        return "mem@%d" % (p[0] | p[1] << 8), "%d bytes" % 32
    return None


def _name(p, o):
    return cstr_text(p, o, 10)  # a char[10] as sent: any bytes, UTF-8 or not


def _mission_items(ep, sim):
    """A mission's DO_SET_RELAY / DO_REPEAT_RELAY / DO_SET_SERVO / DO_REPEAT_SERVO drive the
    servo table (services/servos.py do_item) and DO_CONTROL_VIDEO the camera as each
    becomes current (the runner's on_item; a hook already there is still called)."""
    missions = ep.services.get("missions")
    runner = getattr(missions, "runner", None)
    if runner is None:
        return
    servos = ep.services.get("servos")
    before = runner.on_item

    def on_item(r):
        item = r.item
        if item is not None and servos is not None and 181 <= item.command <= 184:
            servos.do_item(item)
        elif item is not None and item.command == 200 and sim is not None:
            sim.video = item.param2 > 0 or item.param4 > 0  # transmission or recording
        if before is not None:
            before(r)
    runner.on_item = on_item


def compose(ep, sim=None):
    """Attach to an endpoint that has the calibration service (the simulator's board);
    the simulator's camera (sim.video) answers DO_CONTROL_VIDEO (services/seed_commands.py):
    param2 transmission or param4 recording above 0 turns it on, both 0 off."""
    debug = ep.services.get("debug")
    values = {}
    if debug is not None:
        def on_debug(link, msgid, p):
            text = _debug_text(msgid, p)
            if text:
                if text[0] not in values and len(values) >= DEBUG_NAMES:
                    # Names are whatever arrives: kept without a bound they took the heap.
                    del values[next(iter(values))]
                values[text[0]] = text[1]
                ep.statustext(_INFO, "Debug %s=%s" % text)
        debug.handler = on_debug
        debug.values = values
    geo = ep.services.get("geography")
    if geo is not None:
        def on_correction(link, p):
            x, y, z = struct.unpack_from("<fff", p, 0)
            geo.corrections = getattr(geo, "corrections", 0) + 1
            ep.statustext(_INFO, "State correction x=%.2f y=%.2f z=%.2f" % (x, y, z))
        geo.on_state_correction = on_correction
    _mission_items(ep, sim)
    seed = ep.services.get("seed_commands")
    if seed is not None and sim is not None and hasattr(sim, "video"):
        def video(cmd):
            on = any(cmd.finite(i) and cmd.int(i) > 0 for i in (2, 4))
            sim.video = on
            ep.statustext(_INFO, "Video on" if on else "Video off")
            return _ACCEPTED
        seed.on_video = video
    return ep.add(SimCalibration(sim=sim))
