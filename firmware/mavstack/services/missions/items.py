"""What a mission item must hold: the check of an uploaded item against the rules of its
plan type (frames the vehicle flies, commands it knows, numbers where a command needs
them, positions within range or left unset where the command takes "where the vehicle
is", DO_JUMP targets within the plan), its 32-byte record built on the way (store.py's
layout), the STATUSTEXT that names a refused item, and the seed's MISSION_ITEM float
degrees converted to MISSION_ITEM_INT's 1e7 integers. Allocation-free on a 32-bit board
too: coordinates stay in their bytes, and the refusal's text is written into a buffer
made at import. m is the missions service (its record buffer, frames, extra commands
and the transfer under way). Reference: docs/services/missions.md.
"""
import gc

from ...compat import const
from ...fields import LOCAL_FRAMES, f32_is_nan, f32_to_small, fix, i32_cmp, u16, unset
from ...kernels import copy, zero

# Loading a module from a .mpy leaves the loader's garbage between the code it kept:
# collect it now, so that what comes next finds room on a small heap.
gc.collect()

# MAV_MISSION_RESULT
_ACCEPTED = const(0)
_UNSUPPORTED_FRAME = const(2)
_UNSUPPORTED = const(3)
_INVALID_PARAM1 = const(6)
_INVALID_PARAM5_X = const(10)
_INVALID_PARAM6_Y = const(11)
_INVALID_PARAM7 = const(12)
_SEVERITY_ERROR = const(3)  # MAV_SEVERITY

_TYPE_MISSION = const(0)
_CMD_DO_JUMP = const(177)
_FRAME_MISSION = const(2)

# Position bounds in 1e7 degrees, as (signed high half, low half): +-90e7, +-180e7.
_LAT_MAX_HI = const(13732)  # 900000000 = 13732 * 65536 + 59648
_LAT_MAX_LO = const(59648)
_LAT_MIN_HI = const(-13733)  # -900000000 = -13733 * 65536 + 5888
_LAT_MIN_LO = const(5888)
_LON_MAX_HI = const(27465)  # 1800000000 = 27465 * 65536 + 53760
_LON_MAX_LO = const(53760)
_LON_MIN_HI = const(-27466)  # -1800000000 = -27466 * 65536 + 11776
_LON_MIN_LO = const(11776)

