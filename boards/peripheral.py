"""What the peripheral boards share (unix_peripheral, qemu_m0_rangefinder): mavstack as
a distance sensor on an autopilot's serial port, not as the autopilot. Component 158
(MAV_COMP_ID_PERIPHERAL), HEARTBEAT with MAV_AUTOPILOT_INVALID, the system id followed
from the autopilot's HEARTBEAT, its own few parameters, commands (REQUEST_MESSAGE among
them), no missions, modes or streams. docs/services/peripheral.md.

The application is a rangefinder: DISTANCE_SENSOR at RNGFND_RATE_HZ from a simulated
reading that sweeps between 1 and 4 m, a NAMED_VALUE_INT count of readings once a second;
MAV_CMD_USER_1 (param1 0/1) pauses and resumes it. Its ticks allocate nothing.
"""
from mavstack.compat import ticks_add, ticks_diff
from mavstack.services.params import REAL32

DIALECT = "common"
SYSID = "follow"  # the autopilot's, from its HEARTBEAT; nothing is sent before
SYSID_WAIT_MS = 10000  # then this one (the autopilot's, when heard later, wins)
SYSID_FALLBACK = 1
COMPID = 158  # MAV_COMP_ID_PERIPHERAL
MAV_TYPE = 0  # MAV_TYPE_GENERIC (common has no rangefinder type); MAV_AUTOPILOT_INVALID is implied
SERVICES = ("peripheral", "params", "commands")
ACK_UNSUPPORTED_BROADCAST = False  # a command for every component that it has not: no ACK
PARAM_ENCODING = "bytewise"  # (REAL32 parameters are the same under either encoding)
# REAL32, as ArduPilot's parameters all are on the wire: a peripheral behind an autopilot
# cannot tell which integer encoding the station asking assumes (docs/services/peripheral.md).
PARAMS = (
    ("RNGFND_RATE_HZ", REAL32, 10.0, 1.0, 50.0),
    ("RNGFND_MIN_CM", REAL32, 20.0, 0.0, 65535.0),
    ("RNGFND_MAX_CM", REAL32, 700.0, 1.0, 65535.0),
    ("RNGFND_ORIENT", REAL32, 25.0, 0.0, 100.0),  # MAV_SENSOR_ORIENTATION: 25 pointing down
    ("RNGFND_TYPE", REAL32, 0.0, 0.0, 4.0),  # MAV_DISTANCE_SENSOR: 0 laser
)
_CMD_USER_1 = 31010


class Rangefinder:
    def __init__(self, ep):
        self.ep = ep
        self.periph = ep.services["peripheral"]
        self.params = ep.services.get("params")
        self.running = True
        self.readings = 0
        self.distance = 150  # cm
        self.step = 3
        self._next = ep.now
        self._next_count = ep.now
        self.sensor = self.periph.distance_sensor(20, 700)
        self.count = self.periph.named_int("RNG_COUNT")
        self._configure()
        if self.params is not None:
            self.params.on_change = self._changed
        ep.commands[_CMD_USER_1] = self._run_pause

    def _get(self, name, default):
        return int(self.params.get(name)) if self.params is not None else default

    def _configure(self):
        # Start-up and a parameter set (rare, the heap open): the slot takes the settings.
        self.period = 1000 // max(1, self._get("RNGFND_RATE_HZ", 10))
        self.sensor.configure(self._get("RNGFND_MIN_CM", 20), self._get("RNGFND_MAX_CM", 700),
                              self._get("RNGFND_TYPE", 0), 0, self._get("RNGFND_ORIENT", 25))

    def _changed(self, name, value):
        if name.startswith("RNGFND_"):
            self._configure()

    def _run_pause(self, cmd):
        if not cmd.finite(1) or cmd.int(1) not in (0, 1):
            return 2  # MAV_RESULT_DENIED
        self.running = cmd.int(1) == 1
        return 0

    def tick(self, now):
        if not self.running or ticks_diff(now, self._next) < 0:
            return
        self._next = ticks_add(self._next, self.period)
        if ticks_diff(now, self._next) >= 0:
            self._next = ticks_add(now, self.period)
        d = self.distance + self.step
        if d < 100 or d > 400:
            self.step = -self.step
        self.distance = d
        self.readings += 1
        self.sensor.send(d, 100)
        if ticks_diff(now, self._next_count) >= 0:
            self._next_count = ticks_add(now, 1000)
            self.count.send(self.readings)


def application(ep):
    return Rangefinder(ep)
