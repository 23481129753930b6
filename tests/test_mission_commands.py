"""Missions as today's planners make them: the commands MAVSDK's and QGroundControl's
planners put in a plan (NAV_DELAY, DO_CHANGE_SPEED, regions of interest, loiter to
altitude, landing sequences, camera and gimbal) are accepted and flown by the simulated
vehicle; a takeoff at "the current position" (x, y INT32_MAX) is accepted; an item the
vehicle refuses gets the exact MISSION_ACK result and a STATUSTEXT naming the item and
its command. Rules in-process (CPython, the bench's memory link), then over UDP against
the unix vehicle with pymavlink and MAVSDK."""
import math
import time

import pytest

import gcs_tools
from conftest import recv
from gcs_tools import mavsdk_system
from mission_gcs import LAT0, LON0, Item, MissionClient, same, waypoint
from mission_rig import Rig

ACCEPTED, UNSUPPORTED_FRAME, UNSUPPORTED = 0, 2, 3
INVALID_PARAM1, INVALID_PARAM5_X, INVALID_PARAM7 = 6, 10, 12
COMPLETE = 5
INT32_MAX = 0x7FFFFFFF
NAN = float("nan")

# One item of each command the planners emit (frame, command, current, autocontinue,
# p1..p4, x, y, z), as they fill them.
PLANNERS = [
    Item(3, 22, 0, 1, 0.0, 0.0, 0.0, NAN, INT32_MAX, INT32_MAX, 15.0),  # NAV_TAKEOFF here
    Item(2, 178, 0, 1, 1.0, 12.0, -1.0, 0.0, 0, 0, NAN),  # DO_CHANGE_SPEED: ground, 12 m/s
    Item(3, 195, 0, 1, 0.0, 0.0, 0.0, 0.0, LAT0 + 3000, LON0 + 3000, 5.0),  # DO_SET_ROI_LOCATION
    Item(2, 1000, 0, 1, -45.0, 0.0, NAN, NAN, 0, 0, 0.0),  # DO_GIMBAL_MANAGER_PITCHYAW
    Item(2, 205, 0, 1, -90.0, 0.0, 30.0, 0.0, 0, 0, 2.0),  # DO_MOUNT_CONTROL
    Item(3, 16, 0, 1, 0.0, 2.0, 0.0, NAN, LAT0 + 1000, LON0, 15.0),  # NAV_WAYPOINT
    Item(2, 93, 0, 1, 1.0, -1.0, -1.0, -1.0, 0, 0, 0.0),  # NAV_DELAY 1 s (MAVSDK's loiter_time_s)
    Item(2, 206, 0, 1, 20.0, 0.0, 1.0, 0.0, 0, 0, 0.0),  # DO_SET_CAM_TRIGG_DIST
    Item(2, 2000, 0, 1, 0.0, 0.0, 1.0, 0.0, 0, 0, NAN),  # IMAGE_START_CAPTURE: one photo
    Item(2, 2001, 0, 1, 0.0, NAN, NAN, NAN, 0, 0, NAN),  # IMAGE_STOP_CAPTURE
    Item(2, 197, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),  # DO_SET_ROI_NONE
    Item(2, 189, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),  # DO_LAND_START
    Item(3, 31, 0, 1, 0.0, 10.0, 0.0, 0.0, LAT0 + 1000, LON0 + 1000, 8.0),  # NAV_LOITER_TO_ALT
    Item(3, 21, 0, 1, 0.0, 0.0, 0.0, NAN, INT32_MAX, INT32_MAX, 0.0),  # NAV_LAND here
]


@pytest.fixture
def rig(tmp_path):
    return Rig(tmp_path, services=("status", "commands", "missions"))


def texts(rig):
    return [m.text for m in rig.take("STATUSTEXT")]


def test_planners_commands_are_accepted(rig):
    for item in PLANNERS:
        assert rig.upload([waypoint(0), item]) == ACCEPTED, item
    assert rig.upload(PLANNERS) == ACCEPTED
    assert same(rig.download(), PLANNERS)
    rig.run(50)
    assert texts(rig) == []


