"""Where the vehicle is allowed to be: the GPS global origin and the safety area.

SET_GPS_GLOBAL_ORIGIN and SAFETY_SET_ALLOWED_AREA are kept (storage file "geography")
and told back on change and on request. The other services check targets against the
area through this one (allows..., check_target, check_item), by int32 bytes compared by
16-bit halves, allocating nothing. Also the LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET slot
and the seed's STATE_CORRECTION. Reference: docs/services/seed.md.
"""
import struct
from struct import pack_into

from ..compat import const
from ..fields import LOCAL_FRAMES, f32_is_nan, fix, i32_cmp, unset
from ..kernels import copy
from ..storage import save_sealed, sealed
from ..statustext import WARNING

_FRAME_LOCAL_NED = const(1)
_GLOBAL_TARGET_FRAMES = b"\x00\x03\x05\x06\x0a\x0b"  # global, relative and terrain altitude
_MSG_SET_GPS_GLOBAL_ORIGIN = const(48)
_MSG_GPS_GLOBAL_ORIGIN = const(49)
_MSG_SAFETY_SET_ALLOWED_AREA = const(54)
_MSG_SAFETY_ALLOWED_AREA = const(55)
_MSG_STATE_CORRECTION = const(64)
_MSG_LOCAL_OFFSET = const(89)
_STATE_CORRECTION_CRC_LEN = const(0x242482)  # the seed's #64 (today's #64 is another message)

_INVALID_PARAM5_X = const(10)
_INVALID_PARAM6_Y = const(11)
_INVALID_PARAM7 = const(12)

_FILE = "geography"
# 0 flags (1 origin, 2 area), 1 area frame, 2 origin lat, lon, alt (int32 x3),
# 14 area p1x, p1y, p1z, p2x, p2y, p2z (float32 as given), 38 CRC-16 of 0..37
_FILE_LEN = const(40)
_HAS_ORIGIN = const(1)
_HAS_AREA = const(2)
# The bounds, int32 each: x min, x max, y min, y max, z min, z max
_XMIN = const(0)
_YMIN = const(8)
_ZMIN = const(16)
_FAR_M = 200000.0  # farther (m, an altitude too) than any area's int32 bound: outside it


