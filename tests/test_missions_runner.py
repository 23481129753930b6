"""Mission execution support (mavstack/services/missions/runner.py): the order items come in with
DO_JUMPs, MISSION_START's range, autocontinue, the CONDITION items handed to the
application, and the reports ground stations see. In-process on CPython, then the
unix vehicle flying a mission in AUTO."""
import time

import pytest

from conftest import recv
from mission_gcs import Item, MissionClient, plan, waypoint
from mission_rig import Rig

NOT_STARTED, ACTIVE, PAUSED, COMPLETE = 2, 3, 4, 5


def jump(target, repeat):
    return Item(2, 177, 0, 1, float(target), float(repeat), 0.0, 0.0, 0, 0, 0.0)


def fly(rig, steps=100):
    """Carry out every item at once -> the sequence of items flown."""
    runner = rig.missions.runner
    order = []
    while runner.state == ACTIVE and len(order) < steps:
        order.append(runner.current)
        assert runner.item.seq == runner.current
        assert runner.reached()
        rig.run(1)
    return order


@pytest.fixture
def rig(tmp_path):
    return Rig(tmp_path)


def test_do_jump_repeats(rig):
    items = [waypoint(0), waypoint(1), waypoint(2), jump(1, 2), waypoint(4)]
    assert rig.upload(items) == 0
    runner = rig.missions.runner
    assert runner.state == NOT_STARTED
    assert runner.start()
    rig.take()
    assert fly(rig) == [0, 1, 2, 1, 2, 1, 2, 4]
    assert runner.state == COMPLETE
    assert [m.seq for m in rig.take("MISSION_ITEM_REACHED")] == [0, 1, 2, 1, 2, 1, 2, 4]
    rig.run(2)
    assert rig.last("MISSION_CURRENT").mission_state == COMPLETE


def test_nested_jumps_and_forever(rig):
    items = [waypoint(0), waypoint(1), jump(0, 1), waypoint(3), jump(3, 2), waypoint(5)]
    assert rig.upload(items) == 0
    runner = rig.missions.runner
    runner.start()
    assert fly(rig) == [0, 1, 0, 1, 3, 3, 3, 5]
    assert rig.upload([waypoint(0), waypoint(1), jump(0, -1)]) == 0  # -1: for ever
    runner.start()
    assert fly(rig, steps=20) == [0, 1] * 10


def test_jump_counters_reset(rig):
    items = [waypoint(0), waypoint(1), jump(0, 1), waypoint(3)]
    assert rig.upload(items) == 0
    runner = rig.missions.runner
    runner.start()
    assert fly(rig, steps=3) == [0, 1, 0]  # the jump is used up
    assert rig.upload(items) == 0  # a new upload resets the counters
    runner.start()
    assert fly(rig) == [0, 1, 0, 1, 3]
    runner.start()  # so does MISSION_START
    assert fly(rig, steps=3) == [0, 1, 0]
    rig.send("command_long", 1, 1, 224, 0, 1, 1, 0, 0, 0, 0, 0)  # DO_SET_MISSION_CURRENT 1, reset
    assert rig.last("COMMAND_ACK").result == 0
    assert fly(rig) == [1, 0, 1, 3]


def test_mission_start_range(rig):
    assert rig.upload(plan(8)) == 0
    runner = rig.missions.runner
    rig.send("command_long", 1, 1, 300, 0, 2, 4, 0, 0, 0, 0, 0)  # MAV_CMD_MISSION_START 2..4
    assert rig.last("COMMAND_ACK").result == 0
    assert fly(rig) == [2, 3, 4]
    rig.send("command_long", 1, 1, 300, 0, 0, 0, 0, 0, 0, 0, 0)  # as QGroundControl sends it
    assert fly(rig) == list(range(8))
    rig.send("command_long", 1, 1, 300, 0, 9, 0, 0, 0, 0, 0, 0)
    assert rig.last("COMMAND_ACK").result == 4  # FAILED: no item 9
    assert rig.upload([]) == 0
    rig.send("command_long", 1, 1, 300, 0, 0, 0, 0, 0, 0, 0, 0)
    assert rig.last("COMMAND_ACK").result == 4  # nothing to fly
    assert runner.state == 1  # NO_MISSION


def test_autocontinue_off_holds(rig):
    items = [waypoint(0), waypoint(1)._replace(autocontinue=0), waypoint(2)]
    assert rig.upload(items) == 0
    runner = rig.missions.runner
    runner.start()
    assert runner.reached() and runner.current == 1
    assert runner.reached() and runner.waiting and runner.current == 1
    assert not runner.reached()  # reported once
    runner.proceed()
    assert runner.current == 2 and not runner.waiting


