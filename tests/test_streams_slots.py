"""Telemetry slots: every setter's payload decoded by pymavlink, in today's common
dialect (MAVLink 2, extensions included) and in the seed's (MAVLink 1, the seed's
own BATTERY_STATUS). In-process on CPython over the in-memory link."""
import os
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench, Board  # noqa: E402
import wire_oracle  # noqa: E402

from mavstack.dialects import common, seed2012  # noqa: E402
from mavstack.services.streams.slots import split_fmt  # noqa: E402
from mavstack.services.streams.telemetry import MESSAGES  # noqa: E402

approx = pytest.approx
U16 = 0xFFFF


class Recorder:
    """A transport that keeps what the vehicle sends, frame by frame."""

    name = "recorder"
    bytes_per_s = 200000

    def __init__(self):
        self.data = bytearray()

    def readinto(self, buf):
        return 0

    def write(self, buf, n):
        self.data += bytes(buf[:n])
        return n

    def close(self):
        pass


def vehicle(dialect, version):
    b = Bench(services=("commands", "streams"), dialect=dialect, version=version)
    rec = Recorder()
    link = b.ep.add_link(rec, version)
    b.run(1234)  # some uptime for the time fields
    return b, b.ep.telemetry, link, rec


def sent(b, link, rec, dialect_name, version, msgid):
    """The messages one send of the slot's producer put on the wire, decoded by pymavlink."""
    rec.data = bytearray()
    assert b.ep.producers[msgid](link)
    return wire_oracle.decode_frames(dialect_name, version, rec.data)


def one(b, link, rec, dialect_name, version, msgid):
    msgs = sent(b, link, rec, dialect_name, version, msgid)
    assert len(msgs) == 1 and msgs[0].get_msgId() == msgid, msgs
    return msgs[0]


def check(msg, **want):
    for name, value in want.items():
        got = getattr(msg, name)
        if isinstance(value, float):
            assert got == approx(value, rel=1e-6, abs=1e-7), (msg.get_type(), name, got, value)
        else:
            assert got == value, (msg.get_type(), name, got, value)


def test_split_fmt_separates_extensions():
    assert split_fmt(common.FMT[24], 30) == ("<QiiiHHHHBB", "<iIIIIH")
    assert split_fmt(seed2012.FMT[24], 30) == ("<QiiiHHHHBB", None)
    assert split_fmt(common.FMT[36], 21) == ("<IHHHHHHHHB", "<HHHHHHHH")
    assert split_fmt(common.FMT[30], 28) == ("<Iffffff", None)


def test_every_listed_message_has_a_slot_and_a_producer():
    b, tm, link, rec = vehicle(common, 2)
    for msgid in MESSAGES:
        assert msgid in tm.slots and b.ep.producers[msgid] == tm.slots[msgid].send
    seed, stm, _, _ = vehicle(seed2012, 1)
    assert 65 not in stm.slots and 245 not in stm.slots  # not in the seed
    assert stm.slots[147].size == 16