class Geography:
    NAME = "geography"

    def __init__(self):
        self.origin_set = False
        self.area_set = False
        self.area_local = False
        self.on_state_correction = None  # handler(link, payload), the application's
        self._file = bytearray(_FILE_LEN)
        self._bounds = bytearray(24)
        self._tmp = bytearray(24)  # the corners being checked
        self._z = bytearray(4)  # a mission item's z as an int32
        self._target = bytearray(28)  # a setpoint's position, as a mission record has it
        self.refusing = False  # the last setpoint was outside (told once, not per frame)
        self._slot = None
        self.refused = 0
        self._v1 = self._v2 = self._v3 = self._v4 = self._v5 = self._v6 = 0

    def attach(self, ep):
        self.ep = ep
        # Bound methods made once: making one on a message's path would allocate.
        self._origin_m = self.send_origin
        self._area_m = self.send_area
        ep.on(_MSG_SET_GPS_GLOBAL_ORIGIN, self._on_set_origin)
        ep.on(_MSG_SAFETY_SET_ALLOWED_AREA, self._on_set_area)
        if ep.dialect.CRC_LEN.get(_MSG_STATE_CORRECTION) == _STATE_CORRECTION_CRC_LEN:
            ep.on(_MSG_STATE_CORRECTION, self._on_state_correction)
        if ep.has(_MSG_GPS_GLOBAL_ORIGIN):
            ep.producers[_MSG_GPS_GLOBAL_ORIGIN] = self._origin_m
        if ep.has(_MSG_SAFETY_ALLOWED_AREA):
            ep.producers[_MSG_SAFETY_ALLOWED_AREA] = self._area_m
        if ep.has(_MSG_LOCAL_OFFSET):
            from .streams.telemetry import Slot  # loaded only for the slot: RAM

            self._slot = Slot(ep, _MSG_LOCAL_OFFSET)
            ep.producers[_MSG_LOCAL_OFFSET] = self._slot.send
        self._load()
        storage = getattr(ep, "storage", None)
        if storage is not None:
            storage.reserve(_FILE, _FILE_LEN)

    # --- the API ---------------------------------------------------------------------
    def allows(self, lat_e7, lon_e7, alt_mm=None):
        """Is this global position (1e7 degrees, mm) inside the allowed area?"""
        if not self.area_set or self.area_local:
            return True
        if not _between(self._bounds, _XMIN, lat_e7 >> 16, lat_e7 & 0xFFFF):
            return False
        if not _between(self._bounds, _YMIN, lon_e7 >> 16, lon_e7 & 0xFFFF):
            return False
        if alt_mm is None:
            return True
        z = alt_mm * 10  # the bounds' z is metres * 1e4
        return _between(self._bounds, _ZMIN, z >> 16, z & 0xFFFF)

    def allows_local(self, x_m, y_m, z_m=None):
        """Is this local position (m, NED) inside the allowed area (when it is local)?"""
        if not self.area_set or not self.area_local:
            return True
        for o, v in ((_XMIN, x_m), (_YMIN, y_m), (_ZMIN, z_m)):
            if v is None:
                continue
            if not -_FAR_M < v < _FAR_M:  # (infinities too: no int for them)
                return False
            v = int(v * 10000)
            if not _between(self._bounds, o, v >> 16, v & 0xFFFF):
                return False
        return True

    def origin(self):
        """(lat 1e7 deg, lon 1e7 deg, alt mm) of the GPS global origin, None if not set
        (makes a tuple: for the application, not a hot path)."""
        if not self.origin_set:
            return None
        return struct.unpack_from("<iii", self._file, 2)

    def allows_degrees(self, lat, lon, alt_m=None):
        """allows() for degrees and metres (floats: for the simulator, not a hot path)."""
        if not self.area_set or self.area_local:
            return True
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and _near(alt_m)):
            return False  # (NaN and infinities too)
        return self.allows(int(round(lat * 1e7)), int(round(lon * 1e7)),
                           None if alt_m is None else int(round(alt_m * 1000)))

    def allows_command(self, cmd, frame=-1):
        """Is a command's position (param5-7 in its frame; COMMAND_LONG's as `frame`, else
        global) inside the area? False with a STATUSTEXT. Makes floats: not for setpoints."""
        if not self.area_set:
            return True
        f = cmd.frame if cmd.is_int else (frame if frame >= 0 else 0)
        z = cmd.float(7) if cmd.finite(7) else None
        if cmd.nan(5) or cmd.nan(6):
            ok = True
        elif f in LOCAL_FRAMES:
            ok = self.allows_local(cmd.float(5), cmd.float(6), z)
        elif cmd.is_int:
            x, y = cmd.int(5), cmd.int(6)
            ok = not (x or y) or x == 0x7FFFFFFF or (_near(z) and self.allows(x, y, None if z is None else int(z * 1000)))
        else:
            ok = self.allows_degrees(cmd.float(5), cmd.float(6), z)
        if not ok:
            self.refused += 1
            self.ep.statustext(WARNING, b"Target outside the allowed area")
        return ok

    def check_target(self, p, is_global):
        """A position setpoint inside the area (or not checked)? Its x, y, z go into a
        mission record's places and check_item decides, allocating nothing."""
        if not self.area_set or p[48] & 7 == 7:  # type_mask: x, y and z ignored
            return True
        frame = p[52]
        t = self._target
        copy(t, p, 4 << 10 | 16, 12)
        if is_global:
            if frame not in _GLOBAL_TARGET_FRAMES:
                return True
        elif frame != _FRAME_LOCAL_NED:
            return True
        else:
            fix(t, 16, True)
            fix(t, 20, True)
        return self._told(self.check_item(t, frame) == 0)

    def _told(self, ok):
        if not ok and not self.refusing:
            self.refused += 1
            self.ep.statustext(WARNING, b"Setpoint outside the allowed area")
        self.refusing = not ok
        return ok

    def check_item(self, rec, frame):
        """A mission record's position against the area -> 0 or the MAV_MISSION_RESULT
        naming the coordinate outside it (other frames' items and unset ones pass)."""
        if not self.area_set or (frame in LOCAL_FRAMES) != self.area_local:
            return 0
        b = self._bounds
        if not unset(rec, 16) and not _inside(b, _XMIN, rec, 16):
            return _INVALID_PARAM5_X
        if not unset(rec, 20) and not _inside(b, _YMIN, rec, 20):
            return _INVALID_PARAM6_Y
        if f32_is_nan(rec, 24):
            return 0
        copy(self._z, rec, 24 << 10, 4)
        fix(self._z, 0, True)
        return 0 if _inside(b, _ZMIN, self._z, 0) else _INVALID_PARAM7

    def local_offset(self, x, y, z, roll, pitch, yaw):
        """LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET: m, rad."""
        # Staged, then packed by a function of few locals (see _pack_offset).
        self._v1, self._v2, self._v3 = x, y, z  # (three at a time: no tuple is made)
        self._v4, self._v5, self._v6 = roll, pitch, yaw
        self._pack_offset()

    def _pack_offset(self):
        s = self._slot
        if s is None:
            return
        pack_into("<fff", s.buf, 4, self._v1, self._v2, self._v3)
        pack_into("<fff", s.buf, 16, self._v4, self._v5, self._v6)
        self.ep.clock.stamp_ms(s.buf, 0)
        s.written = True

    # --- producers ---------------------------------------------------------------------
    def send_origin(self, link):
        if not self.origin_set:
            return False
        off = link.begin()
        copy(link.txbuf, self._file, 2 << 10 | off, 12)
        return link.send(_MSG_GPS_GLOBAL_ORIGIN)

    def send_area(self, link):
        if not self.area_set:
            return False
        off = link.begin()
        copy(link.txbuf, self._file, 14 << 10 | off, 24)
        link.txbuf[off + 24] = self._file[1]
        return link.send(_MSG_SAFETY_ALLOWED_AREA)

    # --- inbound -----------------------------------------------------------------------
    def _may(self, link, target_system, target_component):
        if not self.ep.for_us(target_system, target_component):
            return False
        if self.ep.allows(link):
            return True
        self.refused += 1
        self.ep.statustext(WARNING, b"Geography: GCS not in control")
        return False

    def _on_set_origin(self, link, p):
        if not self._may(link, p[12], 0):
            return
        if not _latitude_ok(p, 0):
            self.refused += 1
            self.ep.statustext(WARNING, b"Origin refused: latitude out of range")
            return
        copy(self._file, p, 0 << 10 | 2, 12)
        self._file[0] |= _HAS_ORIGIN
        self.origin_set = True
        self._save()
        self._to_all(self._origin_m)

    def _on_set_area(self, link, p):
        if not self._may(link, p[24], p[25]):
            return
        if _zeros(p, 24):
            self._file[0] &= ~_HAS_AREA & 0xFF
            self.area_set = False
        elif not self._bounds_from(p, 0, p[26]):
            self.refused += 1
            self.ep.statustext(WARNING, b"Allowed area refused: bad corner")
            return
        else:
            copy(self._file, p, 0 << 10 | 14, 24)
            self._file[1] = p[26]
            self._file[0] |= _HAS_AREA
            self.area_set = True
            self.area_local = p[26] in LOCAL_FRAMES
        self._save()
        self._to_all(self._area_m)

    def _on_state_correction(self, link, p):
        if self.on_state_correction is not None:
            self.on_state_correction(link, p)

    def _to_all(self, producer):
        i = 0
        while i < len(self.ep.links):
            producer(self.ep.links[i])
            i += 1

    # --- the bounds --------------------------------------------------------------------
    def _bounds_from(self, p, o, frame):
        """The six float32 at p[o:] (p1x, p1y, p1z, p2x, p2y, p2z) as int32 bounds ->
        False for NaN, infinities, values beyond int32, latitudes beyond +-90."""
        t = self._tmp
        copy(t, p, o << 10, 24)
        local = frame in LOCAL_FRAMES
        if not _fixed(t, local):
            return False
        if not local and not (_latitude_ok(t, 0) and _latitude_ok(t, 12)):
            return False
        _order3(self._bounds, t)
        return True

    # --- storage -----------------------------------------------------------------------
    def _load(self):
        storage = getattr(self.ep, "storage", None)
        if storage is None or not storage.exists(_FILE):
            return
        try:
            with storage.open(_FILE) as f:
                data = f.read()
        except OSError:
            data = b""
        if not sealed(data, _FILE_LEN):
            self.ep.statustext(WARNING, b"Origin and allowed area corrupt: cleared")
            return
        copy(self._file, data, 0, _FILE_LEN)
        self.origin_set = bool(data[0] & _HAS_ORIGIN)
        if data[0] & _HAS_AREA and self._bounds_from(data, 14, data[1]):
            self.area_set = True
            self.area_local = data[1] in LOCAL_FRAMES
        else:
            self._file[0] &= _HAS_ORIGIN

    def _save(self):
        try:
            self._write()
        except OSError:
            self.ep.statustext(WARNING, b"Origin and allowed area not saved")

    def _write(self):
        storage = getattr(self.ep, "storage", None)
        if storage is None:
            return
        save_sealed(storage, _FILE, self._file)


