"""PREFLIGHT_CALIBRATION (241) and PREFLIGHT_SET_SENSOR_OFFSETS (242): the application's.

Calibrating sensors and setting their offsets is the board's business, so both
commands go to the application's handler:
    ep.services["calibration"].handler = handler(cmd) -> MAV_RESULT
(cmd as services/commands.py hands it: cmd.int(i), cmd.float(i), cmd.defer() for a
calibration that takes time: return IN_PROGRESS, report with progress() and finish with
done()). PREFLIGHT_CALIBRATION: param1 gyro, param2 magnetometer, param3 ground
pressure, param4 radio, param5 accelerometer, param6 compass/motor interference,
param7 airspeed (1: calibrate, 0: not); PREFLIGHT_SET_SENSOR_OFFSETS: param1 the sensor
(0 gyro, 1 accelerometer, 2 magnetometer, 3 absolute pressure, 4 differential pressure,
5 GPS, 6 optical flow), param2-7 its offsets.

Built in, before the handler: the sender must be in control (operator control) and
the vehicle disarmed (a calibration moves the estimates the vehicle flies by):
otherwise DENIED, with a STATUSTEXT. The documented default without a handler is
UNSUPPORTED with a STATUSTEXT: a board with nothing to calibrate has nothing to do.
The simulated vehicle's handler is firmware/sim_seed.py.
"""
from ..compat import const
from ..statustext import WARNING

NEEDS = ("commands",)  # its commands
USES = ("status",)  # refused while armed

_CMD_PREFLIGHT_CALIBRATION = const(241)
_CMD_PREFLIGHT_SET_SENSOR_OFFSETS = const(242)
_DENIED = const(2)
_UNSUPPORTED = const(3)


class Calibration:
    NAME = "calibration"
    CLOCK = False

    def __init__(self):
        self.handler = None

    def attach(self, ep):
        self.ep = ep
        ep.commands[_CMD_PREFLIGHT_CALIBRATION] = self._cmd
        ep.commands[_CMD_PREFLIGHT_SET_SENSOR_OFFSETS] = self._cmd

    def _cmd(self, cmd):
        if not self.ep.allows(cmd.link):
            self.ep.statustext(WARNING, b"Calibration: GCS not in control")
            return _DENIED
        status = self.ep.services.get("status")
        if status is not None and status.armed:
            self.ep.statustext(WARNING, b"Calibration refused: armed")
            return _DENIED
        if self.handler is None:
            self.ep.statustext(WARNING, b"Calibration: nothing to calibrate")
            return _UNSUPPORTED
        return self.handler(cmd)


def create(ep):
    return ep.add(Calibration())
