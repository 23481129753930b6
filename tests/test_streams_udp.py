"""Telemetry streams end to end: the unix vehicle over UDP, pymavlink ground stations.

Rates are measured from arrival times at the ground station; the vehicle's own
loop, the simulator and the host's scheduler are all in the measurement.
"""
import time

import pytest

from conftest import free_udp_port, recv
from gcs_tools import run, command, listen, MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, mavsdk_system

SET_INTERVAL, GET_INTERVAL, REQUEST_MESSAGE = 511, 510, 512

# REQUEST_DATA_STREAM groups and the messages the unix vehicle sends for each.
GROUPS = {
    1: ("RAW_IMU", "SCALED_IMU", "RAW_PRESSURE", "SCALED_PRESSURE", "HIGHRES_IMU"),
    2: ("SYS_STATUS", "GPS_RAW_INT", "GPS_STATUS", "MISSION_CURRENT", "NAV_CONTROLLER_OUTPUT",
        "EXTENDED_SYS_STATE"),
    3: ("RC_CHANNELS_RAW", "RC_CHANNELS", "SERVO_OUTPUT_RAW"),
    4: ("RC_CHANNELS_SCALED",),
    6: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    10: ("ATTITUDE", "ATTITUDE_QUATERNION"),
    11: ("VFR_HUD",),
    12: ("SYSTEM_TIME", "BATTERY_STATUS", "OPTICAL_FLOW"),
}


def set_interval(m, msgid, us, target=0):
    return run(m, SET_INTERVAL, msgid, us, 0, 0, 0, 0, target)


def get_interval(m, msgid):
    command(m, GET_INTERVAL, msgid)
    a = recv(m, "COMMAND_ACK", 5, lambda a: a.command == GET_INTERVAL)
    assert a is not None and a.result == MAV_RESULT_ACCEPTED
    mi = recv(m, "MESSAGE_INTERVAL", 5, lambda x: x.message_id == msgid)
    assert mi is not None
    return mi.interval_us


def collect(gcss, seconds, types=None):
    """{gcs index: {type: [arrival times]}} and bytes per gcs, heartbeats sent meanwhile
    (a udpin link forgets a ground station that stays silent)."""
    times = [dict() for _ in gcss]
    nbytes = [0] * len(gcss)
    end = time.time() + seconds
    beat = 0
    while True:
        now = time.time()
        if now >= end:
            return times, nbytes
        if now >= beat:
            beat = now + 0.5
            for m in gcss:
                m.mav.heartbeat_send(6, 8, 0, 0, 0)
        for i, m in enumerate(gcss):
            while True:
                msg = m.recv_match(blocking=False)
                if msg is None:
                    break
                t = msg.get_type()
                if t == "BAD_DATA":
                    continue
                nbytes[i] += len(msg.get_msgbuf())
                if types is None or t in types:
                    times[i].setdefault(t, []).append(time.time())
        time.sleep(0.001)


def rate(ts):
    """Messages per second from arrival times."""
    if len(ts) < 2:
        return 0.0
    return (len(ts) - 1) / (ts[-1] - ts[0])


def drain(m, seconds=0.3):
    end = time.time() + seconds
    while time.time() < end:
        m.recv_match(blocking=True, timeout=0.05)


def test_1_10_and_50_hz_are_met(vehicle):
    v = vehicle()
    m = v.gcs()
    want = {"ATTITUDE": (30, 50), "GLOBAL_POSITION_INT": (33, 10), "SCALED_IMU": (26, 1)}
    for name, (msgid, hz) in want.items():
        assert set_interval(m, msgid, 1e6 / hz) == MAV_RESULT_ACCEPTED
        assert get_interval(m, msgid) == int(1e6 / hz)
    drain(m, 0.5)
    times, _ = collect([m], 10.5, set(want))
    for name, (msgid, hz) in want.items():
        ts = [t for t in times[0].get(name, []) if t - times[0][name][0] <= 10.2]
        assert abs(rate(ts) - hz) <= 0.05 * hz, (name, rate(ts), len(ts))


def test_57600_link_keeps_the_budget_with_fair_shares(vehicle):
    bps = 5760
    v = vehicle(args=["--set", "udp_bytes_per_s=%d" % bps])
    m = v.gcs()
    asked = {"ATTITUDE": (30, 100), "GLOBAL_POSITION_INT": (33, 100), "VFR_HUD": (74, 50), "SCALED_IMU": (26, 50)}
    for name, (msgid, hz) in asked.items():  # about twice what the link carries
        assert set_interval(m, msgid, 1e6 / hz) == MAV_RESULT_ACCEPTED
    drain(m, 2.5)  # the fit follows once a second
    seconds = 6.0
    times, nbytes = collect([m], seconds)
    assert nbytes[0] <= bps * seconds + 600, nbytes[0] / seconds
    assert nbytes[0] >= 0.8 * bps * seconds  # and the link is used
    shares = {}
    for name, (msgid, hz) in asked.items():
        got = rate(times[0].get(name, []))
        assert got > 0, name
        shares[name] = got / hz
        reported = 1e6 / get_interval(m, msgid)  # MESSAGE_INTERVAL: the achieved interval
        assert abs(reported - got) <= 0.15 * got, (name, reported, got)
    assert max(shares.values()) < 0.75
    assert max(shares.values()) - min(shares.values()) < 0.2 * max(shares.values()), shares


