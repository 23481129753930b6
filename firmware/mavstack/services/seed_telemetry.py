"""The seed's setpoint reports, slots the application fills: what the vehicle is steering
to, in the seed's message set (seed2012) only.

local_setpoint(), global_setpoint(), attitude_setpoint(), speed_setpoint() and
rates_setpoint() pack LOCAL_POSITION_SETPOINT, GLOBAL_POSITION_SETPOINT_INT and the three
ROLL_PITCH_YAW_*_SETPOINT into slots that streams and REQUEST_MESSAGE send. A slot exists
only where the dialect's id is the seed's message; elsewhere the setters do nothing. Where
the inputs service echoes a SET_*_SETPOINT into the same message, the slot is that one.
Reference: docs/services/streams.md.
"""
from struct import pack_into

from ..compat import const
from .streams.slots import Slot

AFTER = ("inputs",)  # its echoes share the inputs service's slots

_LOCAL = const(51)
_GLOBAL = const(52)
_ATTITUDE = const(58)
_SPEED = const(59)
_RATES = const(80)
# The seed's CRC_EXTRA | len << 8 | len << 16 of each (dialects/seed2012.py)
SEED = ((_LOCAL, 0x1111DF), (_GLOBAL, 0x0F0F8D), (_ATTITUDE, 0x1414EF),
        (_SPEED, 0x1414EE), (_RATES, 0x14147F))


class SeedTelemetry:
    NAME = "seed_telemetry"

    def __init__(self):
        self.slots = {}
        self._local = self._global = self._attitude = self._speed = self._rates = None
        self._v1 = self._v2 = self._v3 = self._v4 = self._frame = 0

    def attach(self, ep):
        self.ep = ep
        for msgid, crc_len in SEED:
            if ep.dialect.CRC_LEN.get(msgid) == crc_len:
                slot = _echo_slot(ep, msgid) or Slot(ep, msgid)
                self.slots[msgid] = slot
                ep.producers[msgid] = slot.send
        g = self.slots.get
        self._local = g(_LOCAL)
        self._global = g(_GLOBAL)
        self._attitude = g(_ATTITUDE)
        self._speed = g(_SPEED)
        self._rates = g(_RATES)

    # Setters stage their values (self._v1..) and a function of few locals packs them
    # (small frames: see docs/design.md).
    def local_setpoint(self, frame, x, y, z, yaw):
        self._v1 = x
        self._v2 = y
        self._v3 = z
        self._v4 = yaw
        self._frame = frame
        self._pack_local()

    def global_setpoint(self, frame, lat, lon, alt, yaw):
        self._v1 = lat
        self._v2 = lon
        self._v3 = alt
        self._v4 = yaw
        self._frame = frame
        self._pack_global()

    def attitude_setpoint(self, roll, pitch, yaw, thrust):
        self._stage(roll, pitch, yaw, thrust)
        self._pack_four(self._attitude)

    def speed_setpoint(self, roll_speed, pitch_speed, yaw_speed, thrust):
        self._stage(roll_speed, pitch_speed, yaw_speed, thrust)
        self._pack_four(self._speed)

    def rates_setpoint(self, roll_rate, pitch_rate, yaw_rate, thrust):
        self._stage(roll_rate, pitch_rate, yaw_rate, thrust)
        self._pack_four(self._rates)

    def _stage(self, a, b, c, d):
        self._v1 = a
        self._v2 = b
        self._v3 = c
        self._v4 = d

    def _pack_local(self):
        s = self._local
        if s is None:
            return
        pack_into("<ffff", s.buf, 0, self._v1, self._v2, self._v3, self._v4)
        s.buf[16] = self._frame
        s.written = True

    def _pack_global(self):
        s = self._global
        if s is None:
            return
        pack_into("<iii", s.buf, 0, self._v1, self._v2, self._v3)
        pack_into("<hB", s.buf, 12, self._v4, self._frame)
        s.written = True

    def _pack_four(self, s):
        # time_boot_ms, then four floats
        if s is None:
            return
        pack_into("<ffff", s.buf, 4, self._v1, self._v2, self._v3, self._v4)
        self.ep.clock.stamp_ms(s.buf, 0)
        s.written = True


def _echo_slot(ep, msgid):
    """The slot the inputs service (inputs/echo.py) already echoes a setpoint into:
    one message, one slot, whether a setpoint or the application wrote it last."""
    inputs = ep.services.get("inputs")
    for r in getattr(inputs, "records", ()):
        echo = getattr(r, "echo", None)
        if echo is not None and echo.slot.msgid == msgid:
            return echo.slot
    return None


def create(ep):
    return ep.add(SeedTelemetry())
