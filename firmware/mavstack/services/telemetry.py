"""Telemetry slots: the application writes vehicle state, the stream scheduler sends it.

Each telemetry message has one preallocated payload (a slot). A setter packs its
arguments straight into that payload, so an update allocates nothing and the last
value written is what goes out. A slot that was never written is not sent.
Setters take the message's fields in the order the MAVLink definition lists them
and in its wire units (degE7, mm, cdeg, ...): converting is the application's job,
so no float is made here. time_boot_ms / time_usec are filled in from the
endpoint's uptime when the value is written (the moment it was sampled).

Every slot is also the producer of its message (endpoint.producers[msgid]), so
MAV_CMD_REQUEST_MESSAGE and the stream scheduler (services/streams.py) send it.
HEARTBEAT, SYS_STATUS, SYSTEM_TIME, STATUSTEXT and HOME_POSITION belong to the
status service, MISSION_CURRENT to missions; battery() also hands the figures
SYS_STATUS reports to the status service (status.set_battery).

The dialect gives each payload's layout. Fields MAVLink 2 appended (extensions)
are packed only where the dialect has them; BATTERY_STATUS differs altogether
between the seed (six cells, 16 bytes) and today's common set, and battery()
fills whichever the dialect defines.
"""
import struct

from ..compat import const

_SYS_STATUS = const(1)
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
# NAMED_VALUE_* carry several values told apart by name; each name keeps its own payload.
NAMED_VALUES = 4

_UNUSED_U16 = const(0xFFFF)
_UNUSED_I16 = const(0x7FFF)
_SEED_BATTERY_SIZE = const(16)

_SIZES = {"B": 1, "b": 1, "s": 1, "H": 2, "h": 2, "I": 4, "i": 4, "f": 4, "Q": 8, "q": 8, "d": 8}


def split_fmt(fmt, base_len):
    """('<base', '<extensions' or None) of a payload format: the MAVLink 1 fields
    (the first base_len bytes) and those MAVLink 2 appended."""
    size = 0
    count = ""
    for i in range(1, len(fmt)):
        c = fmt[i]
        if "0" <= c <= "9":
            count += c
            continue
        size += _SIZES[c] * (int(count) if count else 1)
        count = ""
        if size == base_len:
            if i + 1 == len(fmt):
                return fmt, None
            return fmt[: i + 1], "<" + fmt[i + 1:]
    raise ValueError("format %r is not %d bytes" % (fmt, base_len))


class Slot:
    """One message's payload, packed by its setter and sent as it stands."""

    def __init__(self, ep, msgid):
        info = ep.dialect.CRC_LEN[msgid]
        self.msgid = msgid
        self.size = info >> 16
        self.buf = bytearray(self.size)
        self.ext_off = (info >> 8) & 0xFF
        self.base, self.ext = split_fmt(ep.fmt(msgid), self.ext_off)
        self.written = False

    def send(self, link):
        """Producer: send the last value written; False while there is none."""
        if not self.written:
            return False
        return link.send_payload(self.msgid, self.buf, self.size)


class NamedSlot(Slot):
    """NAMED_VALUE_FLOAT/INT: up to NAMED_VALUES names, sent in turn."""

    def __init__(self, ep, msgid, count=NAMED_VALUES):
        Slot.__init__(self, ep, msgid)
        self.bufs = [bytearray(self.size) for _ in range(count)]
        self.names = [None] * count
        self.used = 0
        self.next = 0

    def find(self, name):
        names = self.names
        for i in range(self.used):
            if names[i] == name:
                return self.bufs[i]
        if self.used == len(names):
            return self.bufs[self.used - 1]  # full: the last one is shared
        names[self.used] = name
        self.used += 1
        return self.bufs[self.used - 1]

    def send(self, link):
        if not self.used:
            return False
        i = self.next
        self.next = i + 1 if i + 1 < self.used else 0
        return link.send_payload(self.msgid, self.bufs[i], self.size)


