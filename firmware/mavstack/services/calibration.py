"""PREFLIGHT_CALIBRATION (241) and PREFLIGHT_SET_SENSOR_OFFSETS (242): the application's.

Calibrating sensors and setting their offsets is the board's business, so both
commands go to the application's handler:
    ep.services["calibration"].handler = handler(cmd) -> MAV_RESULT
(cmd as services/commands/ hands it; cmd.defer() for a calibration that takes time).
Built in, before the handler: the sender must be in control and the vehicle disarmed
(a calibration moves the estimates the vehicle flies by): otherwise DENIED, with a
STATUSTEXT. Without a handler: UNSUPPORTED with a STATUSTEXT (nothing to calibrate).
The simulated vehicle's handler is firmware/sim/seed.py.
Reference (the commands' parameters): docs/services/seed.md.
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
