"""What a peripheral's application sends: slots made once, each holding its message's
payload, so that a send packs the new value into it and frames it on every link without
allocating (DISTANCE_SENSOR, NAMED_VALUE_FLOAT, NAMED_VALUE_INT). Made by the peripheral
service (peripheral.distance_sensor(), named_float(), named_int()); sent at RANK_FILL, so
heartbeats and answers go first on a busy link.
Reference: docs/services/peripheral.md
"""
from struct import pack_into

from ...compat import const
from ...link import RANK_FILL, RANK_AUTO

_MSG_DISTANCE_SENSOR = const(132)
_MSG_NAMED_VALUE_FLOAT = const(251)
_MSG_NAMED_VALUE_INT = const(252)
_DISTANCE_LEN = const(39)  # MAVLink 2 payload: quaternion and signal_quality included
_NAMED_LEN = const(18)


class _Slot:
    MSGID = -1

    def send_to(self, link):
        """This slot's payload as it is, on one link -> sent (a producer: REQUEST_MESSAGE)."""
        self.ep.clock.stamp_ms(self.payload, 0)
        link.rank = RANK_FILL
        sent = link.send_payload(self.MSGID, self.payload, self.n)
        link.rank = RANK_AUTO
        return sent

    def _all(self):
        links = self.ep.links
        i = 0  # by index: see docs/design.md
        sent = 0
        while i < len(links):
            if self.send_to(links[i]):
                sent += 1
            i += 1
        return sent


class DistanceSensor(_Slot):
    MSGID = _MSG_DISTANCE_SENSOR

    def __init__(self, ep, min_cm, max_cm, kind, sensor_id, orientation):
        self.ep = ep
        self.n = _DISTANCE_LEN
        self.payload = bytearray(_DISTANCE_LEN)
        self.configure(min_cm, max_cm, kind, sensor_id, orientation)

    def configure(self, min_cm, max_cm, kind, sensor_id, orientation):
        """The sensor's range, type, id and orientation (a parameter set: in place)."""
        # time_boot_ms, min, max, current; type, id, orientation, covariance (255: unknown)
        pack_into("<HH", self.payload, 4, min_cm, max_cm)
        pack_into("<BBBB", self.payload, 10, kind, sensor_id, orientation, 255)

    def send(self, distance_cm, quality=0):
        """current_distance in cm (UINT16_MAX: no reading), signal_quality 0-100 (0:
        unknown) -> on how many links it went."""
        p = self.payload
        p[8] = distance_cm & 0xFF
        p[9] = (distance_cm >> 8) & 0xFF
        p[38] = quality
        return self._all()


class NamedValue(_Slot):
    def __init__(self, ep, name, is_int):
        self.ep = ep
        self.MSGID = _MSG_NAMED_VALUE_INT if is_int else _MSG_NAMED_VALUE_FLOAT
        self._fmt = "<i" if is_int else "<f"
        self.n = _NAMED_LEN
        self.payload = bytearray(_NAMED_LEN)
        raw = name.encode() if isinstance(name, str) else bytes(name)
        if len(raw) > 10:
            raise ValueError("a NAMED_VALUE name has at most 10 characters")
        self.payload[8:8 + len(raw)] = raw

    def send(self, value):
        """-> on how many links it went."""
        pack_into(self._fmt, self.payload, 4, value)
        return self._all()