# Helpers of few locals (docs/design.md).
def _near(m):
    return m is None or -_FAR_M < m < _FAR_M


def _between(b, o, hi, lo):
    """bounds b[o] (min) <= hi:lo <= b[o + 4] (max)."""
    return i32_cmp(b, o, hi, lo) <= 0 and i32_cmp(b, o + 4, hi, lo) >= 0


def _inside(b, o, v, vo):
    """The int32 at v[vo] within the bounds b[o], b[o + 4]."""
    return _le(b, o, v, vo) and _le(v, vo, b, o + 4)


def _le(a, ao, b, bo):
    """The int32 at a[ao] <= the one at b[bo], by halves."""
    d = _hi(a, ao) - _hi(b, bo)
    if d:
        return d < 0
    return _lo(a, ao) <= _lo(b, bo)


def _lo(v, o):
    return v[o] | v[o + 1] << 8


def _hi(v, o):
    """The signed high half of the int32 at v[o]."""
    hi = v[o + 2] | v[o + 3] << 8
    return hi - 0x10000 if hi & 0x8000 else hi


def _order(b, o, t, i, j):
    """b[o] = the smaller of the int32 t[i], t[j]; b[o + 4] the larger."""
    if _greater(t, i, j):
        i, j = j, i
    copy(b, t, i << 10 | o, 4)
    copy(b, t, j << 10 | (o + 4), 4)


def _order3(b, t):
    # The corners (x, y, z of p1 at t[0..11], of p2 at t[12..23]) as min, max bounds.
    _order(b, _XMIN, t, 0, 12)
    _order(b, _YMIN, t, 4, 16)
    _order(b, _ZMIN, t, 8, 20)


def _greater(t, i, j):
    """The int32 at t[i] > the one at t[j]."""
    lo = t[j] | t[j + 1] << 8
    return i32_cmp(t, i, _hi(t, j), lo) > 0


def _fixed(t, local):
    """The corners' float32 made int32 in place: x, y as degrees * 1e7 (metres * 1e4
    where local), z as metres * 1e4 -> False if one is no number or beyond int32."""
    return (fix(t, 0, local) and fix(t, 4, local) and fix(t, 12, local) and fix(t, 16, local)
            and fix(t, 8, True) and fix(t, 20, True))


def _latitude_ok(p, o):
    # -90e7 <= lat <= 90e7, by halves (see missions/items.py)
    return i32_cmp(p, o, 13732, 59648) <= 0 and i32_cmp(p, o, -13733, 5888) >= 0


def _zeros(p, n):
    i = 0
    while i < n:
        if p[i]:
            return False
        i += 1
    return True


def create(ep):
    return ep.add(Geography())