# What an item's command needs, per MAV_MISSION_TYPE: 3 bytes a command, its id (little
# endian) and what it needs: bits 0-3 param1-4 must be numbers, _P7 z must be a
# number, _POS x/y are a position (range-checked in global frames, refused in
# MAV_FRAME_MISSION), _HERE x/y may be unset (INT32_MAX in MISSION_ITEM_INT, NaN in
# MISSION_ITEM): the position the vehicle is at when it gets there. Bytes, not tuples:
# a small board keeps them in one object. Beyond the seed's commands, those today's
# planners put in their missions (speed, delays, regions of interest, landing
# sequences, camera and gimbal): the application sees each one as the runner makes it
# current (runner.on_item); what it has nothing to do for it steps over.
_P1 = const(1)
_P2 = const(2)
_HERE = const(16)
_P7 = const(64)
_POS = const(128)
_MISSION_RULES = (
    b"\x10\x00\xc0"  # 16 NAV_WAYPOINT: _POS | _P7
    b"\x11\x00\xd0"  # 17 NAV_LOITER_UNLIM: _POS | _P7 | _HERE
    b"\x12\x00\xd1"  # 18 NAV_LOITER_TURNS: _POS | _P7 | _HERE | _P1
    b"\x13\x00\xd1"  # 19 NAV_LOITER_TIME: _POS | _P7 | _HERE | _P1
    b"\x14\x00\x00"  # 20 NAV_RETURN_TO_LAUNCH
    b"\x15\x00\x90"  # 21 NAV_LAND: _POS | _HERE (z NaN: land at ground level)
    b"\x16\x00\x90"  # 22 NAV_TAKEOFF: _POS | _HERE (z NaN: the default takeoff altitude)
    b"\x1f\x00\xd0"  # 31 NAV_LOITER_TO_ALT: _POS | _P7 | _HERE
    b"\x50\x00\x00"  # 80 NAV_ROI
    b"\x51\x00\x00"  # 81 NAV_PATHPLANNING
    b"\x5d\x00\x01"  # 93 NAV_DELAY: _P1 (seconds; -1: until the time of day in param2-4)
    b"\x70\x00\x01"  # 112 CONDITION_DELAY: _P1
    b"\x71\x00\x41"  # 113 CONDITION_CHANGE_ALT: _P1 | _P7
    b"\x72\x00\x01"  # 114 CONDITION_DISTANCE: _P1
    b"\x73\x00\x01"  # 115 CONDITION_YAW: _P1
    b"\xb0\x00\x01"  # 176 DO_SET_MODE: _P1
    b"\xb1\x00\x03"  # 177 DO_JUMP: _P1 | _P2
    b"\xb2\x00\x02"  # 178 DO_CHANGE_SPEED: _P2
    b"\xb3\x00\x01"  # 179 DO_SET_HOME: _P1
    b"\xb4\x00\x03"  # 180 DO_SET_PARAMETER: _P1 | _P2
    b"\xb5\x00\x03"  # 181 DO_SET_RELAY: _P1 | _P2
    b"\xb6\x00\x03"  # 182 DO_REPEAT_RELAY: _P1 | _P2
    b"\xb7\x00\x03"  # 183 DO_SET_SERVO: _P1 | _P2
    b"\xb8\x00\x03"  # 184 DO_REPEAT_SERVO: _P1 | _P2
    b"\xbd\x00\x00"  # 189 DO_LAND_START (its x/y, if any, only tell sequences apart)
    b"\xc3\x00\x80"  # 195 DO_SET_ROI_LOCATION: _POS
    b"\xc4\x00\x00"  # 196 DO_SET_ROI_WPNEXT_OFFSET
    b"\xc5\x00\x00"  # 197 DO_SET_ROI_NONE
    b"\xc8\x00\x00"  # 200 DO_CONTROL_VIDEO
    b"\xc9\x00\x01"  # 201 DO_SET_ROI: _P1 (the ROI mode)
    b"\xca\x00\x00"  # 202 DO_DIGICAM_CONFIGURE
    b"\xcb\x00\x00"  # 203 DO_DIGICAM_CONTROL
    b"\xcc\x00\x01"  # 204 DO_MOUNT_CONFIGURE: _P1 (the mount mode)
    b"\xcd\x00\x00"  # 205 DO_MOUNT_CONTROL
    b"\xce\x00\x01"  # 206 DO_SET_CAM_TRIGG_DIST: _P1 (metres, 0: stop)
    b"\xd6\x00\x01"  # 214 DO_SET_CAM_TRIGG_INTERVAL: _P1 (ms)
    b"\xe8\x03\x00"  # 1000 DO_GIMBAL_MANAGER_PITCHYAW (NaN: no change)
    b"\x12\x02\x00"  # 530 SET_CAMERA_MODE
    b"\x13\x02\x00"  # 531 SET_CAMERA_ZOOM
    b"\x14\x02\x00"  # 532 SET_CAMERA_FOCUS
    b"\xd0\x07\x00"  # 2000 IMAGE_START_CAPTURE
    b"\xd1\x07\x00"  # 2001 IMAGE_STOP_CAPTURE
    b"\xc4\x09\x00"  # 2500 VIDEO_START_CAPTURE
    b"\xc5\x09\x00"  # 2501 VIDEO_STOP_CAPTURE
    b"\x95\x11\x80"  # 4501 CONDITION_GATE: _POS (a survey's line ends)
)
_FENCE_RULES = (
    b"\x88\x13\x80"  # 5000 NAV_FENCE_RETURN_POINT: _POS
    b"\x89\x13\x81"  # 5001 NAV_FENCE_POLYGON_VERTEX_INCLUSION: _POS | _P1 (vertex count)
    b"\x8a\x13\x81"  # 5002 NAV_FENCE_POLYGON_VERTEX_EXCLUSION: _POS | _P1
    b"\x8b\x13\x81"  # 5003 NAV_FENCE_CIRCLE_INCLUSION: _POS | _P1 (radius)
    b"\x8c\x13\x81"  # 5004 NAV_FENCE_CIRCLE_EXCLUSION: _POS | _P1
)
_RALLY_RULES = b"\xec\x13\xc0"  # 5100 NAV_RALLY_POINT: _POS | _P7
_RULES = (_MISSION_RULES, _FENCE_RULES, _RALLY_RULES)


