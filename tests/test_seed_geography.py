"""Geography against the unix vehicle over UDP, pymavlink as the ground station:
SET_GPS_GLOBAL_ORIGIN and SAFETY_SET_ALLOWED_AREA answered on change and on request,
kept across a restart; mission items outside the area refused with the coordinate's
MAV_MISSION_INVALID_PARAM*; LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET a slot; refusals
when the sender is not in control or does not address us; STATE_CORRECTION (seed set)
delivered under the seed's dialect (test_seed_mpy.py)."""
import time

from conftest import recv
from gcs_tools import MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, request, statustext
from mission_gcs import LAT0, LON0, MissionClient, plan

INVALID_PARAM5_X, INVALID_PARAM6_Y, INVALID_PARAM7 = 10, 11, 12
FRAME_GLOBAL, FRAME_LOCAL_NED = 0, 1
PASSKEY = "sesame"


def set_area(m, p1, p2, frame=FRAME_GLOBAL, target=(1, 1)):
    m.mav.safety_set_allowed_area_send(target[0], target[1], frame, *p1, *p2)


def area_box():
    # A box around the test plans' points (mission_gcs.waypoint), altitude 0..100 m.
    return ((LAT0 - 5000) / 1e7, (LON0 - 5000) / 1e7, 0.0), ((LAT0 + 200000) / 1e7, (LON0 + 200000) / 1e7, 100.0)


def test_origin_answered_on_change_and_request_and_kept(vehicle, tmp_path):
    # seed: SET_GPS_GLOBAL_ORIGIN
    # seed: GPS_GLOBAL_ORIGIN
    v = vehicle()
    m = v.gcs()
    assert request(m, 49)[1] is None  # nothing to tell before an origin is set
    m.mav.set_gps_global_origin_send(1, LAT0, -1223000000, 12345)
    o = recv(m, "GPS_GLOBAL_ORIGIN", 5)
    assert (o.latitude, o.longitude, o.altitude) == (LAT0, -1223000000, 12345)
    v.stop()
    v = vehicle()  # same storage
    m = v.gcs()
    result, o = request(m, 49)
    assert result == MAV_RESULT_ACCEPTED
    assert (o.latitude, o.longitude, o.altitude) == (LAT0, -1223000000, 12345)
    # A latitude beyond 90 degrees is refused, and said why; the origin stays.
    m.mav.set_gps_global_origin_send(1, 900000001, 0, 0)
    assert statustext(m, "Origin refused") is not None
    assert request(m, 49)[1].latitude == LAT0


def test_not_addressed_or_not_in_control_is_refused(vehicle):
    v = vehicle(args=["--set", "operator_passkey=" + PASSKEY])
    m = v.gcs()
    m.mav.set_gps_global_origin_send(7, LAT0, LON0, 0)  # another system's
    assert recv(m, "GPS_GLOBAL_ORIGIN", 1.5) is None
    m.mav.set_gps_global_origin_send(1, LAT0, LON0, 0)  # ours, but not in control
    assert statustext(m, "not in control") is not None
    assert recv(m, "GPS_GLOBAL_ORIGIN", 1.0) is None
    set_area(m, *area_box())
    assert statustext(m, "not in control") is not None
    assert request(m, 55)[1] is None
    # In control, the same message is taken.
    m.mav.change_operator_control_send(1, 0, 0, PASSKEY.encode())
    assert recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5).ack == 0
    m.mav.set_gps_global_origin_send(1, LAT0, LON0, 0)
    assert recv(m, "GPS_GLOBAL_ORIGIN", 5) is not None


def test_allowed_area_gates_mission_items(vehicle):
    # seed: SAFETY_SET_ALLOWED_AREA
    # seed: SAFETY_ALLOWED_AREA
    v = vehicle()
    m = v.gcs()
    c = MissionClient(m)
    inside = plan(4, tag=1)
    assert c.upload(inside) == 0  # no area yet
    set_area(m, *area_box())
    a = recv(m, "SAFETY_ALLOWED_AREA", 5)
    assert a.frame == FRAME_GLOBAL and abs(a.p1x - (LAT0 - 5000) / 1e7) < 1e-5
    assert c.upload(inside) == 0
    for change, code in ((dict(x=LAT0 - 10000), INVALID_PARAM5_X), (dict(y=LON0 + 300000), INVALID_PARAM6_Y),
                         (dict(z=150.0), INVALID_PARAM7)):
        items = plan(4, tag=2)
        items[2] = items[2]._replace(**change)
        assert c.upload(items) == code
    assert statustext(m, "Mission item 2") is not None
    # The seed's MISSION_ITEM (float degrees) is checked the same way.
    items = plan(2, tag=3, form="float")
    items[1] = items[1]._replace(x=(LAT0 - 10000) / 1e7)
    c.form = "float"
    assert c.upload(items) == INVALID_PARAM5_X
    # Requested, and kept across a restart; six zeros clear it.
    v.stop()
    v = vehicle()
    m = v.gcs()
    result, a = request(m, 55)
    assert result == MAV_RESULT_ACCEPTED and abs(a.p2z - 100.0) < 1e-3
    items = plan(4, tag=4)
    items[0] = items[0]._replace(x=LAT0 - 10000)
    assert MissionClient(m).upload(items) == INVALID_PARAM5_X
    set_area(m, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    time.sleep(0.3)
    assert MissionClient(m).upload(items) == 0
    # A corner that is no position is refused, with a STATUSTEXT.
    set_area(m, (91.0, 8.0, 0.0), (47.0, 9.0, 10.0))
    assert statustext(m, "Allowed area refused") is not None


def test_local_offset_is_a_slot(vehicle):
    # seed: LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET
    v = vehicle()
    m = v.gcs()
    result, msg = request(m, 89)
    assert result == MAV_RESULT_ACCEPTED and msg is None  # nothing written yet: nothing sent
    # The simulator fills it once there is an origin: its start, 1 km south of it here.
    m.mav.set_gps_global_origin_send(1, 474067252, 85455940, 488000)
    time.sleep(0.5)
    result, msg = request(m, 89)
    assert result == MAV_RESULT_ACCEPTED and msg is not None
    assert abs(msg.x + 1000) < 20 and abs(msg.y) < 20


def test_corrupt_store_is_cleared_and_said(tmp_path):
    import os
    import sys

    from conftest import ROOT

    sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
    from harness import Bench

    (tmp_path / "geography").write_bytes(b"\x03" * 40)  # flags say both, CRC wrong
    b = Bench(services=("status", "commands", "geography"), storage=str(tmp_path))
    geo = b.ep.services["geography"]
    assert not geo.origin_set and not geo.area_set
    assert geo.allows(0, 0, 0)
    texts = []
    b.watch = lambda msgid, p: texts.append(bytes(p[1:51]).rstrip(b"\0")) if msgid == 253 else None
    b.run(20, 50)
    assert b"Origin and allowed area corrupt: cleared" in texts