def test_common_setters_decode_in_pymavlink():
    b, tm, link, rec = vehicle(common, 2)
    ms = tm.time_boot_ms
    us = tm.uptime_ms * 1000
    assert ms >= 1234

    def get(msgid):
        return one(b, link, rec, "common", 2, msgid)

    tm.attitude(0.1, -0.2, 0.3, 0.01, -0.02, 0.03)
    check(get(30), time_boot_ms=ms, roll=0.1, pitch=-0.2, yaw=0.3, rollspeed=0.01, pitchspeed=-0.02, yawspeed=0.03)
    tm.attitude_quaternion(0.9, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    m = get(31)
    check(m, time_boot_ms=ms, q1=0.9, q2=0.1, q3=0.2, q4=0.3, rollspeed=0.4, pitchspeed=0.5, yawspeed=0.6)
    assert list(m.repr_offset_q) == [0, 0, 0, 0]
    tm.global_position(473977420, 85455940, 488123, 1234, 150, -250, -30, 27000)
    check(get(33), time_boot_ms=ms, lat=473977420, lon=85455940, alt=488123, relative_alt=1234,
          vx=150, vy=-250, vz=-30, hdg=27000)
    tm.local_position(1.5, -2.5, -3.0, 0.5, 0.25, -0.125)
    check(get(32), time_boot_ms=ms, x=1.5, y=-2.5, z=-3.0, vx=0.5, vy=0.25, vz=-0.125)
    tm.gps_raw(3, 473977420, 85455940, 488123, 80, 120, 150, 9000, 12, 535000, 1200, 1800, 150, 2000, 4500)
    check(get(24), time_usec=us, fix_type=3, lat=473977420, lon=85455940, alt=488123, eph=80, epv=120, vel=150,
          cog=9000, satellites_visible=12, alt_ellipsoid=535000, h_acc=1200, v_acc=1800, vel_acc=150,
          hdg_acc=2000, yaw=4500)
    tm.gps_status(3, [1, 2, 3], [1, 0, 1], [10, 20, 30], [40, 50, 60], [30, 31, 32])
    m = get(25)
    assert m.satellites_visible == 3
    assert list(m.satellite_prn) == [1, 2, 3] + [0] * 17
    assert list(m.satellite_used[:3]) == [1, 0, 1]
    assert list(m.satellite_elevation[:3]) == [10, 20, 30]
    assert list(m.satellite_azimuth[:3]) == [40, 50, 60]
    assert list(m.satellite_snr[:4]) == [30, 31, 32, 0]
    tm.scaled_imu(1, 2, -1000, 4, 5, 6, 210, -7, 430)
    check(get(26), time_boot_ms=ms, xacc=1, yacc=2, zacc=-1000, xgyro=4, ygyro=5, zgyro=6, xmag=210, ymag=-7, zmag=430)
    tm.raw_imu(11, 12, 13, 14, 15, 16, 17, 18, 19)
    check(get(27), time_usec=us, xacc=11, yacc=12, zacc=13, xgyro=14, ygyro=15, zgyro=16, xmag=17, ymag=18, zmag=19)
    tm.raw_pressure(10132, 2, 3, 2500)
    check(get(28), time_usec=us, press_abs=10132, press_diff1=2, press_diff2=3, temperature=2500)
    tm.scaled_pressure(1013.25, 0.5, 2500)
    check(get(29), time_boot_ms=ms, press_abs=1013.25, press_diff=0.5, temperature=2500)
    tm.highres_imu(0.1, 0.2, -9.8, 0.01, 0.02, 0.03, 0.21, 0.0, 0.43, 1013.25, 0.5, 488.5, 15.5, 0x1FFF)
    check(get(105), time_usec=us, xacc=0.1, yacc=0.2, zacc=-9.8, xgyro=0.01, ygyro=0.02, zgyro=0.03, xmag=0.21,
          ymag=0.0, zmag=0.43, abs_pressure=1013.25, diff_pressure=0.5, pressure_alt=488.5, temperature=15.5,
          fields_updated=0x1FFF)
    chans = [1000, 1100, 1200, 1300, 1500, 1600, 1700, 2000, 1800, 1900]
    tm.rc_channels(chans, 200)
    check(get(35), time_boot_ms=ms, port=0, rssi=200, chan1_raw=1000, chan2_raw=1100, chan5_raw=1500, chan8_raw=2000)
    check(get(34), time_boot_ms=ms, rssi=200, chan1_scaled=-10000, chan2_scaled=-8000, chan5_scaled=0,
          chan8_scaled=10000)
    check(get(65), time_boot_ms=ms, chancount=10, rssi=200, chan1_raw=1000, chan9_raw=1800, chan10_raw=1900,
          chan11_raw=U16, chan18_raw=U16)
    tm.rc_channels([1500, 1500], 255)
    check(get(35), chan1_raw=1500, chan3_raw=U16, chan8_raw=U16)
    check(get(34), chan2_scaled=0, chan3_scaled=0x7FFF)
    tm.servo_output([1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000], 1)
    check(get(36), time_usec=us & 0xFFFFFFFF, port=1, servo1_raw=1100, servo8_raw=1800, servo9_raw=1900,
          servo10_raw=2000, servo11_raw=0, servo16_raw=0)
    tm.nav_controller(1.5, -2.5, 90, 180, 1234, 3.5, 0.5, -0.25)
    check(get(62), nav_roll=1.5, nav_pitch=-2.5, nav_bearing=90, target_bearing=180, wp_dist=1234,
          alt_error=3.5, aspd_error=0.5, xtrack_error=-0.25)
    tm.vfr_hud(12.5, 11.0, 270, 55, 500.25, -1.5)
    check(get(74), airspeed=12.5, groundspeed=11.0, heading=270, throttle=55, alt=500.25, climb=-1.5)
    tm.optical_flow(7, 10, -20, 0.5, -0.25, 200, 3.5, 0.1, 0.2)
    check(get(100), time_usec=us, sensor_id=7, flow_x=10, flow_y=-20, flow_comp_m_x=0.5, flow_comp_m_y=-0.25,
          quality=200, ground_distance=3.5, flow_rate_x=0.1, flow_rate_y=0.2)
    tm.battery(12300, 450, 87, 1200, [4100, 4104, 4096], 2, 2500, 345, 600, 1)
    check(get(147), id=2, battery_function=0, type=0, temperature=2500, current_battery=450, current_consumed=1200,
          energy_consumed=345, battery_remaining=87, time_remaining=600, charge_state=1)
    m = get(147)
    assert list(m.voltages) == [4100, 4104, 4096] + [U16] * 7
    assert list(m.voltages_ext) == [0, 0, 0, 0]
    tm.battery(12300)  # only the total known
    m = get(147)
    assert list(m.voltages) == [12300] + [U16] * 9
    check(m, current_battery=-1, battery_remaining=-1, current_consumed=-1, energy_consumed=-1, temperature=0x7FFF)
    assert (tm.voltage_mv, tm.current_ca, tm.remaining) == (12300, -1, -1)
    tm.extended_sys_state(0, 2)
    check(get(245), vtol_state=0, landed_state=2)
    tm.debug(3, 2.5)
    check(get(254), time_boot_ms=ms, ind=3, value=2.5)
    tm.debug_vect(b"vec", 1.0, 2.0, 3.0)
    check(get(250), time_usec=us, name="vec", x=1.0, y=2.0, z=3.0)
    tm.named_value_int(b"count", -7)
    check(get(252), time_boot_ms=ms, name="count", value=-7)


def test_named_values_are_sent_in_turn():
    b, tm, link, rec = vehicle(common, 2)
    tm.named_value_float(b"alpha", 1.5)
    tm.named_value_float(b"beta", 2.5)
    tm.named_value_float(b"alpha", 3.5)  # an update, not a third name
    seen = [one(b, link, rec, "common", 2, 251) for _ in range(4)]
    assert [(m.name, m.value) for m in seen] == [("alpha", 3.5), ("beta", 2.5)] * 2


def test_time_fields_follow_the_clock():
    b, tm, link, rec = vehicle(common, 2)
    tm.attitude(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    first = one(b, link, rec, "common", 2, 30).time_boot_ms
    b.run(250)
    assert one(b, link, rec, "common", 2, 30).time_boot_ms == first  # the sample's time, not the send's
    tm.attitude(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert one(b, link, rec, "common", 2, 30).time_boot_ms == first + 250


def test_unwritten_slot_is_not_sent():
    b, tm, link, rec = vehicle(common, 2)
    rec.data = bytearray()
    assert not b.ep.producers[105](link)
    assert rec.data == bytearray()


def test_seed_setters_decode_in_pymavlink():
    b, tm, link, rec = vehicle(seed2012, 1)
    ms = tm.time_boot_ms
    us = tm.uptime_ms * 1000

    def get(msgid):
        return one(b, link, rec, "seed2012", 1, msgid)

    # The seed's BATTERY_STATUS: six cells, current, accu id, remaining.
    tm.battery(12300, 450, 87, 1200, [4100, 4104, 4096], 2)
    check(get(147), accu_id=2, voltage_cell_1=4100, voltage_cell_2=4104, voltage_cell_3=4096,
          voltage_cell_4=U16, voltage_cell_6=U16, current_battery=450, battery_remaining=87)
    tm.battery(11100, -1, 50)
    check(get(147), voltage_cell_1=11100, voltage_cell_2=U16, current_battery=-1, battery_remaining=50)
    # Extension arguments are accepted and left out where the dialect has no such fields.
    tm.gps_raw(3, 473977420, 85455940, 488123, 80, 120, 150, 9000, 12, 535000, 1200)
    check(get(24), time_usec=us, fix_type=3, lat=473977420, satellites_visible=12, cog=9000)
    tm.servo_output([1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900], 0)
    check(get(36), servo1_raw=1100, servo8_raw=1800)
    tm.rc_channels([1000, 2000], 100)
    check(get(35), chan1_raw=1000, chan2_raw=2000, chan3_raw=U16, rssi=100)
    check(get(34), chan1_scaled=-10000, chan2_scaled=10000)
    tm.attitude(0.1, -0.2, 0.3, 0.01, -0.02, 0.03)
    check(get(30), time_boot_ms=ms, roll=0.1, yawspeed=0.03)
    tm.vfr_hud(12.5, 11.0, 270, 55, 500.25, -1.5)
    check(get(74), heading=270, throttle=55, alt=500.25)
    tm.optical_flow(7, 10, -20, 0.5, -0.25, 200, 3.5)
    check(get(100), sensor_id=7, flow_x=10, quality=200, ground_distance=3.5)
    tm.scaled_pressure(1013.25, 0.5, 2500)
    check(get(29), press_abs=1013.25, temperature=2500)
    tm.highres_imu(0.1, 0.2, -9.8, 0.01, 0.02, 0.03, 0.21, 0.0, 0.43, 1013.25, 0.5, 488.5, 15.5, 0x1FFF)
    check(get(105), time_usec=us, zacc=-9.8, fields_updated=0x1FFF)
    tm.named_value_float(b"alpha", 1.5)
    check(get(251), name="alpha", value=1.5)
    tm.extended_sys_state(0, 2)  # not in the seed: a no-op
    tm.rc_channels([1500] * 12)


class Listed(Board):
    TELEMETRY = (30, 147)  # ATTITUDE, BATTERY_STATUS


def every_writer(tm):
    """Every writer, once."""
    tm.attitude(0.1, -0.2, 0.3, 0.01, -0.02, 0.03)
    tm.attitude_quaternion(0.9, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    tm.global_position(473977420, 85455940, 488123, 1234, 150, -250, -30, 27000)
    tm.local_position(1.5, -2.5, -3.0, 0.5, 0.25, -0.125)
    tm.gps_raw(3, 473977420, 85455940, 488123, 80, 120, 150, 9000, 12)
    tm.gps_status(3, [1, 2, 3], [1, 0, 1], [10, 20, 30], [40, 50, 60], [30, 31, 32])
    tm.scaled_imu(1, 2, -1000, 4, 5, 6, 210, -7, 430)
    tm.raw_imu(11, 12, 13, 14, 15, 16, 17, 18, 19)
    tm.raw_pressure(10132, 2, 3, 2500)
    tm.scaled_pressure(1013.25, 0.5, 2500)
    tm.highres_imu(0.1, 0.2, -9.8, 0.01, 0.02, 0.03, 0.21, 0.0, 0.43, 1013.25, 0.5, 488.5, 15.5, 0x1FFF)
    tm.rc_channels([1000, 1100, 1200, 1300, 1500, 1600, 1700, 2000, 1800, 1900], 200)
    tm.servo_output([1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000], 1)
    tm.nav_controller(1.5, -2.5, 90, 180, 1234, 3.5, 0.5, -0.25)
    tm.vfr_hud(12.5, 11.0, 270, 55, 500.25, -1.5)
    tm.optical_flow(7, 10, -20, 0.5, -0.25, 200, 3.5, 0.1, 0.2)
    tm.battery(12300, 450, 87, 1200, [4100, 4104, 4096], 2, 2500, 345, 600, 1)
    tm.extended_sys_state(0, 2)
    tm.debug(3, 2.5)
    tm.debug_vect(b"vec", 1.0, 2.0, 3.0)
    tm.named_value_int(b"count", -7)
    tm.named_value_float(b"speed", 1.5)


def test_telemetry_setting_makes_only_the_listed_slots():
    """TELEMETRY: slots and producers for the listed messages alone; every other writer
    still runs (into one sink, never sent), and a request for its message is refused."""
    b = Bench(services=("commands", "streams"), board=Listed)
    rec = Recorder()
    link = b.ep.add_link(rec, 2)
    b.run(1234)
    tm = b.ep.telemetry
    assert sorted(tm.slots) == [30, 147]
    assert not any(m in b.ep.producers for m in MESSAGES if m not in (30, 147))
    every_writer(tm)
    check(one(b, link, rec, "common", 2, 30), roll=0.1, pitch=-0.2, yaw=0.3)
    check(one(b, link, rec, "common", 2, 147), id=2, current_battery=450, battery_remaining=87)
    assert not tm.written(24) and tm.written(30)
    assert not b.ep.services["streams"].set_rate(link, 24, 5)  # GPS_RAW_INT: not produced
    assert b.ep.services["streams"].set_rate(link, 30, 5)


def test_telemetry_setting_writers_allocate_nothing_on_micropython():
    from conftest import run_mpy

    r = run_mpy(
        "import micropython\n"
        "from harness import Bench, Board\n"
        "class Listed(Board):\n"
        "    TELEMETRY = (30,)\n"
        "b = Bench(services=('commands', 'streams'), board=Listed)\n"
        "tm = b.ep.telemetry\n"
        "def write():\n"
        "    tm.attitude(0.1, -0.2, 0.3, 0.01, -0.02, 0.03)\n"  # a slot
        "    tm.vfr_hud(12.5, 11.0, 270, 55, 500.25, -1.5)\n"  # the sink
        "    tm.global_position(473977420, 85455940, 488123, 1234, 150, -250, -30, 27000)\n"
        "    tm.extended_sys_state(0, 2)\n"
        "    tm.nav_controller(1.5, -2.5, 90, 180, 1234, 3.5, 0.5, -0.25)\n"
        "    tm.debug(3, 2.5)\n"
        "    tm.named_value_int(b'count', -7)\n"
        "write()\n"
        "micropython.heap_lock()\n"
        "write()\n"
        "micropython.heap_unlock()\n"
        "print('ok', sorted(tm.slots))\n", path=[os.path.join(ROOT, "tests", "mpy")])
    assert r.returncode == 0 and r.stdout.split()[:2] == ["ok", "[30]"], r.stdout + r.stderr