@pytest.mark.parametrize("item, code, text", [
    (Item(2, 31000, 0, 1, 0, 0, 0, 0, 0, 0, 0.0), UNSUPPORTED, "Mission item 1: cmd 31000 unsupported"),
    (Item(1, 16, 0, 1, 0, 0, 0, 0, 0, 0, 5.0), UNSUPPORTED_FRAME, "Mission item 1: cmd 16 frame 1 unsupported"),
    (Item(2, 195, 0, 1, 0, 0, 0, 0, 0, 0, 0.0), UNSUPPORTED_FRAME, "Mission item 1: cmd 195 frame 2 unsupported"),
    (Item(2, 93, 0, 1, NAN, 0, 0, 0, 0, 0, 0.0), INVALID_PARAM1, "Mission item 1: cmd 93 param1 invalid"),
    (Item(3, 16, 0, 1, 0, 0, 0, 0, INT32_MAX, LON0, 5.0), INVALID_PARAM5_X, "Mission item 1: cmd 16 x/lat invalid"),
    (Item(3, 16, 0, 1, 0, 0, 0, 0, LAT0, LON0, NAN), INVALID_PARAM7, "Mission item 1: cmd 16 z/alt invalid"),
])
def test_refusal_names_item_and_command(rig, item, code, text):
    assert rig.upload([waypoint(0), waypoint(1)]) == ACCEPTED
    rig.run(50)
    rig.take()
    assert rig.upload([waypoint(0), item, waypoint(2)]) == code
    rig.run(50)
    assert texts(rig) == [text]
    assert len(rig.download()) == 2  # the plan in force stands


def test_refusal_text_of_fence_and_big_numbers(rig):
    fence = [Item(0, 5001, 0, 1, 4.0, 0, 0, 0, LAT0, LON0, 0.0)] * 3 + [waypoint(3)]
    assert rig.upload(fence, mission_type=1) == UNSUPPORTED
    rig.run(50)
    assert texts(rig) == ["Fence item 3: cmd 16 unsupported"]
    items = [waypoint(i) for i in range(300)]
    items[299] = Item(2, 65535, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)
    assert rig.upload(items) == UNSUPPORTED
    rig.run(50)
    assert texts(rig) == ["Mission item 299: cmd 65535 unsupported"]


def test_takeoff_where_the_vehicle_is(rig):
    """x, y INT32_MAX: "the current position", where the command may take it; the seed's
    MISSION_ITEM says it with NaN, and gets NaN back."""
    takeoff = Item(3, 22, 0, 1, 0.0, 0.0, 0.0, 0.0, INT32_MAX, INT32_MAX, 20.0)
    assert rig.upload([takeoff, waypoint(1)]) == ACCEPTED
    got = rig.download()
    assert (got[0].x, got[0].y) == (INT32_MAX, INT32_MAX)
    down = rig.download(as_int=False)
    assert math.isnan(down[0].x) and math.isnan(down[0].y)
    seed = [takeoff._replace(x=NAN, y=NAN), waypoint(1, form="float")]
    assert rig.upload(seed, as_int=False) == ACCEPTED
    assert (rig.download()[0].x, rig.download()[0].y) == (INT32_MAX, INT32_MAX)
    # A waypoint needs its position: NaN or INT32_MAX there is refused.
    assert rig.upload([waypoint(0)._replace(x=INT32_MAX)]) == INVALID_PARAM5_X
    assert rig.upload([waypoint(0, form="float")._replace(x=NAN)], as_int=False) == INVALID_PARAM5_X
    runner = rig.missions.runner
    rig.upload([takeoff])
    item = runner.item
    assert item.x_unset and item.y_unset and math.isnan(item.lat) and item.z == 20.0


def test_udp_upload_of_every_planner_command(vehicle):
    v = vehicle()
    m = v.gcs()
    c = MissionClient(m)
    assert c.upload(PLANNERS) == ACCEPTED
    assert same(c.download(), PLANNERS)
    v.check_alive()


def test_udp_refusal_ack_and_statustext(vehicle):
    v = vehicle()
    m = v.gcs()
    c = MissionClient(m)
    assert c.upload([waypoint(0), waypoint(1), Item(2, 31000, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)]) == UNSUPPORTED
    assert gcs_tools.statustext(m, "Mission item 2: cmd 31000 unsupported") is not None
    v.check_alive()


def _fly(m, count, seconds=40):
    """Arm, AUTO, and listen until MISSION_CURRENT says complete -> (items reached in
    order, seconds each was reached at)."""
    assert gcs_tools.run(m, 400, 1) == 0  # arm
    assert gcs_tools.run(m, 176, 4 | 1) == 0  # DO_SET_MODE: AUTO
    start = time.time()
    reached, at = [], []
    deadline = start + seconds
    beat = 0
    while time.time() < deadline:
        if time.time() > beat:
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            beat = time.time() + 1
        msg = recv(m, ["MISSION_ITEM_REACHED", "MISSION_CURRENT"], 5)
        assert msg is not None
        if msg.get_type() == "MISSION_ITEM_REACHED":
            if not reached or reached[-1] != msg.seq:
                reached.append(msg.seq)
                at.append(time.time() - start)
        elif msg.mission_state == COMPLETE and msg.total == count:
            return reached, at
    raise AssertionError("mission not complete: reached %r" % reached)