def check(m, p, is_int, seq):
    """Validate item seq (payload p of MISSION_ITEM_INT, or MISSION_ITEM if not is_int)
    and build its record in m.rec -> MAV_MISSION_RESULT. A refusal is also told in a
    STATUSTEXT naming the item, its command and what is wrong with it."""
    result = _check(m, p, is_int, seq)
    if result != _ACCEPTED:
        _refused(m, seq, result)
    return result


def _check(m, p, is_int, seq):
    # The record: params, x, y, z as they came, command, frame, autocontinue.
    copy(m.rec, p, 0, 28)
    m.rec[28] = p[30]
    m.rec[29] = p[31]
    m.rec[30] = p[34]
    m.rec[31] = p[36]
    frame = p[34]
    if frame not in m.frames:
        return _UNSUPPORTED_FRAME
    need = _need(m, u16(p, 30))
    if need < 0:
        return _UNSUPPORTED
    if need & _POS and frame == _FRAME_MISSION:
        return _UNSUPPORTED_FRAME
    return (_xy(m.rec, frame in LOCAL_FRAMES, need, is_int) or _numbers(p, need)
            or (_jump(m, p, seq) if u16(p, 30) == _CMD_DO_JUMP else _area(m, need)))


def _area(m, need):
    """A position outside the allowed area (services/geography.py, when the board has
    it) -> INVALID_PARAM5_X / _PARAM6_Y / _PARAM7 for the coordinate outside."""
    if not need & _POS:
        return _ACCEPTED
    geo = m.ep.services.get("geography")
    return _ACCEPTED if geo is None else geo.check_item(m.rec, m.rec[30])


def _need(m, command):
    """What the command needs (_P*, _POS bits), -1 if this plan type does not take it."""
    mt = m.transfer.store.mission_type
    rules = _RULES[mt]
    for i in range(0, len(rules), 3):
        if rules[i] | rules[i + 1] << 8 == command:
            return rules[i + 2]
    if mt == _TYPE_MISSION and m.extra is not None:
        return m.extra.get(command, -1)
    return -1


def _xy(rec, local, need, is_int):
    """x, y of the record: the seed's float degrees made integers, then range-checked."""
    if not _coord(rec, 16, local, need, is_int):
        return _INVALID_PARAM5_X
    if not _coord(rec, 20, local, need, is_int):
        return _INVALID_PARAM6_Y
    return _ACCEPTED


def _coord(rec, o, local, need, is_int):
    """x (o 16) or y (o 20) of the record -> False if refused. Unset where the command
    takes that (INT32_MAX, or NaN in the seed's form) is stored as INT32_MAX; the seed's
    NaN or beyond int32 is refused where a position is needed, else stored as 0."""
    if need & _HERE and (unset(rec, o) if is_int else f32_is_nan(rec, o)):
        rec[o] = rec[o + 1] = rec[o + 2] = 0xFF
        rec[o + 3] = 0x7F
        return True
    if not is_int and not fix(rec, o, local) and need & _POS:
        return False
    if not need & _POS or local:
        return True
    # Latitude (o 16) within +-90 degrees, longitude within +-180, by 16-bit halves:
    # a high half strictly between the bounds' is within them, else the halves compare.
    hi = rec[o + 2] | rec[o + 3] << 8
    if hi & 0x8000:
        hi -= 0x10000
    if o == 16:
        return _LAT_MIN_HI < hi < _LAT_MAX_HI or (
            i32_cmp(rec, 16, _LAT_MAX_HI, _LAT_MAX_LO) <= 0 and i32_cmp(rec, 16, _LAT_MIN_HI, _LAT_MIN_LO) >= 0)
    return _LON_MIN_HI < hi < _LON_MAX_HI or (
        i32_cmp(rec, 20, _LON_MAX_HI, _LON_MAX_LO) <= 0 and i32_cmp(rec, 20, _LON_MIN_HI, _LON_MIN_LO) >= 0)