class Telemetry:
    """The slots of one endpoint (ep.telemetry); the application calls the setters."""

    def __init__(self, ep):
        self.ep = ep
        self.slots = {}
        for msgid in MESSAGES:
            if ep.has(msgid):
                if msgid == _NAMED_VALUE_FLOAT or msgid == _NAMED_VALUE_INT:
                    slot = NamedSlot(ep, msgid)
                else:
                    slot = Slot(ep, msgid)
                self.slots[msgid] = slot
                ep.producers[msgid] = slot.send
        g = self.slots.get
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

    # As ints, for applications and tests (heap objects past 2^30 on a 32-bit board).
    @property
    def uptime_ms(self):
        return self.clock.uptime_ms()

    @property
    def time_boot_ms(self):
        return self.clock.uptime_ms() & 0xFFFFFFFF

    def written(self, msgid):
        slot = self.slots.get(msgid)
        return slot is not None and slot.written

    # --- setters, in the message's field order and units -------------------------

    def attitude(self, roll, pitch, yaw, rollspeed, pitchspeed, yawspeed):
        """ATTITUDE: rad, rad/s."""
        s = self._attitude
        struct.pack_into(s.base, s.buf, 0, 0, roll, pitch, yaw, rollspeed, pitchspeed, yawspeed)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def attitude_quaternion(self, q1, q2, q3, q4, rollspeed, pitchspeed, yawspeed):
        """ATTITUDE_QUATERNION: w, x, y, z; rad/s."""
        s = self._quaternion
        struct.pack_into(s.base, s.buf, 0, 0, q1, q2, q3, q4, rollspeed, pitchspeed, yawspeed)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def global_position(self, lat, lon, alt, relative_alt, vx, vy, vz, hdg):
        """GLOBAL_POSITION_INT: degE7, degE7, mm (MSL), mm (above home), cm/s NED, cdeg (65535 unknown)."""
        s = self._global
        struct.pack_into(s.base, s.buf, 0, 0, lat, lon, alt, relative_alt, vx, vy, vz, hdg)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def local_position(self, x, y, z, vx, vy, vz):
        """LOCAL_POSITION_NED: m, m/s."""
        s = self._local
        struct.pack_into(s.base, s.buf, 0, 0, x, y, z, vx, vy, vz)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def gps_raw(self, fix_type, lat, lon, alt, eph, epv, vel, cog, satellites_visible,
                alt_ellipsoid=0, h_acc=0, v_acc=0, vel_acc=0, hdg_acc=0, yaw=0):
        """GPS_RAW_INT: GPS_FIX_TYPE, degE7, degE7, mm, HDOP*100, VDOP*100, cm/s, cdeg, count;
        the accuracies (mm, mm/s, degE5) and yaw (cdeg) where the dialect has them."""
        s = self._gps_raw
        struct.pack_into(s.base, s.buf, 0, 0, lat, lon, alt, eph, epv, vel, cog,
                         fix_type, satellites_visible)
        self.clock.stamp_us(s.buf, 0)
        if s.ext is not None:
            struct.pack_into(s.ext, s.buf, s.ext_off, alt_ellipsoid, h_acc, v_acc, vel_acc, hdg_acc, yaw)
        s.written = True

    def gps_status(self, satellites_visible, prn, used, elevation, azimuth, snr):
        """GPS_STATUS: the count and up to 20 satellites' prn, used, elevation (deg),
        azimuth (deg * 256 / 360) and snr (dB), each a sequence of small ints."""
        s = self._gps_status
        b = s.buf
        b[0] = satellites_visible
        self._bytes(b, 1, prn)
        self._bytes(b, 21, used)
        self._bytes(b, 41, elevation)
        self._bytes(b, 61, azimuth)
        self._bytes(b, 81, snr)
        s.written = True

    def _bytes(self, b, off, values):
        n = len(values)
        for i in range(20):
            b[off + i] = values[i] & 0xFF if i < n else 0

    def scaled_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag):
        """SCALED_IMU: mG, mrad/s, mgauss."""
        s = self._scaled_imu
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def raw_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag):
        """RAW_IMU: the sensors' raw counts."""
        s = self._raw_imu
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro,
                         xmag, ymag, zmag)
        self.clock.stamp_us(s.buf, 0)
        s.written = True

    def raw_pressure(self, press_abs, press_diff1, press_diff2, temperature):
        """RAW_PRESSURE: raw counts."""
        s = self._raw_pressure
        struct.pack_into(s.base, s.buf, 0, 0, press_abs, press_diff1, press_diff2, temperature)
        self.clock.stamp_us(s.buf, 0)
        s.written = True

    def scaled_pressure(self, press_abs, press_diff, temperature):
        """SCALED_PRESSURE: hPa, hPa, cdegC."""
        s = self._scaled_pressure
        struct.pack_into(s.base, s.buf, 0, 0, press_abs, press_diff, temperature)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def highres_imu(self, xacc, yacc, zacc, xgyro, ygyro, zgyro, xmag, ymag, zmag,
                    abs_pressure, diff_pressure, pressure_alt, temperature, fields_updated):
        """HIGHRES_IMU: m/s/s, rad/s, gauss, hPa, hPa, m, degC, HIGHRES_IMU_UPDATED_FLAGS."""
        s = self._highres
        struct.pack_into(s.base, s.buf, 0, 0, xacc, yacc, zacc, xgyro, ygyro, zgyro,
                         xmag, ymag, zmag, abs_pressure, diff_pressure, pressure_alt, temperature, fields_updated)
        self.clock.stamp_us(s.buf, 0)
        s.written = True

    def rc_channels(self, chans, rssi=255):
        """RC inputs, a sequence of up to 18 pulse widths (us): fills RC_CHANNELS_RAW
        (the first 8), RC_CHANNELS_SCALED (1000..2000 us as -10000..10000) and, where
        the dialect has it, RC_CHANNELS with all of them. rssi 0..254, 255 unknown."""
        n = len(chans)
        raw = self._rc_raw
        scaled = self._rc_scaled
        self.clock.stamp_ms(raw.buf, 0)
        self.clock.stamp_ms(scaled.buf, 0)
        for i in range(8):
            if i < n:
                v = chans[i]
                sv = (v - 1500) * 20
                sv = -10000 if sv < -10000 else (10000 if sv > 10000 else sv)
            else:
                v = _UNUSED_U16
                sv = _UNUSED_I16
            struct.pack_into("<H", raw.buf, 4 + 2 * i, v)
            struct.pack_into("<h", scaled.buf, 4 + 2 * i, sv)
        raw.buf[21] = rssi
        scaled.buf[21] = rssi
        raw.written = scaled.written = True
        rc = self._rc
        if rc is not None:
            self.clock.stamp_ms(rc.buf, 0)
            for i in range(18):
                struct.pack_into("<H", rc.buf, 4 + 2 * i, chans[i] if i < n else _UNUSED_U16)
            rc.buf[40] = n if n < 18 else 18
            rc.buf[41] = rssi
            rc.written = True

    def servo_output(self, outputs, port=0):
        """SERVO_OUTPUT_RAW: a sequence of up to 8 (16 where the dialect has the
        extension) output pulse widths (us); missing ones are sent as 0."""
        s = self._servo
        b = s.buf
        n = len(outputs)
        self.clock.stamp_us32(b, 0)
        for i in range(8):
            struct.pack_into("<H", b, 4 + 2 * i, outputs[i] if i < n else 0)
        b[20] = port
        if s.ext is not None:
            for i in range(8):
                struct.pack_into("<H", b, 21 + 2 * i, outputs[8 + i] if 8 + i < n else 0)
        s.written = True

    def nav_controller(self, nav_roll, nav_pitch, nav_bearing, target_bearing, wp_dist,
                       alt_error, aspd_error, xtrack_error):
        """NAV_CONTROLLER_OUTPUT: deg, deg, deg, deg, m, m, m/s, m."""
        s = self._nav
        struct.pack_into(s.base, s.buf, 0, nav_roll, nav_pitch, alt_error, aspd_error, xtrack_error,
                         nav_bearing, target_bearing, wp_dist)
        s.written = True

    def vfr_hud(self, airspeed, groundspeed, heading, throttle, alt, climb):
        """VFR_HUD: m/s, m/s, deg (0..360), % (0..100), m (MSL), m/s."""
        s = self._hud
        struct.pack_into(s.base, s.buf, 0, airspeed, groundspeed, alt, climb, heading, throttle)
        s.written = True

    def optical_flow(self, sensor_id, flow_x, flow_y, flow_comp_m_x, flow_comp_m_y, quality,
                     ground_distance, flow_rate_x=0.0, flow_rate_y=0.0):
        """OPTICAL_FLOW: dpix, dpix, m/s, m/s, 0..255, m; rad/s where the dialect has them."""
        s = self._flow
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
            self._cells(b, 0, 6, voltage_mv, cells)
            struct.pack_into("<hBb", b, 12, current_ca, battery_id, remaining)
        else:
            struct.pack_into("<iih", b, 0, consumed_mah, energy_hj, temperature)
            self._cells(b, 10, 10, voltage_mv, cells)
            # current_battery, id, battery_function and type (unknown), battery_remaining
            struct.pack_into("<hBBBb", b, 30, current_ca, battery_id, 0, 0, remaining)
            if s.ext is not None:
                struct.pack_into("<iB", b, 36, time_remaining, charge_state)
                n = len(cells) if cells is not None else 0
                for i in range(4):
                    v = cells[10 + i] if 10 + i < n else 0
                    struct.pack_into("<H", b, 41 + 2 * i, v)
        s.written = True

    def _cells(self, b, off, count, total_mv, cells):
        # Unknown cells are UINT16_MAX; without cell voltages the total goes in cell 1.
        n = len(cells) if cells is not None else 0
        for i in range(count):
            if n:
                v = cells[i] if i < n else _UNUSED_U16
            else:
                v = (total_mv if total_mv < _UNUSED_U16 else _UNUSED_U16 - 1) if i == 0 else _UNUSED_U16
            struct.pack_into("<H", b, off + 2 * i, v)

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
        s = self._named_float
        buf = s.find(name)
        struct.pack_into(s.base, buf, 0, 0, value, name)
        self.clock.stamp_ms(buf, 0)
        s.written = True

    def named_value_int(self, name, value):
        """NAMED_VALUE_INT: name as bytes, up to 10; int32 value."""
        s = self._named_int
        buf = s.find(name)
        struct.pack_into(s.base, buf, 0, 0, value, name)
        self.clock.stamp_ms(buf, 0)
        s.written = True

    def debug(self, ind, value):
        """DEBUG: index, float value."""
        s = self._debug
        struct.pack_into(s.base, s.buf, 0, 0, value, ind)
        self.clock.stamp_ms(s.buf, 0)
        s.written = True

    def debug_vect(self, name, x, y, z):
        """DEBUG_VECT: name as bytes, up to 10; three floats."""
        s = self._debug_vect
        struct.pack_into(s.base, s.buf, 0, 0, x, y, z, name)
        self.clock.stamp_us(s.buf, 0)
        s.written = True