def test_simulator_flies_the_planners_commands(vehicle):
    """Takeoff where it stands, the speed change, ROI and camera items, a 1 s NAV_DELAY,
    loiter to altitude and a landing where it is: every item reached, in order."""
    v = vehicle(args=["--set", "sim_speed=200", "--set", "sim_climb=100"])
    m = v.gcs()
    c = MissionClient(m)
    assert c.upload(PLANNERS) == ACCEPTED
    reached, at = _fly(m, len(PLANNERS))
    assert reached == list(range(len(PLANNERS)))
    assert at[6] - at[5] >= 0.9  # the NAV_DELAY held
    pos = recv(m, "GLOBAL_POSITION_INT", 5)
    # Landed where the loiter-to-altitude item was (x, y unset: here).
    assert abs(pos.lat - (LAT0 + 1000)) < 300 and abs(pos.lon - (LON0 + 1000)) < 400
    assert abs(pos.relative_alt) < 1500
    v.check_alive()


def test_mavsdk_mission_with_loiter_time_flies_to_the_end(vehicle):
    """MAVSDK's Mission plugin: loiter_time_s (NAV_DELAY), speed (DO_CHANGE_SPEED), camera
    actions (IMAGE_START_CAPTURE, DO_SET_CAM_TRIGG_DIST, video), a takeoff and a
    landing; the upload is accepted, and the vehicle (armed and put in AUTO by a
    pymavlink ground station on a second link) flies it to the end: MAVSDK's mission
    progress reaches the total. (MAVSDK itself refuses a plan with a gimbal angle unless
    the vehicle has a gimbal manager it has discovered: the vehicle never sees that
    upload; DO_GIMBAL_MANAGER_PITCHYAW and DO_MOUNT_CONTROL are in the pymavlink
    upload above.)"""
    from mavsdk.plugins.mission import Mission, MissionItem, MissionPlan

    v, port, m = gcs_tools.two_links(vehicle, "--set", "sim_speed=100", "--set", "sim_climb=50")
    lat, lon = LAT0 / 1e7, LON0 / 1e7
    CA, VA = MissionItem.CameraAction, MissionItem.VehicleAction

    def item(dlat, dlon, alt, speed=NAN, loiter=NAN, camera=CA.NONE, action=VA.NONE, distance=NAN):
        return MissionItem(lat + dlat, lon + dlon, alt, speed, False, NAN, NAN, camera, loiter, NAN, NAN,
                           NAN, distance, action)

    items = [item(0, 0, 10, action=VA.TAKEOFF),
             item(0.0002, 0, 12, speed=8.0, loiter=1.0, camera=CA.TAKE_PHOTO),
             item(0.0002, 0.0002, 12, camera=CA.START_PHOTO_DISTANCE, distance=20.0),
             item(0, 0.0002, 12, loiter=0.5, camera=CA.STOP_PHOTO_DISTANCE),
             item(0, 0.0001, 12, camera=CA.START_VIDEO),
             item(0, 0, 12, camera=CA.STOP_VIDEO),
             item(0, 0, 0, action=VA.LAND)]
    with mavsdk_system(port) as system:
        mission = Mission(system)
        mission.upload_mission(MissionPlan(items))
        held = MissionClient(m).download()
        commands = [h.command for h in held]
        for command in (93, 178, 2000, 206, 2500, 2501, 22, 21):  # loiter_time_s, speed, camera ...
            assert command in commands, commands
        reached, at = _fly(m, len(held))
        assert reached == list(range(len(held)))
        deadline = time.time() + 10
        progress = mission.mission_progress()
        while (progress.current != progress.total) and time.time() < deadline:
            time.sleep(0.2)
            progress = mission.mission_progress()
        assert progress.total == len(items) and progress.current == progress.total, progress
        assert mission.is_mission_finished()
    v.check_alive()


# --- on MicroPython: the check and its refusal text allocate nothing -----------------
CHECK_SCRIPT = """
import struct
nan = float("nan")
import sys
from harness import Bench, Board, heap_requests
from mavstack.services.missions import items as mission_items

class B(Board):
    MISSION_CAPACITY = 20
    FENCE_CAPACITY = 4
    RALLY_CAPACITY = 2

b = Bench(services=("status", "commands", "missions"), board=B, storage="ram")
m = b.ep.services["missions"]
status = b.ep.services["status"]
m.transfer.store = m.stores[0]
m.transfer.count = 5
items = []
for frame, command, p1, x, y, z in %r:
    p = bytearray(38)
    struct.pack_into("<ffffiifHHBBBBB", p, 0, p1, 0.0, 0.0, 0.0, x, y, z, 1, command, 1, 1, frame, 0, 1)
    items.append(p)
results = [0] * len(items)

class Run:
    def go(self, _):
        i = 0
        while i < len(items):
            results[i] = mission_items.check(m, items[i], True, i + 1)
            i += 1

requested = heap_requests(Run().go, 0)
print(results)
print(requested, status.texts.count, status.texts.text(0), status.texts.text(status.texts.count - 1))
"""