# --- the STATUSTEXT of a refused item ------------------------------------------------
# "Mission item 12: cmd 31000 unsupported", written into a buffer made at import: a
# refusal is rare, but the board may run with its heap locked.
_TEXT = bytearray(50)
_PLAN = (b"Mission item ", b"Fence item ", b"Rally item ")
_WHY = (b" frame ", b" unsupported", b" invalid", b" param", b" x/lat", b" y/lon", b" z/alt")


def _refused(m, seq, result):
    # Statement by statement, few values on the stack (docs/design.md, function frames).
    # The command and frame are in the record.
    n = _text(0, _PLAN[m.transfer.store.mission_type])
    n = _digits(n, seq)
    n = _text(n, b": cmd ")
    n = _digits(n, u16(m.rec, 28))
    # What is wrong: " frame 1 unsupported", " unsupported", " param1 invalid" ...
    if result == _UNSUPPORTED_FRAME:
        n = _text(n, _WHY[0])
        n = _digits(n, m.rec[30])
        n = _text(n, _WHY[1])
    elif result == _UNSUPPORTED:
        n = _text(n, _WHY[1])
    elif _INVALID_PARAM1 <= result < _INVALID_PARAM5_X:
        n = _text(n, _WHY[3])
        n = _digits(n, result - _INVALID_PARAM1 + 1)
        n = _text(n, _WHY[2])
    elif _INVALID_PARAM5_X <= result <= _INVALID_PARAM7:
        n = _text(n, _WHY[4 + result - _INVALID_PARAM5_X])
        n = _text(n, _WHY[2])
    else:
        n = _text(n, b" result ")
        n = _digits(n, result)
    zero(_TEXT, n, len(_TEXT))
    m.ep.statustext(_SEVERITY_ERROR, _TEXT)


def _text(at, text):
    """_TEXT[at:] = text, cut at its end -> the offset after it."""
    i = 0
    while i < len(text) and at < len(_TEXT):
        _TEXT[at] = text[i]
        at += 1
        i += 1
    return at


def _digits(at, n):
    """The decimal digits of 0 <= n < 100000 at _TEXT[at:], cut at its end -> the offset
    after them."""
    d = 10000
    while d > 1 and n < d:
        d //= 10
    while d and at < len(_TEXT):
        _TEXT[at] = 0x30 + n // d % 10
        at += 1
        d //= 10
    return at


def _jump(m, p, seq):
    # f32_to_small: a target or repeat count beyond 2^30 is as wrong as any other.
    target = f32_to_small(p, 0)
    if target < 0 or target >= m.transfer.count or target == seq:
        return _INVALID_PARAM1
    if f32_to_small(p, 4) < -1:
        return _INVALID_PARAM1 + 1
    return _ACCEPTED


def _numbers(p, need):
    """NaN where the command needs a number -> INVALID_PARAM1..4, 7; else ACCEPTED."""
    i = 0
    while need >> i & 0x0F:  # (param1..4 as needed: a waypoint needs none of them)
        if need >> i & 1 and f32_is_nan(p, i * 4):
            return _INVALID_PARAM1 + i
        i += 1
    if need & _P7 and f32_is_nan(p, 24):
        return _INVALID_PARAM7
    return _ACCEPTED
