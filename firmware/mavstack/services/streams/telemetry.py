"""Telemetry: the typed writers the application calls (ep.telemetry.attitude(...), ...).

Each writer takes its message's fields in the MAVLink definition's order and wire units,
packs them into the message's slot (slots.py) and stamps time_boot_ms / time_usec from the
endpoint's clock; the stream scheduler and REQUEST_MESSAGE send the slot. battery() also
hands SYS_STATUS's figures to the status service. Reference: docs/services/streams.md.
"""
import struct
from struct import pack_into

from ...compat import const
from .slots import (NamedSlot, Sink, Slot, fill_u16, put_bytes20, put_cells, put_ext_cells,
                    put_rc8, put_u16s)

_GPS_RAW_INT = const(24)
_GPS_STATUS = const(25)
_SCALED_IMU = const(26)
_RAW_IMU = const(27)
_RAW_PRESSURE = const(28)
_SCALED_PRESSURE = const(29)
_ATTITUDE = const(30)
_ATTITUDE_QUATERNION = const(31)
_LOCAL_POSITION_NED = const(32)
_GLOBAL_POSITION_INT = const(33)
_RC_CHANNELS_SCALED = const(34)
_RC_CHANNELS_RAW = const(35)
_SERVO_OUTPUT_RAW = const(36)
_NAV_CONTROLLER_OUTPUT = const(62)
_RC_CHANNELS = const(65)
_VFR_HUD = const(74)
_OPTICAL_FLOW = const(100)
_HIGHRES_IMU = const(105)
_BATTERY_STATUS = const(147)
_EXTENDED_SYS_STATE = const(245)
_DEBUG_VECT = const(250)
_NAMED_VALUE_FLOAT = const(251)
_NAMED_VALUE_INT = const(252)
_DEBUG = const(254)

# Every message a slot can hold; those the dialect lacks get no slot.
MESSAGES = (
    _GPS_RAW_INT, _GPS_STATUS, _SCALED_IMU, _RAW_IMU, _RAW_PRESSURE, _SCALED_PRESSURE,
    _ATTITUDE, _ATTITUDE_QUATERNION, _LOCAL_POSITION_NED, _GLOBAL_POSITION_INT,
    _RC_CHANNELS_SCALED, _RC_CHANNELS_RAW, _SERVO_OUTPUT_RAW, _NAV_CONTROLLER_OUTPUT,
    _RC_CHANNELS, _VFR_HUD, _OPTICAL_FLOW, _HIGHRES_IMU, _BATTERY_STATUS,
    _EXTENDED_SYS_STATE, _DEBUG_VECT, _NAMED_VALUE_FLOAT, _NAMED_VALUE_INT, _DEBUG,
)
_UNUSED_U16 = const(0xFFFF)
_UNUSED_I16 = const(0x7FFF)
_SEED_BATTERY_SIZE = const(16)


