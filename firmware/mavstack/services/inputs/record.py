"""One pilot or offboard input as the application reads it: the latest payload, copied
into a buffer made at start-up, with allocation-free accessors, its age and its sender.

Input reads any kind's fields by wire offset (u8 ... i32; milli(): a float32 times 1000
as an int, from its bits); ManualInput, RcOverride, PositionTarget and AttitudeTarget name
their kinds' fields. Reference: docs/services/inputs.md.
"""
from struct import unpack_from

from ...compat import const, ticks_diff
from ...fields import f32_is_nan
from ...kernels import copy

AGE_NEVER = const(0x3FFFFFFF)
_MILLI_MAX = const(0x3FFFFFFF)


class Input:
    def __init__(self, svc, kind, msgid, target_system=-1, target_component=-1):
        ep = svc.ep
        self.svc = svc
        self.ep = ep
        self.kind = kind
        self.msgid = msgid
        self.size = ep.dialect.CRC_LEN[msgid] >> 16
        self.buf = bytearray(self.size)
        self.ts = target_system  # wire offset of target_system, -1: none (broadcast input)
        self.tc = target_component
        self.seen = False
        self.live = False  # arriving: loss not yet reported
        self.stamp = 0
        self.sysid = 0
        self.compid = 0
        self.link = -1
        self.count = 0
        self.callback = None
        self.echo = None  # an Echo (echo.py) the input is answered with

    # --- arrival (per frame: a few compares and a copy, nothing allocated) ----------
    def deliver(self, link, p):
        if not self._for_us(p) or not self.ep.allows(link):
            return
        copy(self.buf, p, 0, self.size)
        self.stamp = self.ep.now
        rx = link.rx
        self.sysid = rx.sysid
        self.compid = rx.compid
        self.link = link.index
        self.seen = True
        self.live = True
        self.count = (self.count + 1) & 0x3FFFFFFF
        self.arrived()
        if self.echo is not None:
            self.echo.answer(self.buf)
        if self.callback is not None:
            self.callback(self)

    def _for_us(self, p):
        ep = self.ep
        if self.ts >= 0 and p[self.ts] != 0 and p[self.ts] != ep.sysid:
            return False
        return self.tc < 0 or p[self.tc] == 0 or p[self.tc] == ep.compid

    def arrived(self):
        """What a kind does with a new value beyond keeping it (RC override: channels)."""

    # --- age --------------------------------------------------------------------
    def age_ms(self):
        if not self.seen:
            return AGE_NEVER
        d = ticks_diff(self.ep.now, self.stamp)
        return d if d < AGE_NEVER else AGE_NEVER

    def fresh(self):
        return self.seen and ticks_diff(self.ep.now, self.stamp) <= self.svc.timeout_ms

    def stamp_newer(self, other):
        """Arrived after the other input's last (both seen)."""
        return ticks_diff(self.stamp, other.stamp) > 0

    # --- reads by wire offset -------------------------------------------------------
    def u8(self, o):
        return self.buf[o] if o < self.size else 0

    def i8(self, o):
        v = self.u8(o)
        return v - 256 if v & 0x80 else v

    def u16(self, o):
        if o + 1 >= self.size:
            return 0
        b = self.buf
        return b[o] | b[o + 1] << 8

    def i16(self, o):
        v = self.u16(o)
        return v - 0x10000 if v & 0x8000 else v

    def u32(self, o):
        return self.u16(o) | self.u16(o + 2) << 16

    def i32(self, o):
        return self.i16(o + 2) << 16 | self.u16(o)

    def is_nan(self, o):
        return bool(f32_is_nan(self.buf, o))

    def milli(self, o):
        return milli(self.buf, o)

    def f(self, o):
        """The float32 at o (allocates on MicroPython)."""
        return unpack_from("<f", self.buf, o)[0]


def milli(p, o):
    """The float32 at p[o] times 1000, rounded, as a small int: NaN and infinities 0,
    |f| >= 2^20 saturated at +-(2^30 - 1). From its bits, in 16-bit halves, so no float
    and no int of 2^30 or more is made."""
    hi = p[o + 2] | p[o + 3] << 8
    e = (hi >> 7) & 0xFF
    if e == 0xFF or e < 100:  # NaN, inf; |f| < 2^-27 reads 0
        return 0
    # |f| >= 2^20: f * 1000 too close to 2^30
    v = _MILLI_MAX if e > 146 else _magnitude(p, o, hi, 150 - e)
    return -v if hi & 0x8000 else v