def test_conditions_reach_the_application(rig):
    items = [waypoint(0),
             Item(2, 112, 0, 1, 3.0, 0, 0, 0, 0, 0, 0.0),  # CONDITION_DELAY 3 s
             Item(2, 114, 0, 1, 25.0, 0, 0, 0, 0, 0, 0.0),  # CONDITION_DISTANCE 25 m
             Item(2, 115, 0, 1, 90.0, 30.0, 1.0, 0.0, 0, 0, 0.0),  # CONDITION_YAW 90 deg
             Item(3, 113, 0, 1, 2.0, 0, 0, 0, 0, 0, 40.0),  # CONDITION_CHANGE_ALT to 40 m
             waypoint(5)]
    assert rig.upload(items) == 0
    runner = rig.missions.runner
    runner.start()
    runner.reached()
    item = runner.item
    assert (item.command, item.param1, item.is_condition) == (112, 3.0, True)
    rig.run(1500)
    assert 1400 <= runner.elapsed_ms() <= 1600
    runner.reached()
    assert runner.item.command == 114 and runner.item.param1 == 25.0
    nxt = runner.next_nav()
    assert nxt.seq == 5 and nxt.is_nav and abs(nxt.lat - items[5].x / 1e7) < 1e-9
    runner.reached()
    assert (runner.item.command, runner.item.param1, runner.item.param2) == (115, 90.0, 30.0)
    runner.reached()
    assert (runner.item.command, runner.item.z) == (113, 40.0)


def test_run_pause_and_set_current(rig):
    assert rig.upload(plan(5)) == 0
    runner = rig.missions.runner
    seen = []
    runner.on_item = lambda r: seen.append(r.current)
    assert runner.run() and runner.state == ACTIVE
    runner.reached()
    runner.pause()
    assert runner.state == PAUSED
    rig.send("mission_set_current", 1, 1, 3)
    assert runner.current == 3 and runner.state == PAUSED
    assert runner.run() and runner.current == 3
    assert fly(rig) == [3, 4]
    assert seen[:3] == [0, 1, 3]
    rig.send("mission_set_current", 1, 1, 1)  # a completed mission can be flown again from an item
    assert runner.run() and fly(rig) == [1, 2, 3, 4]


def test_simulator_flies_the_mission(vehicle):
    """The unix vehicle in AUTO and armed flies the waypoints (fast, for the test), jumps
    as DO_JUMP says, and reports each item reached; its position follows."""
    v = vehicle(args=["--set", "sim_speed=1000", "--set", "sim_climb=300"])
    m = v.gcs()
    lat, lon = 473977420, 85455940
    items = [Item(3, 22, 0, 1, 0, 0, 0, 0, 0, 0, 20.0),  # TAKEOFF to 20 m
             Item(3, 16, 0, 1, 0, 5.0, 0, 0, lat + 20000, lon, 20.0),
             Item(3, 16, 0, 1, 0, 5.0, 0, 0, lat + 20000, lon + 30000, 30.0),
             jump(1, 1),
             Item(2, 112, 0, 1, 0.2, 0, 0, 0, 0, 0, 0.0),  # CONDITION_DELAY 0.2 s
             Item(3, 16, 0, 1, 0, 5.0, 0, 0, lat - 10000, lon - 10000, 25.0)]
    c = MissionClient(m)
    assert c.upload(items) == 0
    m.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)  # arm
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 400).result == 0
    m.mav.command_long_send(1, 1, 176, 0, 4 | 1, 0, 0, 0, 0, 0, 0)  # DO_SET_MODE: AUTO
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 176).result == 0
    reached = []
    done = None
    deadline = time.time() + 30
    beat = 0
    while time.time() < deadline and done is None:
        if time.time() > beat:  # a ground station's heartbeat: the vehicle keeps talking to us
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            beat = time.time() + 1
        msg = recv(m, ["MISSION_ITEM_REACHED", "MISSION_CURRENT"], 5)
        assert msg is not None
        if msg.get_type() == "MISSION_ITEM_REACHED":
            reached.append(msg.seq)
        elif msg.mission_state == COMPLETE:
            done = msg
    assert reached == [0, 1, 2, 1, 2, 4, 5], reached
    pos = recv(m, "GLOBAL_POSITION_INT", 5)
    v.check_alive()
    assert pos is not None
    # within the acceptance radius (5 m) of the last waypoint
    assert abs(pos.lat - (lat - 10000)) < 500 and abs(pos.lon - (lon - 10000)) < 700
    assert abs(pos.relative_alt / 1000.0 - 25.0) < 3.0