def test_check_and_refusal_text_allocate_nothing_on_micropython():
    import os

    from conftest import ROOT, run_mpy

    cases = [(3, 22, 0.0, INT32_MAX, INT32_MAX, 10.0), (2, 93, 1.0, 0, 0, 0.0), (2, 2000, 0.0, 0, 0, NAN),
             (3, 195, 0.0, LAT0, LON0, 5.0), (2, 31000, 0.0, 0, 0, 0.0), (1, 16, 0.0, 0, 0, 5.0),
             (2, 93, NAN, 0, 0, 0.0), (3, 16, 0.0, INT32_MAX, LON0, 5.0)]
    r = run_mpy(CHECK_SCRIPT % (cases,), path=[os.path.join(ROOT, "tests", "mpy")])
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.strip().splitlines()
    assert lines[0] == "[0, 0, 0, 0, 3, 2, 6, 10]"
    requested, count, _ = lines[1].split(" ", 2)
    assert requested == "0" and count == "8", lines[1]  # two passes, four refusals each
    assert lines[1].endswith("Mission item 5: cmd 31000 unsupported Mission item 8: cmd 16 x/lat invalid"), lines[1]


def test_simulator_carries_out_roi_camera_gimbal_and_speed(tmp_path):
    """In-process (CPython): the simulator as the unix board's application, its clock
    stepped 20 ms at a time. Flying north with a region of interest to the east, the nose
    points east; distance-triggered photos follow the metres flown; gimbal angles, video
    and a changed speed stay as the items set them."""
    import os
    import sys

    from conftest import ROOT

    sys.path.insert(0, os.path.join(ROOT, "firmware"))
    from sim import Simulator

    r = Rig(tmp_path, services=("status", "commands", "missions"),
            options={"sim_speed": "50", "sim_climb": "50"})
    items = [Item(3, 22, 0, 1, 0.0, 0.0, 0.0, NAN, INT32_MAX, INT32_MAX, 10.0),
             Item(3, 195, 0, 1, 0.0, 0.0, 0.0, 0.0, LAT0, LON0 + 500000, 10.0),  # ROI 3.8 km east
             Item(2, 2000, 0, 1, 0.0, 0.0, 1.0, 0.0, 0, 0, NAN),  # one photo
             Item(2, 206, 0, 1, 10.0, 0.0, 0.0, 0.0, 0, 0, NAN),  # a photo every 10 m
             Item(3, 16, 0, 1, 0.0, 2.0, 0.0, NAN, LAT0 + 9000, LON0, 10.0),  # 100 m north
             Item(2, 206, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, NAN),  # no more
             Item(2, 205, 0, 1, -90.0, 0.0, 0.0, 0.0, 0, 0, 2.0),  # mount pitch -90
             Item(2, 1000, 0, 1, NAN, 30.0, NAN, NAN, 0, 0, 0.0),  # gimbal yaw 30, pitch kept
             Item(2, 197, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),  # ROI none
             Item(2, 2500, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, NAN),  # video on
             Item(2, 178, 0, 1, 1.0, 3.0, -1.0, 0.0, 0, 0, NAN),  # 3 m/s
             Item(2, 93, 0, 1, 0.5, -1.0, -1.0, -1.0, 0, 0, 0.0),  # NAV_DELAY 0.5 s
             Item(3, 16, 0, 1, 0.0, 2.0, 0.0, NAN, LAT0 + 9000, LON0 + 100, 10.0)]  # 7.5 m east
    assert r.upload(items) == ACCEPTED
    sim = Simulator(r.ep)
    r.b.app = sim
    status = r.ep.services["status"]
    runner = r.missions.runner
    status.arm(True)
    status.set_mode(4 | 1 | 128)  # AUTO, custom mode flag, armed
    headings = []
    delay_ms = 0
    for _ in range(3000):
        r.b.run(1, 20)
        r.take()
        if runner.current == 4 and runner.state == 3:
            headings.append(math.degrees(sim.heading) % 360.0)
        if runner.current == 11:
            delay_ms += 20
        if runner.state == COMPLETE:
            break
    assert runner.state == COMPLETE, (runner.current, runner.state)
    # The nose on the ROI, east, all the way north.
    assert len(headings) > 5 and all(80 < h < 100 for h in headings[3:]), str([round(h) for h in headings])
    assert sim.roi is None and sim.video and sim.gimbal == (-90.0, 30.0)
    assert 10 <= sim.photos <= 12, sim.photos  # one, then one per 10 m of the 100 m leg
    assert sim._pilot.speed == 3.0
    assert 480 <= delay_ms <= 560
    assert abs(sim.alt - 488.0 - 10.0) < 0.6