class Telemetry:
    """The slots of one endpoint (ep.telemetry); the application calls the setters."""

    def __init__(self, ep):
        self.ep = ep
        self.slots = {}  # msgid -> Slot; public: other services write into one (servos)
        # TELEMETRY: the messages the board writes (default: all); the others' writers
        # write into one Sink and nothing is sent.
        listed = ep.setting("TELEMETRY") or MESSAGES
        room = 0
        for msgid in MESSAGES:
            if ep.has(msgid) and msgid in listed:
                if msgid == _NAMED_VALUE_FLOAT or msgid == _NAMED_VALUE_INT:
                    slot = NamedSlot(ep, msgid)
                else:
                    slot = Slot(ep, msgid)
                self.slots[msgid] = slot
                ep.producers[msgid] = slot.send
            elif ep.has(msgid):
                room = max(room, ep.dialect.CRC_LEN[msgid] >> 16)
        self._sink = Sink(room) if room else None
        g = self._slot
        self._gps_raw = g(_GPS_RAW_INT)
        self._gps_status = g(_GPS_STATUS)
        self._scaled_imu = g(_SCALED_IMU)
        self._raw_imu = g(_RAW_IMU)
        self._raw_pressure = g(_RAW_PRESSURE)
        self._scaled_pressure = g(_SCALED_PRESSURE)
        self._attitude = g(_ATTITUDE)
        self._quaternion = g(_ATTITUDE_QUATERNION)
        self._local = g(_LOCAL_POSITION_NED)
        self._global = g(_GLOBAL_POSITION_INT)
        self._rc_scaled = g(_RC_CHANNELS_SCALED)
        self._rc_raw = g(_RC_CHANNELS_RAW)
        self._rc = g(_RC_CHANNELS)
        self._servo = g(_SERVO_OUTPUT_RAW)
        self._nav = g(_NAV_CONTROLLER_OUTPUT)
        self._hud = g(_VFR_HUD)
        self._flow = g(_OPTICAL_FLOW)
        self._highres = g(_HIGHRES_IMU)
        self._battery = g(_BATTERY_STATUS)
        self._seed_battery = self._battery is not None and self._battery.size == _SEED_BATTERY_SIZE
        self._ext_state = g(_EXTENDED_SYS_STATE)
        self._debug_vect = g(_DEBUG_VECT)
        self._named_float = g(_NAMED_VALUE_FLOAT)
        self._named_int = g(_NAMED_VALUE_INT)
        self._debug = g(_DEBUG)
        # time_boot_ms / time_usec: stamped as bytes from the endpoint's clock (uptime.py)
        self.clock = ep.clock
        # The battery as SYS_STATUS reports it (-1: unknown).
        self.voltage_mv = 0xFFFF
        self.current_ca = -1
        self.remaining = -1
        # Setters of six to eight parameters stage their values here and a packer of no
        # arguments packs them (small frames: docs/design.md; a setter of nine or more
        # takes its frame from the heap). Made here, so that storing them later adds no
        # attribute (the heap may be locked).
        self._v1 = self._v2 = self._v3 = self._v4 = self._v5 = self._v6 = self._v7 = self._v8 = 0

    # As ints, for applications and tests (not for a hot path: see docs/design.md).
    @property
    def uptime_ms(self):
        return self.clock.uptime_ms()

    @property
    def time_boot_ms(self):
        return self.clock.uptime_ms() & 0xFFFFFFFF

    def _slot(self, msgid):
        """msgid's slot; the sink where the board leaves it out, None if the dialect lacks it."""
        s = self.slots.get(msgid)
        return self._sink if s is None and self.ep.has(msgid) else s

    def written(self, msgid):
        slot = self.slots.get(msgid)
        return slot is not None and slot.written

    # --- setters, in the message's field order and units -------------------------

    def attitude(self, roll, pitch, yaw, rollspeed, pitchspeed, yawspeed):
        """ATTITUDE: rad, rad/s."""
        self._v1, self._v2, self._v3 = roll, pitch, yaw  # (three at a time: no tuple is made)
        self._v4, self._v5, self._v6 = rollspeed, pitchspeed, yawspeed
        self._six_floats(self._attitude)

    def attitude_quaternion(self, q1, q2, q3, q4, rollspeed, pitchspeed, yawspeed):
        """ATTITUDE_QUATERNION: w, x, y, z; rad/s."""
        self._v1, self._v2, self._v3 = q1, q2, q3
        self._v4, self._v5, self._v6 = q4, rollspeed, pitchspeed
        self._v7 = yawspeed
        self._put_quaternion()

    def global_position(self, lat, lon, alt, relative_alt, vx, vy, vz, hdg):
        """GLOBAL_POSITION_INT: degE7, degE7, mm (MSL), mm (above home), cm/s NED, cdeg (65535 unknown)."""
        self._v1, self._v2, self._v3 = lat, lon, alt
        self._v4, self._v5, self._v6 = relative_alt, vx, vy
        self._v7, self._v8 = vz, hdg
        self._put_global()

    def local_position(self, x, y, z, vx, vy, vz):
        """LOCAL_POSITION_NED: m, m/s."""
        self._v1, self._v2, self._v3 = x, y, z
        self._v4, self._v5, self._v6 = vx, vy, vz
        self._six_floats(self._local)

    # Packers of the staged values (self._v1..), a few fields a call.
    def _six_floats(self, s):
        # ATTITUDE, LOCAL_POSITION_NED: time_boot_ms and six floats.
        b = s.buf
        pack_into("<fff", b, 4, self._v1, self._v2, self._v3)
        pack_into("<fff", b, 16, self._v4, self._v5, self._v6)
        self.clock.stamp_ms(b, 0)
        s.written = True

    def _put_quaternion(self):
        b = self._quaternion.buf
        pack_into("<ffff", b, 4, self._v1, self._v2, self._v3, self._v4)
        pack_into("<fff", b, 20, self._v5, self._v6, self._v7)
        self.clock.stamp_ms(b, 0)
        self._quaternion.written = True

    def _put_global(self):
        b = self._global.buf
        pack_into("<iiii", b, 4, self._v1, self._v2, self._v3, self._v4)
        pack_into("<hhhH", b, 20, self._v5, self._v6, self._v7, self._v8)
        self.clock.stamp_ms(b, 0)
        self._global.written = True

    def gps_raw(self, fix_type, lat, lon, alt, eph, epv, vel, cog, satellites_visible,
                alt_ellipsoid=0, h_acc=0, v_acc=0, vel_acc=0, hdg_acc=0, yaw=0):
        """GPS_RAW_INT: GPS_FIX_TYPE, degE7, degE7, mm, HDOP*100, VDOP*100, cm/s, cdeg, count;
        the accuracies (mm, mm/s, degE5) and yaw (cdeg) where the dialect has them."""
        s = self._gps_raw
        if s.base is None:  # the sink
            return
        struct.pack_into(s.base, s.buf, 0, 0, lat, lon, alt, eph, epv, vel, cog,
                         fix_type, satellites_visible)
        self.clock.stamp_us(s.buf, 0)
        if s.ext is not None:
            struct.pack_into(s.ext, s.buf, s.ext_off, alt_ellipsoid, h_acc, v_acc, vel_acc, hdg_acc, yaw)
        s.written = True

    def gps_status(self, satellites_visible, prn, used, elevation, azimuth, snr):
        """GPS_STATUS: the count and up to 20 satellites' prn, used, elevation (deg),
        azimuth (deg * 256 / 360) and snr (dB), each a sequence of small ints."""
        self._gps_status.buf[0] = satellites_visible
        put_bytes20(self._gps_status.buf, 1, prn)
        put_bytes20(self._gps_status.buf, 21, used)
        put_bytes20(self._gps_status.buf, 41, elevation)
        put_bytes20(self._gps_status.buf, 61, azimuth)
        put_bytes20(self._gps_status.buf, 81, snr)
        self._gps_status.written = True

    def scaled_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag):
        """SCALED_IMU: mG, mrad/s, mgauss."""
        s = self._scaled_imu
        if s.base is None:  # the sink
            return
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def raw_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag):
        """RAW_IMU: the sensors' raw counts."""
        s = self._raw_imu
        if s.base is None:  # the sink
            return
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro,
                         xmag, ymag, zmag)
        self.clock.stamp_us(s.buf, 0)
        s.written = True

    def raw_pressure(self, press_abs, press_diff1, press_diff2, temperature):
        """RAW_PRESSURE: raw counts."""
        pack_into("<hh", self._raw_pressure.buf, 8, press_abs, press_diff1)
        pack_into("<hh", self._raw_pressure.buf, 12, press_diff2, temperature)
        self.clock.stamp_us(self._raw_pressure.buf, 0)
        self._raw_pressure.written = True

    def scaled_pressure(self, press_abs, press_diff, temperature):
        """SCALED_PRESSURE: hPa, hPa, cdegC."""
        pack_into("<ffh", self._scaled_pressure.buf, 4, press_abs, press_diff, temperature)
        self.clock.stamp_ms(self._scaled_pressure.buf, 0)
        self._scaled_pressure.written = True

    def highres_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag,
                    abs_pressure, diff_pressure, pressure_alt, temperature, fields_updated):
        """HIGHRES_IMU: m/s/s, rad/s, gauss, hPa, hPa, m, degC, HIGHRES_IMU_UPDATED_FLAGS."""
        s = self._highres
        if s.base is None:  # the sink
            return
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro,
                         xmag, ymag, zmag, abs_pressure, diff_pressure, pressure_alt, temperature, fields_updated)
        self.clock.stamp_us(s.buf, 0)
        s.written = True

    def rc_channels(self, chans, rssi=255):
        """RC inputs, a sequence of up to 18 pulse widths (us): fills RC_CHANNELS_RAW
        (the first 8), RC_CHANNELS_SCALED (1000..2000 us as -10000..10000) and, where
        the dialect has it, RC_CHANNELS with all of them. rssi 0..254, 255 unknown."""
        self.clock.stamp_ms(self._rc_raw.buf, 0)
        self.clock.stamp_ms(self._rc_scaled.buf, 0)
        put_rc8(self._rc_raw.buf, self._rc_scaled.buf, chans)
        self._rc_raw.buf[21] = rssi
        self._rc_scaled.buf[21] = rssi
        self._rc_raw.written = self._rc_scaled.written = True
        if self._rc is not None:
            self.clock.stamp_ms(self._rc.buf, 0)
            off = put_u16s(self._rc.buf, 4, 40, chans, 0)
            fill_u16(self._rc.buf, off, 40, _UNUSED_U16)
            self._rc.buf[40] = (off - 4) >> 1  # chancount
            self._rc.buf[41] = rssi
            self._rc.written = True

    def servo_output(self, outputs, port=0):
        """SERVO_OUTPUT_RAW: a sequence of up to 8 (16 where the dialect has the
        extension) output pulse widths (us); missing ones are sent as 0."""
        b = self._servo.buf
        self.clock.stamp_us32(b, 0)
        off = put_u16s(b, 4, 20, outputs, 0)
        fill_u16(b, off, 20, 0)
        b[20] = port
        if self._servo.ext is not None:
            off = put_u16s(b, 21, 37, outputs, 8)
            fill_u16(b, off, 37, 0)
        self._servo.written = True

    def nav_controller(self, nav_roll, nav_pitch, nav_bearing, target_bearing, wp_dist,
                       alt_error, aspd_error, xtrack_error):
        """NAV_CONTROLLER_OUTPUT: deg, deg, deg, deg, m, m, m/s, m."""
        self._v1 = nav_roll
        self._v2 = nav_pitch
        self._v3 = nav_bearing
        self._v4 = target_bearing
        self._v5 = wp_dist
        self._v6 = alt_error
        self._v7 = aspd_error
        self._v8 = xtrack_error
        self._put_nav()

    def _put_nav(self):
        # nav_roll, nav_pitch, alt_error, aspd_error, xtrack_error, nav_bearing, target_bearing, wp_dist
        b = self._nav.buf
        pack_into("<ff", b, 0, self._v1, self._v2)
        pack_into("<fff", b, 8, self._v6, self._v7, self._v8)
        pack_into("<hhH", b, 20, self._v3, self._v4, self._v5)
        self._nav.written = True

    def vfr_hud(self, airspeed, groundspeed, heading, throttle, alt, climb):
        """VFR_HUD: m/s, m/s, deg (0..360), % (0..100), m (MSL), m/s."""
        self._v1, self._v2, self._v3 = airspeed, groundspeed, heading
        self._v4, self._v5, self._v6 = throttle, alt, climb
        self._put_hud()

    def _put_hud(self):
        # airspeed, groundspeed, alt, climb, heading, throttle
        b = self._hud.buf
        pack_into("<ffff", b, 0, self._v1, self._v2, self._v5, self._v6)
        pack_into("<hH", b, 16, self._v3, self._v4)
        self._hud.written = True

    def optical_flow(self, sensor_id, flow_x, flow_y, flow_comp_m_x, flow_comp_m_y, quality,
                     ground_distance, flow_rate_x=0.0, flow_rate_y=0.0):
        """OPTICAL_FLOW: dpix, dpix, m/s, m/s, 0..255, m; rad/s where the dialect has them."""
        s = self._flow
        if s.base is None:  # the sink
            return
        struct.pack_into(s.base, s.buf, 0, 0, flow_comp_m_x, flow_comp_m_y,
                         ground_distance, flow_x, flow_y, sensor_id, quality)
        self.clock.stamp_us(s.buf, 0)
        if s.ext is not None:
            struct.pack_into(s.ext, s.buf, s.ext_off, flow_rate_x, flow_rate_y)
        s.written = True

    def battery(self, voltage_mv, current_ca=-1, remaining=-1, consumed_mah=-1, cells=None,
                battery_id=0, temperature=_UNUSED_I16, energy_hj=-1, time_remaining=0, charge_state=0):
        """The battery: mV, cA (-1 unknown), % (-1 unknown), mAh (-1 unknown), cell mV
        (a sequence; None: only the total is known), cdegC, hJ, s, MAV_BATTERY_CHARGE_STATE.

        Fills BATTERY_STATUS in the dialect's layout: the seed's has six cells and
        no consumption or temperature; today's has ten cells (+4 in extensions).
        The voltage, current and remaining also go to SYS_STATUS (status service).
        """
        self.voltage_mv = voltage_mv if voltage_mv < 0xFFFF else 0xFFFE
        self.current_ca = current_ca
        self.remaining = remaining
        status = self.ep.services.get("status")
        if status is not None:
            status.set_battery(self.voltage_mv, current_ca, remaining)
        s = self._battery
        if s is None:
            return
        b = s.buf
        if self._seed_battery:
            # voltage_cell_1..6, current_battery, accu_id, battery_remaining
            put_cells(b, 0, 12, voltage_mv, cells)
            struct.pack_into("<hBb", b, 12, current_ca, battery_id, remaining)
        else:
            struct.pack_into("<iih", b, 0, consumed_mah, energy_hj, temperature)
            put_cells(b, 10, 30, voltage_mv, cells)
            # current_battery, id, battery_function and type (unknown), battery_remaining
            struct.pack_into("<hBBBb", b, 30, current_ca, battery_id, 0, 0, remaining)
            if s.ext is not None:
                struct.pack_into("<iB", b, 36, time_remaining, charge_state)
                put_ext_cells(b, cells)
        s.written = True

    def extended_sys_state(self, vtol_state, landed_state):
        """EXTENDED_SYS_STATE: MAV_VTOL_STATE, MAV_LANDED_STATE (today's dialect only)."""
        s = self._ext_state
        if s is None:
            return
        s.buf[0] = vtol_state
        s.buf[1] = landed_state
        s.written = True

    def named_value_float(self, name, value):
        """NAMED_VALUE_FLOAT: name as bytes, up to 10 (each name is sent in turn)."""
        buf = self._named_float.find(name)
        pack_into("<f10s", buf, 4, value, name)
        self.clock.stamp_ms(buf, 0)
        self._named_float.written = True

    def named_value_int(self, name, value):
        """NAMED_VALUE_INT: name as bytes, up to 10; int32 value."""
        buf = self._named_int.find(name)
        pack_into("<i10s", buf, 4, value, name)
        self.clock.stamp_ms(buf, 0)
        self._named_int.written = True

    def debug(self, ind, value):
        """DEBUG: index, float value."""
        pack_into("<fB", self._debug.buf, 4, value, ind)
        self.clock.stamp_ms(self._debug.buf, 0)
        self._debug.written = True

    def debug_vect(self, name, x, y, z):
        """DEBUG_VECT: name as bytes, up to 10; three floats."""
        pack_into("<ff", self._debug_vect.buf, 8, x, y)
        pack_into("<f10s", self._debug_vect.buf, 16, z, name)
        self.clock.stamp_us(self._debug_vect.buf, 0)
        self._debug_vect.written = True