def _magnitude(p, o, hi, s):
    # f = m * 2^-s (s >= 4), m of 24 bits: f * 1000 = (m * 1000) >> s, m split into its
    # top 13 and bottom 11 bits so that no product reaches 2^30. (A function of its own,
    # to keep both frames small.)
    mh = (hi & 0x7F | 0x80) << 5 | p[o + 1] >> 3
    ml = (p[o + 1] & 7) << 8 | p[o]
    if s <= 11:
        return (mh * 1000 << (11 - s)) + ((ml * 1000 + (1 << (s - 1))) >> s)
    return (mh * 1000 + (ml * 1000 >> 11) + (1 << (s - 12))) >> (s - 11)


# MANUAL_CONTROL: x y z r (int16), buttons (uint16), target, then the extensions
# buttons2, enabled_extensions, s, t, aux1..6 where the dialect has them.
class ManualInput(Input):
    """x (pitch), y (roll), r (yaw): -1000..1000; z (thrust): 0..1000 (or -1000..1000);
    INT16_MAX: the axis is not used. buttons; buttons2, enabled_extensions, s, t,
    aux(1..6) where the dialect has them (0 otherwise)."""

    def x(self):
        return self.i16(0)

    def y(self):
        return self.i16(2)

    def z(self):
        return self.i16(4)

    def r(self):
        return self.i16(6)

    def buttons(self):
        return self.u16(8)

    def buttons2(self):
        return self.u16(11)

    def extensions(self):
        return self.u8(13)

    def s(self):
        return self.i16(14)

    def t(self):
        return self.i16(16)

    def aux(self, n):
        return self.i16(16 + 2 * n)


_RC_IGNORE = const(0xFFFF)
_RC_RELEASE_HIGH = const(0xFFFE)  # channels 9-18: UINT16_MAX - 1 releases
_RC_CHANNELS = const(18)


class RcOverride(Input):
    """RC_CHANNELS_OVERRIDE kept per channel, as the MAVLink definition says: for
    channels 1-8, UINT16_MAX leaves the channel as it is and 0 releases it back to the
    radio; for 9-18, 0 and UINT16_MAX leave it, UINT16_MAX - 1 releases it. An override
    holds until released or for the board's RC_OVERRIDE_TIMEOUT_MS after the last frame
    that set it.
        rc.channel(n) -> PWM us of channel n (1-18) while overridden, else 0
        rc.overridden(n) -> bool"""

    def __init__(self, svc, kind, msgid, ts, tc):
        Input.__init__(self, svc, kind, msgid, ts, tc)
        self.values = [0] * _RC_CHANNELS  # 0: not overridden
        self.set_at = [0] * _RC_CHANNELS
        self.channels = 8 if self.size <= 18 else _RC_CHANNELS

    def arrived(self):
        i = 0
        while i < self.channels:
            self._take(i)
            i += 1

    def _take(self, i):
        o = 2 * i if i < 8 else 2 * i + 2  # target_system, target_component after chan8
        v = self.buf[o] | self.buf[o + 1] << 8
        if i < 8:
            if v == _RC_IGNORE:
                return
            release = v == 0
        else:
            if v == 0 or v == _RC_IGNORE:
                return
            release = v == _RC_RELEASE_HIGH
        self.values[i] = 0 if release else v
        self.set_at[i] = self.stamp

    def channel(self, n):
        i = n - 1
        if i < 0 or i >= _RC_CHANNELS or not self.values[i]:
            return 0
        if ticks_diff(self.ep.now, self.set_at[i]) > self.svc.rc_timeout_ms:
            self.values[i] = 0
            return 0
        return self.values[i]

    def overridden(self, n):
        return self.channel(n) != 0


# POSITION_TARGET_TYPEMASK bits
IGNORE_X = const(1)
IGNORE_Y = const(2)
IGNORE_Z = const(4)
IGNORE_VX = const(8)
IGNORE_VY = const(16)
IGNORE_VZ = const(32)
IGNORE_AX = const(64)
IGNORE_AY = const(128)
IGNORE_AZ = const(256)
FORCE_SET = const(512)
IGNORE_YAW = const(1024)
IGNORE_YAW_RATE = const(2048)
IGNORE_POSITION = const(7)
IGNORE_VELOCITY = const(56)
IGNORE_ACCEL = const(448)