def test_request_data_stream_groups_start_and_stop(vehicle):
    v = vehicle()
    m = v.gcs(version=1)  # a ground station of the seed's time
    ts, tc = m.target_system, m.target_component
    everything = set(n for names in GROUPS.values() for n in names)

    def request(stream_id, hz, start):
        m.mav.request_data_stream_send(ts, tc, stream_id, hz, start)
        ds = recv(m, "DATA_STREAM", 5, lambda d: d.stream_id == stream_id)
        assert ds is not None and ds.on_off == start and ds.message_rate == (hz if start else 0)

    def wait_for(names):
        seen = set()
        deadline = time.time() + 5
        while not names <= seen and time.time() < deadline:
            msg = m.recv_match(blocking=True, timeout=0.2)
            if msg is not None:
                seen.add(msg.get_type())
        return names - seen

    def quiet(names):
        times, _ = collect([m], 0.6, names)
        return set(times[0])

    request(0, 20, 1)  # ALL
    assert wait_for(everything) == set()
    request(0, 0, 0)
    drain(m, 0.3)
    assert quiet(everything) == set()
    for stream_id, names in GROUPS.items():
        request(stream_id, 20, 1)
        assert wait_for(set(names)) == set(), stream_id
        request(stream_id, 20, 0)
        drain(m, 0.3)
        assert quiet(set(names)) == set(), stream_id


def test_two_ground_stations_get_their_own_rates(vehicle):
    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2])
    g1 = v.gcs(port=p1)
    g2 = v.gcs(port=p2, source_system=254)
    assert set_interval(g1, 30, 200000) == MAV_RESULT_ACCEPTED  # ATTITUDE 5 Hz here
    assert set_interval(g2, 30, 40000) == MAV_RESULT_ACCEPTED  # 25 Hz there
    assert set_interval(g1, 26, 50000) == MAV_RESULT_ACCEPTED  # SCALED_IMU on link 1 only
    assert set_interval(g2, 74, 1e6 / 15, target=2) == MAV_RESULT_ACCEPTED  # VFR_HUD on every link
    assert get_interval(g1, 30) == 200000 and get_interval(g2, 30) == 40000
    collect([g1, g2], 0.5)  # what queued up meanwhile
    times, _ = collect([g1, g2], 4.0, {"ATTITUDE", "SCALED_IMU", "VFR_HUD"})
    assert abs(rate(times[0]["ATTITUDE"]) - 5) <= 0.5
    assert abs(rate(times[1]["ATTITUDE"]) - 25) <= 1.5
    assert abs(rate(times[0]["SCALED_IMU"]) - 20) <= 1.5
    assert "SCALED_IMU" not in times[1]
    for i in (0, 1):
        assert abs(rate(times[i]["VFR_HUD"]) - 15) <= 1.0


def test_message_interval_set_get_disable_restore(vehicle):
    v = vehicle()
    m = v.gcs()
    assert get_interval(m, 30) == 100000  # ATTITUDE: the board's default, 10 Hz
    assert set_interval(m, 30, 40000) == MAV_RESULT_ACCEPTED
    assert get_interval(m, 30) == 40000
    assert set_interval(m, 30, -1) == MAV_RESULT_ACCEPTED
    assert get_interval(m, 30) == -1
    drain(m, 0.2)
    times, _ = collect([m], 1.0, {"ATTITUDE"})
    assert "ATTITUDE" not in times[0]
    assert set_interval(m, 30, 0) == MAV_RESULT_ACCEPTED  # back to the default
    assert get_interval(m, 30) == 100000
    assert recv(m, "ATTITUDE", 2) is not None
    assert set_interval(m, 105, -2) == MAV_RESULT_DENIED  # not an interval
    assert set_interval(m, 22, 100000) == MAV_RESULT_DENIED  # PARAM_VALUE is no stream
    assert get_interval(m, 22) == 0  # 0: not available
    assert get_interval(m, 105) == -1  # HIGHRES_IMU: available, not streamed
    # REQUEST_MESSAGE: MESSAGE_INTERVAL by param2, and a one-shot of any slot.
    assert run(m, REQUEST_MESSAGE, 244, 33) == MAV_RESULT_ACCEPTED
    mi = recv(m, "MESSAGE_INTERVAL", 5, lambda x: x.message_id == 33)
    assert mi is not None and mi.interval_us == 200000
    assert run(m, REQUEST_MESSAGE, 105) == MAV_RESULT_ACCEPTED
    hi = recv(m, "HIGHRES_IMU", 5)
    assert hi is not None and hi.zacc < -9


def test_simulated_vehicle_fills_every_slot_and_flies(vehicle):
    from mission_gcs import MissionClient, Item, LAT0, LON0

    v = vehicle()
    m = v.gcs()
    for msgid in (250, 251, 252, 254):  # DEBUG_VECT, NAMED_VALUE_FLOAT/INT, DEBUG: asked for only
        assert set_interval(m, msgid, 200000) == MAV_RESULT_ACCEPTED
    m.mav.request_data_stream_send(m.target_system, m.target_component, 0, 5, 1)
    drain(m, 0.3)
    times, _ = collect([m], 1.5)
    slots = {"GPS_RAW_INT", "GPS_STATUS", "SCALED_IMU", "RAW_IMU", "RAW_PRESSURE", "SCALED_PRESSURE", "ATTITUDE",
             "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "RC_CHANNELS_SCALED",
             "RC_CHANNELS_RAW", "RC_CHANNELS", "SERVO_OUTPUT_RAW", "NAV_CONTROLLER_OUTPUT", "VFR_HUD",
             "HIGHRES_IMU", "OPTICAL_FLOW", "BATTERY_STATUS", "EXTENDED_SYS_STATE", "NAMED_VALUE_FLOAT",
             "NAMED_VALUE_INT", "DEBUG", "DEBUG_VECT", "SYS_STATUS", "SYSTEM_TIME"}
    assert slots - set(times[0]) == set()

    gps = recv(m, "GPS_RAW_INT", 2)
    assert gps.fix_type >= 3 and gps.satellites_visible >= 6
    assert recv(m, "HIGHRES_IMU", 2).zacc == approx_g()
    assert 940 < recv(m, "SCALED_PRESSURE", 2).press_abs < 970  # 488 m above the sea
    bat = recv(m, "BATTERY_STATUS", 2)
    assert 3000 < bat.voltages[0] < 4300 and 0 <= bat.battery_remaining <= 100
    sys_status = recv(m, "SYS_STATUS", 2)
    assert abs(sys_status.voltage_battery - sum(bat.voltages[:3])) < 100
    assert recv(m, "EXTENDED_SYS_STATE", 2).landed_state == 1  # MAV_LANDED_STATE_ON_GROUND
    consumed0 = bat.current_consumed

    # A mission 60 m north at 10 m, flown in AUTO: the telemetry follows the model.
    plan = [Item(3, 22, 0, 1, 0.0, 0.0, 0.0, 0.0, LAT0, LON0, 10.0),
            Item(3, 16, 0, 1, 0.0, 2.0, 0.0, 0.0, LAT0 + 5400, LON0, 10.0)]
    assert MissionClient(m).upload(plan) == 0
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED  # arm
    assert run(m, 176, 1 | 4) == MAV_RESULT_ACCEPTED  # AUTO
    climbing = listen(m, "GLOBAL_POSITION_INT", 10, lambda g: g.relative_alt > 3000 and g.vz < 0)
    assert climbing is not None
    moving = listen(m, "VFR_HUD", 20, lambda h: h.groundspeed > 1)
    assert moving is not None and moving.throttle > 0
    assert listen(m, "GLOBAL_POSITION_INT", 5, lambda g: g.lat > LAT0 + 500 and g.vx > 0) is not None
    assert listen(m, "ATTITUDE", 2, lambda a: a.pitch < -0.05) is not None  # nose down to go forward
    assert listen(m, "SERVO_OUTPUT_RAW", 2, lambda s: s.servo1_raw > 1300) is not None
    assert listen(m, "EXTENDED_SYS_STATE", 2).landed_state == 2  # in the air
    assert listen(m, "BATTERY_STATUS", 2, lambda b: b.current_battery > 500).current_consumed > consumed0


def approx_g():
    return pytest.approx(-9.81, abs=0.05)


def test_mavsdk_sets_rates_and_reads_telemetry(vehicle):
    from mavsdk.plugins.telemetry import Telemetry

    v = vehicle()
    with mavsdk_system(v.port) as system:
        tel = Telemetry(system)
        tel.set_rate_position(20.0)  # SET_MESSAGE_INTERVAL for GLOBAL_POSITION_INT; raises unless ACCEPTED
        stamps = []
        fixes = []
        tel.subscribe_position(lambda p, _: (stamps.append(time.time()), fixes.append(p)))
        time.sleep(3.0)
        gps = tel.gps_info()
    assert abs(rate(stamps[len(stamps) // 3:]) - 20) <= 2  # after MAVSDK settled on the new rate
    assert abs(fixes[-1].latitude_deg - 47.397742) < 0.001 and abs(fixes[-1].longitude_deg - 8.545594) < 0.001
    assert gps.num_satellites == 12 and gps.fix_type >= 3  # FixType.FIX_3D