class PositionTarget(Input):
    """SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT (the same layout): time_boot_ms, then
    the position (local: x y z m; global: lat_int lon_int degE7, alt m), velocity
    (m/s), acceleration (m/s2), yaw (rad), yaw_rate (rad/s), type_mask, frame.
    *_milli: the float times 1000 (mm, mm/s, mrad); lat_e7/lon_e7 (global): ints (past
    +-107 deg, 2^30 or more: docs/design.md); lon_hi()/lon_lo() and lat_hi()/lat_lo():
    the same in 16-bit halves (value = hi * 65536 + lo, hi signed), for a hot path that
    takes any longitude (fields.i32_cmp compares them with a bound).
    uses_position() / uses_velocity() / uses_accel() / uses_yaw() / uses_yaw_rate():
    the type_mask leaves them in (not all three axes ignored).
    Inside a safety area only (the geography service): a setpoint whose position lies
    outside it is dropped, and told once in a STATUSTEXT."""

    geo = None  # the geography service, when the board has one (Inputs.started)

    def deliver(self, link, p):
        geo = self.geo
        if geo is not None and not geo.check_target(p, self.msgid == 86):
            return
        Input.deliver(self, link, p)

    def type_mask(self):
        return self.u16(48)

    def frame(self):
        return self.u8(52)

    def uses_position(self):
        return self.u16(48) & IGNORE_POSITION != IGNORE_POSITION

    def uses_velocity(self):
        return self.u16(48) & IGNORE_VELOCITY != IGNORE_VELOCITY

    def uses_accel(self):
        return self.u16(48) & IGNORE_ACCEL != IGNORE_ACCEL

    def uses_yaw(self):
        return not self.u16(48) & IGNORE_YAW

    def uses_yaw_rate(self):
        return not self.u16(48) & IGNORE_YAW_RATE

    def x_milli(self):
        return milli(self.buf, 4)

    def y_milli(self):
        return milli(self.buf, 8)

    def z_milli(self):
        return milli(self.buf, 12)

    def lat_e7(self):
        return self.i32(4)

    def lat_hi(self):
        return self.i16(6)

    def lat_lo(self):
        return self.u16(4)

    def lon_hi(self):
        return self.i16(10)

    def lon_lo(self):
        return self.u16(8)

    def lon_e7(self):
        return self.i32(8)

    def alt_milli(self):
        return milli(self.buf, 12)

    def vx_milli(self):
        return milli(self.buf, 16)

    def vy_milli(self):
        return milli(self.buf, 20)

    def vz_milli(self):
        return milli(self.buf, 24)

    def yaw_milli(self):
        return milli(self.buf, 40)

    def yaw_rate_milli(self):
        return milli(self.buf, 44)


# ATTITUDE_TARGET_TYPEMASK bits
IGNORE_ROLL_RATE = const(1)
IGNORE_PITCH_RATE = const(2)
IGNORE_BODY_YAW_RATE = const(4)
IGNORE_THRUST = const(64)
IGNORE_ATTITUDE = const(128)


class AttitudeTarget(Input):
    """SET_ATTITUDE_TARGET: time_boot_ms, q (w x y z), body roll/pitch/yaw rates
    (rad/s), thrust (0..1), target, type_mask. q_milli(i) (i 0..3), rate_milli(i)
    (i 0..2), thrust_milli(); uses_attitude(), uses_thrust(), uses_rate(i)."""

    def type_mask(self):
        return self.u8(38)

    def q_milli(self, i):
        return milli(self.buf, 4 + 4 * i)

    def rate_milli(self, i):
        return milli(self.buf, 20 + 4 * i)

    def thrust_milli(self):
        return milli(self.buf, 32)

    def uses_attitude(self):
        return not self.u8(38) & IGNORE_ATTITUDE

    def uses_thrust(self):
        return not self.u8(38) & IGNORE_THRUST

    def uses_rate(self, i):
        return not self.u8(38) & (1 << i)
