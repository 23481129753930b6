"""Mission protocol rules, in-process on CPython: the missions service on the bench's
in-memory link and a simulated clock, pymavlink encoding the ground stations' frames
and decoding the vehicle's. Exact counts and timings are visible here; the same
behaviour over UDP against the unix vehicle is in test_missions_e2e.py."""
import math
import os
import struct
import sys
import types

import pytest

from conftest import ROOT
from mission_gcs import Item, plan, same, waypoint
from mission_rig import MissionBoard, Rig

ACCEPTED, ERROR, UNSUPPORTED_FRAME, UNSUPPORTED, NO_SPACE = 0, 1, 2, 3, 4
INVALID_PARAM1, INVALID_PARAM2, INVALID_PARAM5_X, INVALID_PARAM6_Y, INVALID_PARAM7 = 6, 7, 10, 11, 12
INVALID_SEQUENCE, DENIED, OPERATION_CANCELLED = 13, 14, 15
NAN = float("nan")


@pytest.fixture
def rig(tmp_path):
    return Rig(tmp_path)


def test_upload_download_and_mission_current(rig):
    items = plan(10, tag=3)
    assert rig.upload(items) == ACCEPTED
    rig.run(2)
    cur = rig.last("MISSION_CURRENT")  # sent on the change, before the 1 Hz beat
    assert (cur.seq, cur.total) == (0, 10)
    assert same(rig.download(), items)
    assert same(rig.download(as_int=False), plan(10, tag=3, form="float"))
    # Count 0 clears; MISSION_CURRENT then says "no mission".
    assert rig.upload([]) == ACCEPTED
    rig.run(2)
    cur = rig.last("MISSION_CURRENT")
    assert cur.total == 0xFFFF and cur.mission_state == 1  # MISSION_STATE_NO_MISSION
    assert rig.download() == []


def test_mission_current_once_a_second(rig):
    rig.take()
    rig.run(3000)
    assert 2 <= len(rig.take("MISSION_CURRENT")) <= 4


def test_seed_form_over_mavlink1(rig):
    """A MAVLink 1 ground station that speaks only the seed's messages is asked with
    MISSION_REQUEST and answered with MISSION_ITEM; coordinates convert exactly."""
    items = plan(20, tag=1, form="float")
    rig.take()
    rig.send("mission_count", 1, 1, 20, 0, v1=True)
    req = rig.take(["MISSION_REQUEST", "MISSION_REQUEST_INT"])
    assert {r.get_type() for r in req} == {"MISSION_REQUEST"} and all(r._raw[0] == 0xFE for r in req)
    assert req[0].seq == 0
    assert rig.upload(items, v1=True, as_int=False) == ACCEPTED
    got = rig.download(v1=True, as_int=False)
    assert same(got, items)
    # Stored as MISSION_ITEM_INT integers: the float degrees * 1e7, rounded.
    ints = rig.download()
    for f, i in zip(items, ints):
        assert i.x == round(f.x * 1e7) and i.y == round(f.y * 1e7)


def test_item_form_follows_the_ground_station(rig):
    """A MAVLink 2 ground station that answers MISSION_REQUEST_INT with MISSION_ITEM is
    asked in its terms from then on."""
    items = plan(12, form="float")
    rig.take()
    rig.send("mission_count", 1, 1, 12, 0)
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == list(range(8))  # a window of 8
    rig.send("mission_item", *rig.item_args(0, items[0]))
    req = rig.take(["MISSION_REQUEST", "MISSION_REQUEST_INT"])
    assert [(r.get_type(), r.seq) for r in req] == [("MISSION_REQUEST", 8)]


@pytest.mark.parametrize("change, code", [
    (dict(frame=1), UNSUPPORTED_FRAME),  # MAV_FRAME_LOCAL_NED: this vehicle flies global frames
    (dict(frame=2), UNSUPPORTED_FRAME),  # a waypoint in MAV_FRAME_MISSION has no position
    (dict(command=31000), UNSUPPORTED),  # MAV_CMD_WAYPOINT_USER_1: not declared by the application
    (dict(command=5001), UNSUPPORTED),  # a fence vertex in the mission
    (dict(x=900000001), INVALID_PARAM5_X),
    (dict(x=-900000001), INVALID_PARAM5_X),
    (dict(y=1800000001), INVALID_PARAM6_Y),
    (dict(z=NAN), INVALID_PARAM7),
    (dict(command=177, frame=2, p1=NAN, p2=1.0), INVALID_PARAM1),  # DO_JUMP without a target
    (dict(command=177, frame=2, p1=9.0, p2=1.0), INVALID_PARAM1),  # ... beyond the plan
    (dict(command=177, frame=2, p1=0.0, p2=-2.0), INVALID_PARAM2),
    (dict(command=112, frame=2, p1=NAN), INVALID_PARAM1),  # CONDITION_DELAY needs its delay
    (dict(command=19, p1=NAN), INVALID_PARAM1),  # LOITER_TIME needs its time
])
def test_validation_result_codes(rig, change, code):
    old = plan(4, tag=7)
    assert rig.upload(old) == ACCEPTED
    new = plan(5, tag=8)
    new[3] = new[3]._replace(**change)
    assert rig.upload(new) == code
    assert same(rig.download(), old)  # the stored plan is untouched


def test_validation_of_seed_form_coordinates(rig):
    old = plan(2, tag=1)
    assert rig.upload(old) == ACCEPTED
    for x, y, code in ((91.0, 8.0, INVALID_PARAM5_X), (NAN, 8.0, INVALID_PARAM5_X),
                       (47.0, math.inf, INVALID_PARAM6_Y), (47.0, -180.5, INVALID_PARAM6_Y),
                       (1e30, 8.0, INVALID_PARAM5_X)):
        new = [waypoint(0, form="float")._replace(x=x, y=y)]
        assert rig.upload(new, as_int=False) == code
    # A command without a position keeps NaN x/y as 0.
    jump = [waypoint(0, form="float"), Item(2, 177, 0, 1, 0.0, 1.0, 0.0, 0.0, NAN, NAN, 0.0)]
    assert rig.upload(jump, as_int=False) == ACCEPTED
    assert rig.download()[1].x == 0
    assert rig.upload(old) == ACCEPTED


def test_declared_commands_are_accepted(tmp_path):
    class Board(MissionBoard):
        MISSION_COMMANDS = (31000,)

    r = Rig(tmp_path, board=Board)
    items = [waypoint(0), Item(2, 31000, 0, 1, 1.0, 2.0, 3.0, 4.0, 0, 0, 0.0)]
    assert r.upload(items) == ACCEPTED
    r.missions.allow(31001)
    assert r.upload([waypoint(0), items[1]._replace(command=31001)]) == ACCEPTED


def test_no_space_and_jump_slots(tmp_path):
    class Board(MissionBoard):
        MISSION_CAPACITY = 30
        MISSION_JUMP_SLOTS = 2

    r = Rig(tmp_path, board=Board)
    old = plan(30)
    assert r.upload(old) == ACCEPTED
    r.take()
    r.send("mission_count", 1, 1, 31, 0)
    assert r.last("MISSION_ACK").type == NO_SPACE
    jumps = plan(4) + [Item(2, 177, 0, 1, 0.0, 1.0, 0, 0, 0, 0, 0.0)] * 3
    assert r.upload(jumps) == NO_SPACE  # three DO_JUMPs, counters for two
    assert same(r.download(), old)


def test_clear_all(rig):
    assert rig.upload(plan(5)) == ACCEPTED
    rig.take()
    rig.send("mission_clear_all", 1, 1, 0)
    assert rig.last("MISSION_ACK").type == ACCEPTED
    assert rig.download() == []
    # 255 clears every plan type.
    fence = [Item(5, 5001, 0, 1, 3.0, 0, 0, 0, 473977420 + i * 1000, 85455940, 0.0) for i in range(3)]
    assert rig.upload(plan(2)) == ACCEPTED and rig.upload(fence, mission_type=1) == ACCEPTED
    rig.send("mission_clear_all", 1, 1, 255)
    assert rig.last("MISSION_ACK").type == ACCEPTED
    assert rig.download() == [] and rig.download(mission_type=1) == []


def test_fence_and_rally(rig):
    mission = plan(3)
    fence = [Item(5, 5001, 0, 1, 4.0, 0, 0, 0, 473977420 + d[0], 85455940 + d[1], 0.0)
             for d in ((0, 0), (1000, 0), (1000, 1000), (0, 1000))]
    fence.append(Item(5, 5003, 0, 1, 50.0, 0, 0, 0, 473977420, 85455940, 0.0))
    rally = [Item(6, 5100, 0, 1, 0, 0, 0, 0, 473977420 + 500, 85455940, 20.0)]
    assert rig.upload(mission) == ACCEPTED
    assert rig.upload(fence, mission_type=1) == ACCEPTED
    assert rig.upload(rally, mission_type=2) == ACCEPTED
    assert same(rig.download(), mission)
    assert same(rig.download(mission_type=1), fence)
    assert same(rig.download(mission_type=2), rally)
    assert rig.upload([waypoint(0)], mission_type=1) == UNSUPPORTED  # a waypoint is no fence item
    assert rig.upload([fence[0]], mission_type=2) == UNSUPPORTED
    rig.take()
    rig.send("mission_count", 1, 1, 1, 3)  # no such plan type
    assert rig.last("MISSION_ACK").type == UNSUPPORTED
    caps = rig.ep.capabilities
    assert caps & 4 and caps & 16384 and caps & 32768  # MISSION_INT, MISSION_FENCE, MISSION_RALLY


def test_fence_and_rally_refused_over_mavlink1(rig):
    """mission_type is a MAVLink 2 extension: on a link held to MAVLink 1 a fence or
    rally transfer cannot be answered in kind, so it is refused."""
    link = rig.ep.links[0]
    link.negotiate = False
    link.tx.version = 1
    fence = [Item(5, 5001, 0, 1, 3.0, 0, 0, 0, 473977420, 85455940, 0.0)]
    for start in (("mission_count", 1, 1, 1, 1), ("mission_request_list", 1, 1, 2),
                  ("mission_clear_all", 1, 1, 1)):
        rig.take()
        rig.send(*start)
        ack = rig.last("MISSION_ACK")
        assert ack is not None and ack.type == UNSUPPORTED
    assert rig.upload(plan(2), v1=True) == ACCEPTED  # the mission itself is fine
    assert rig.upload(fence, mission_type=1) == UNSUPPORTED


def test_partial_write(rig):
    items = plan(10, tag=1)
    assert rig.upload(items) == ACCEPTED
    rig.take()
    rig.send("mission_write_partial_list", 1, 1, 3, 5, 0)
    new = plan(10, tag=2)
    # 3 and 4 at once; the last item once all before it are in.
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [3, 4]
    rig.send("mission_item_int", *rig.item_args(3, new[3]))
    assert rig.take("MISSION_REQUEST_INT") == []
    rig.send("mission_item_int", *rig.item_args(4, new[4]))
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [5]
    rig.send("mission_item_int", *rig.item_args(5, new[5]))
    assert rig.last("MISSION_ACK").type == ACCEPTED
    assert same(rig.download(), items[:3] + new[3:6] + items[6:])
    # The seed's rule: a start beyond the current list is rejected; the plan stays.
    for start, end in ((10, 10), (12, 14), (5, 4), (-1, 3)):
        rig.send("mission_write_partial_list", 1, 1, start, end, 0)
        assert rig.last("MISSION_ACK").type == INVALID_SEQUENCE
    # A range running past the end extends the list.
    rig.send("mission_write_partial_list", 1, 1, 9, 11, 0)
    for seq in (9, 10, 11):
        rig.send("mission_item_int", *rig.item_args(seq, new[seq % 10]))
    assert rig.last("MISSION_ACK").type == ACCEPTED
    got = rig.download()
    assert len(got) == 12 and same(got[9:], [new[9], new[0], new[1]])
    # On an empty list a partial write from 0 starts a new one.
    assert rig.upload([]) == ACCEPTED
    rig.send("mission_write_partial_list", 1, 1, 0, 1, 0)
    for seq in (0, 1):
        rig.send("mission_item_int", *rig.item_args(seq, new[seq]))
    assert rig.last("MISSION_ACK").type == ACCEPTED and same(rig.download(), new[:2])


def test_partial_read(rig):
    items = plan(40, tag=4)
    assert rig.upload(items) == ACCEPTED
    rig.take()
    rig.send("mission_request_partial_list", 1, 1, 5, 9, 0, run=100)
    got = rig.take("MISSION_ITEM_INT")
    assert [g.seq for g in got] == [5, 6, 7, 8, 9]
    assert all(g.param1 == 4.0 for g in got)
    rig.send("mission_request_partial_list", 1, 1, 7, 7, 0, run=50)  # start == end: one item
    assert [g.seq for g in rig.take("MISSION_ITEM_INT")] == [7]
    rig.send("mission_request_partial_list", 1, 1, 30, -1, 0, run=200)  # -1: to the end
    assert [g.seq for g in rig.take("MISSION_ITEM_INT")] == list(range(30, 40))
    rig.send("mission_request_partial_list", 1, 1, 45, -1, 0)
    assert rig.last("MISSION_ACK").type == INVALID_SEQUENCE


def test_partial_read_is_paced(tmp_path):
    r = Rig(tmp_path)
    assert r.upload(plan(100)) == ACCEPTED
    r.ep.links[0].bytes_per_s = 5760  # a 57600 baud radio: at most half of it for the list
    r.take()
    r.send("mission_request_partial_list", 1, 1, 0, -1, 0, run=1)
    r.run(1000)
    n = len(r.take("MISSION_ITEM_INT"))
    assert 40 <= n <= 70  # ~58 a second at 50 bytes a frame
    r.run(2000)
    assert n + len(r.take("MISSION_ITEM_INT")) == 100


def test_rerequests_from_the_round_trip_then_cancel(rig):
    """Missing items are asked again once the measured round trip (here a few ms: the
    floor, 20 ms) has passed, then at doubling intervals; the upload is cancelled only
    after 5 s without a new item."""
    old = plan(3, tag=1)
    assert rig.upload(old) == ACCEPTED
    rig.take()
    rig.send("mission_count", 1, 1, 5, 0)
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [0, 1, 2, 3]
    rig.send("mission_item_int", *rig.item_args(0, plan(5)[0]))
    assert rig.take("MISSION_REQUEST_INT") == []
    rig.run(15)
    assert rig.take("MISSION_REQUEST_INT") == []
    rig.run(10)
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [1, 2, 3]  # after 20 ms
    gaps = []
    t = 25
    elapsed = 25  # since item 0 came
    while elapsed < 4950:
        rig.run(1)
        t += 1
        elapsed += 1
        if rig.take("MISSION_REQUEST_INT"):
            gaps.append(t)
            t = 0
    assert 35 <= gaps[0] <= 60 and gaps[1:5] == [80, 160, 320, 640], gaps  # backing off, 5 doublings at most
    assert set(gaps[5:]) == {640}
    assert rig.take("MISSION_ACK") == []
    rig.run(60)
    acks = rig.take("MISSION_ACK")
    assert [a.type for a in acks] == [OPERATION_CANCELLED]  # 5 s after the last item
    assert same(rig.download(), old)
    assert rig.upload(plan(5, tag=2)) == ACCEPTED  # idle again


def test_progress_keeps_an_upload_alive(tmp_path):
    """An upload that keeps making progress is never cancelled, however long it takes:
    an item every 4 s, with every request before it lost."""
    r = Rig(tmp_path)
    items = plan(6, tag=4)
    r.send("mission_count", 1, 1, 6, 0)
    for seq in range(6):
        r.run(4000)
        assert r.take("MISSION_ACK") == []
        r.send("mission_item_int", *r.item_args(seq, items[seq]))
    assert r.last("MISSION_ACK").type == ACCEPTED and same(r.download(), items)


def test_cancel_is_error_for_mavlink1(rig):
    rig.send("mission_count", 1, 1, 5, 0, v1=True)
    rig.take()
    rig.run(5100)
    assert [a.type for a in rig.take("MISSION_ACK")] == [ERROR]


def test_silence_timeout(tmp_path):
    """5 s of silence from the ground station ends the upload, however often it is asked."""
    r = Rig(tmp_path, options={"mission_retries": "100", "mission_retry_ms": "100"})
    r.send("mission_count", 1, 1, 5, 0)
    r.take()
    r.run(4900)
    assert r.take("MISSION_ACK") == []
    r.run(300)
    assert [a.type for a in r.take("MISSION_ACK")] == [OPERATION_CANCELLED]


def test_ground_station_cancels(rig):
    old = plan(2)
    assert rig.upload(old) == ACCEPTED
    rig.send("mission_count", 1, 1, 5, 0)
    rig.send("mission_ack", 1, 1, OPERATION_CANCELLED, 0)
    rig.take()
    rig.run(2000)
    assert rig.take(["MISSION_REQUEST_INT", "MISSION_ACK"]) == []  # nothing more asked
    assert same(rig.download(), old)


def test_out_of_sequence_items(rig):
    """Items come in any order; one not asked for is ignored; a missing item is asked
    again at once when three items asked after it came without it."""
    items = plan(10)
    rig.send("mission_count", 1, 1, 10, 0)
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == list(range(8))
    rig.send("mission_item_int", *rig.item_args(9, items[9]))  # not asked for (the last): ignored
    for seq in (2, 1):
        rig.send("mission_item_int", *rig.item_args(seq, items[seq]))
    assert rig.take("MISSION_REQUEST_INT") == []
    rig.send("mission_item_int", *rig.item_args(1, items[1]))  # a copy: ignored
    rig.send("mission_item_int", *rig.item_args(3, items[3]))
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [0]  # 0 or its request was lost
    rig.send("mission_item_int", *rig.item_args(0, items[0]))
    # 0..3 in: the window moves on; 1 too, the probe for a peer that serves requests
    # only in order (it would stand after 0, resent, and refuse 8).
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [8, 1]
    for seq in (4, 5, 6, 7, 8):
        rig.send("mission_item_int", *rig.item_args(seq, items[seq]))
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [9]  # the last, once all else is in
    rig.send("mission_item_int", *rig.item_args(9, items[9]))
    assert rig.last("MISSION_ACK").type == ACCEPTED
    assert same(rig.download(), items)


def test_repeated_count_restarts_at_seq_0(rig):
    rig.send("mission_count", 1, 1, 5, 0)
    rig.send("mission_count", 1, 1, 5, 0)  # our requests were lost: ask again
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [0, 1, 2, 3] * 2
    rig.send("mission_item_int", *rig.item_args(0, waypoint(0)))
    rig.take()
    rig.send("mission_count", 1, 1, 5, 0)  # a late copy once items flow: ignored
    assert rig.take("MISSION_REQUEST_INT") == []
    rig.send("mission_count", 1, 1, 3, 0)  # a different count: a new upload
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [0, 1]
    items = plan(3)
    for seq in range(3):
        rig.send("mission_item_int", *rig.item_args(seq, items[seq]))
    assert rig.last("MISSION_ACK").type == ACCEPTED and same(rig.download(), items)


def test_repeated_last_item_is_acked_again(rig):
    items = plan(4)
    assert rig.upload(items) == ACCEPTED
    rig.take()
    rig.send("mission_item_int", *rig.item_args(3, items[3]))  # our ACK was lost
    assert [a.type for a in rig.take("MISSION_ACK")] == [ACCEPTED]
    rig.send("mission_item_int", *rig.item_args(3, items[3]), sysid=200)  # not from the uploader
    assert rig.take("MISSION_ACK") == []


def test_one_transfer_at_a_time(rig):
    """A second ground station (another system id on the same link) is denied while the
    first one's transfer runs, and that transfer goes on undisturbed."""
    old = plan(3, tag=1)
    assert rig.upload(old) == ACCEPTED
    mine = plan(4, tag=2)
    rig.send("mission_count", 1, 1, 4, 0)
    rig.send("mission_item_int", *rig.item_args(0, mine[0]))
    rig.take()
    for start in (("mission_count", 1, 1, 2, 0), ("mission_request_list", 1, 1, 0),
                  ("mission_clear_all", 1, 1, 0), ("mission_write_partial_list", 1, 1, 0, 0, 0),
                  ("mission_request_int", 1, 1, 0, 0)):
        rig.send(*start, sysid=200)
        acks = rig.take("MISSION_ACK")
        assert [(a.type, a.target_system) for a in acks] == [(DENIED, 200)], start
    assert rig.take("MISSION_REQUEST_INT") == []
    for seq in range(1, 4):
        rig.send("mission_item_int", *rig.item_args(seq, mine[seq]))
    assert rig.last("MISSION_ACK").type == ACCEPTED
    assert same(rig.download(sysid=200), mine)  # idle again: anyone may read


def test_downloads_go_side_by_side(rig):
    """A download holds no lock against other readers: a second ground station's list
    and items are answered beside it, and the first one's goes on."""
    items = plan(3)
    assert rig.upload(items) == ACCEPTED
    rig.send("mission_request_list", 1, 1, 0)
    rig.send("mission_request_int", 1, 1, 0, 0)
    rig.take()
    assert same(rig.download(sysid=200), items)
    rig.send("mission_request_int", 1, 1, 1, 0)
    rig.send("mission_request_int", 1, 1, 2, 0)  # the last one: done, no ACK needed
    assert [i.seq for i in rig.take("MISSION_ITEM_INT")] == [1, 2]
    assert rig.take("MISSION_ACK") == []
    assert rig.missions.transfer.state == 0


def _acks_to(rig, sysid):
    return [a.type for a in rig.take("MISSION_ACK") if a.target_system == sysid]


def test_upload_takes_over_a_download(rig):
    """Without operator control anyone may change the plan: an upload takes over from
    another ground station's download, which is told OPERATION_CANCELLED."""
    assert rig.upload(plan(4, tag=1)) == ACCEPTED
    rig.send("mission_request_list", 1, 1, 0, sysid=200)
    rig.send("mission_request_int", 1, 1, 0, 0, sysid=200)
    rig.take()
    new = plan(6, tag=2)
    assert rig.upload(new) == ACCEPTED
    assert same(rig.download(sysid=200), new)


def test_cancelled_download_is_told(rig):
    assert rig.upload(plan(4, tag=1)) == ACCEPTED
    rig.send("mission_request_list", 1, 1, 0, sysid=200)
    rig.take()
    rig.send("mission_count", 1, 1, 2, 0)
    assert _acks_to(rig, 200) == [OPERATION_CANCELLED]
    assert [r.seq for r in rig.take("MISSION_REQUEST_INT")] == [0]


def _passkey_rig(tmp_path):
    r = Rig(tmp_path, services=("status", "commands", "missions"), options={"operator_passkey": "pw"})
    r.send("change_operator_control", 1, 0, 0, b"pw")  # 255 takes control
    return r


def _spam_list(r, sysid=200):
    r.send("mission_request_list", 1, 1, 0, sysid=sysid, run=0)


def test_list_spam_cannot_stop_the_uploads_of_the_ground_station_in_control(tmp_path):
    """Operator control on: a ground station not in control re-sending MISSION_REQUEST_LIST
    before and all through the uploads of the one in control stops none of them."""
    r = _passkey_rig(tmp_path)
    for k in range(5):
        items = plan(12, tag=k + 1)
        _spam_list(r)
        r.run(2)
        r.take()
        r.send("mission_count", 1, 1, len(items), 0)
        result = None
        for _ in range(60):
            _spam_list(r)
            got = r.take(["MISSION_REQUEST_INT", "MISSION_ACK"])
            acks = [g.type for g in got if g.get_type() == "MISSION_ACK" and g.target_system == 255]
            if acks:
                result = acks[-1]
                break
            for req in got:
                if req.get_type() == "MISSION_REQUEST_INT":
                    r.send("mission_item_int", *r.item_args(req.seq, items[req.seq]), run=0)
            r.run(2)
        assert result == ACCEPTED, k
        assert same(r.download(), items)


def test_list_spam_cannot_block_an_upload_without_operator_control(rig):
    """No passkey: a ground station's repeated MISSION_REQUEST_LIST, with an item asked
    each time, holds nothing against another's upload."""
    old = plan(3, tag=1)
    assert rig.upload(old) == ACCEPTED
    for _ in range(5):
        rig.send("mission_request_list", 1, 1, 0, sysid=200)
        rig.send("mission_request_int", 1, 1, 0, 0, sysid=200)
    new = plan(9, tag=2)
    assert rig.upload(new) == ACCEPTED
    assert same(rig.download(), new)


def test_stale_download_is_cancelled(rig):
    """A download whose ground station stops asking (or only starts over) is cancelled
    after 5 s without a new item served, and told so; meanwhile others read beside it."""
    items = plan(4, tag=3)
    assert rig.upload(items) == ACCEPTED
    rig.send("mission_request_list", 1, 1, 0, sysid=200)
    rig.send("mission_request_int", 1, 1, 0, 0, sysid=200)
    rig.take()
    for _ in range(9):  # starting over is no progress
        rig.run(500)
        rig.send("mission_request_list", 1, 1, 0, sysid=200)
        rig.send("mission_request_int", 1, 1, 0, 0, sysid=200)
        assert _acks_to(rig, 200) == []
    rig.run(600)
    assert _acks_to(rig, 200) == [OPERATION_CANCELLED]
    assert rig.missions.transfer.state == 0
    assert same(rig.download(sysid=201), items)


def test_stalled_upload_gives_way(tmp_path):
    """No passkey: an upload that has had no new item since it (re)started does not
    block another ground station's upload; one that moves does."""
    r = Rig(tmp_path)
    other = plan(5, tag=1)
    for k in range(4):  # 200 keeps starting over (a new count each time), and re-sends item 0
        r.send("mission_count", 1, 1, 4 + k % 2, 0, sysid=200)
        r.send("mission_item_int", *r.item_args(0, other[0]), sysid=200)
    r.take()
    mine = plan(7, tag=2)
    assert r.upload(mine) == ACCEPTED
    assert same(r.download(), mine)
    # While 255's upload moves, 200's is refused.
    r.send("mission_count", 1, 1, 7, 0)
    r.send("mission_item_int", *r.item_args(0, mine[0]))
    r.take()
    r.send("mission_count", 1, 1, 5, 0, sysid=200)
    assert _acks_to(r, 200) == [DENIED]


def test_operator_control(tmp_path):
    r = Rig(tmp_path, services=("status", "commands", "missions"), options={"operator_passkey": "pw"})
    old = plan(2)
    r.take()
    r.send("mission_count", 1, 1, 2, 0)
    assert r.last("MISSION_ACK").type == DENIED
    r.send("mission_clear_all", 1, 1, 0)
    assert r.last("MISSION_ACK").type == DENIED
    r.send("mission_write_partial_list", 1, 1, 0, 0, 0)
    assert r.last("MISSION_ACK").type == DENIED
    assert r.download() == []  # reading needs no control
    r.send("change_operator_control", 1, 0, 0, b"pw")
    assert r.upload(old) == ACCEPTED
    assert r.upload(plan(1), sysid=200) is not ACCEPTED


def test_set_current_and_commands(tmp_path):
    r = Rig(tmp_path)
    assert r.upload(plan(6)) == ACCEPTED
    r.take()
    r.send("mission_set_current", 1, 1, 4)
    assert r.last("MISSION_CURRENT").seq == 4
    r.send("mission_set_current", 1, 1, 9)  # no such item: unchanged
    assert r.last("MISSION_CURRENT").seq == 4
    r.send("command_long", 1, 1, 224, 0, 2, 0, 0, 0, 0, 0, 0)  # MAV_CMD_DO_SET_MISSION_CURRENT
    assert r.last("COMMAND_ACK").result == 0 and r.last("MISSION_CURRENT").seq == 2
    r.send("command_long", 1, 1, 224, 0, 6, 0, 0, 0, 0, 0, 0)
    assert r.last("COMMAND_ACK").result == 4  # MAV_RESULT_FAILED
    r.send("command_long", 1, 1, 300, 0, 1, 3, 0, 0, 0, 0, 0)  # MAV_CMD_MISSION_START 1..3
    assert r.last("COMMAND_ACK").result == 0
    cur = r.last("MISSION_CURRENT")
    assert (cur.seq, cur.mission_state) == (1, 3)  # ACTIVE
    # The downloaded item flagged current is the one in force.
    assert [i.current for i in r.download()] == [0, 1, 0, 0, 0, 0]


def test_seed_dialect(tmp_path):
    """On the seed's dialect (no MISSION_ITEM_INT, no extension fields) the same
    service runs the seed's protocol: MISSION_REQUEST / MISSION_ITEM."""
    from mavstack.dialects import seed2012

    r = Rig(tmp_path, dialect=seed2012)
    m = r.missions
    assert not m.has_int and not m.has_type and not r.ep.capabilities & 4
    items = plan(5, tag=2, form="float")
    assert r.upload(items, v1=True, as_int=False) == ACCEPTED
    assert same(r.download(v1=True, as_int=False), items)


def test_plan_ids_where_the_dialect_has_them(tmp_path):
    """Today's common.xml adds opaque_id to MISSION_COUNT and MISSION_ACK and plan ids to
    MISSION_CURRENT; the pymavlink release pinned here predates them. With a dialect
    that has them, the vehicle fills them in."""
    from mavstack.dialects import common
    from mavstack.dialects.table import InfoTable

    sys.path.insert(0, os.path.join(ROOT, "host_tools"))
    import mavgen

    crc_len = dict(common.CRC_LEN.items())
    fmt = dict(common.FMT)
    for msgid, n, f in ((44, 9, "<HBBBI"), (47, 8, "<BBBBI"), (42, 18, "<HHBBIII")):
        crc_len[msgid] = crc_len[msgid] & 0xFFFF | n << 16
        fmt[msgid] = f
    dialect = types.SimpleNamespace(CRC_LEN=InfoTable(mavgen.info_block(crc_len)), FMT=fmt)
    r = Rig(tmp_path, dialect=dialect)
    seen = []
    r.b.watch = lambda msgid, p: seen.append((msgid, bytes(p[:20])))
    r.send("mission_count", 1, 1, 1, 0)
    item = waypoint(0)
    r.send("mission_item_int", *r.item_args(0, item))
    store = r.missions.stores[0]
    plan_id = store.plan_id
    ack = [p for i, p in seen if i == 47][-1]
    assert ack[2] == ACCEPTED and struct.unpack_from("<I", ack, 4)[0] == plan_id != 0
    r.send("mission_request_list", 1, 1, 0)
    count = [p for i, p in seen if i == 44][-1]
    assert struct.unpack_from("<HBBBI", count) == (1, 255, 190, 0, plan_id)
    r.run(1000)
    cur = [p for i, p in seen if i == 42][-1]
    ids = struct.unpack_from("<III", cur, 6)
    assert ids == (plan_id, r.missions.stores[1].plan_id, r.missions.stores[2].plan_id)
    # A new plan, a new id.
    r.send("mission_count", 1, 1, 1, 0)
    r.send("mission_item_int", *r.item_args(0, item))
    assert store.plan_id != plan_id


def test_storage_survives_a_restart(tmp_path):
    r = Rig(tmp_path)
    items = plan(7, tag=5)
    assert r.upload(items) == ACCEPTED
    fence = [Item(5, 5003, 0, 1, 30.0, 0, 0, 0, 473977420, 85455940, 0.0)]
    assert r.upload(fence, mission_type=1) == ACCEPTED
    for s in r.missions.stores:
        s.close()
    r2 = Rig(tmp_path)
    assert same(r2.download(), items) and same(r2.download(mission_type=1), fence)
    assert r2.download(mission_type=2) == []


# --- ground stations as they answer requests ----------------------------------------
class Peer:
    """A ground station's side of an upload on the rig, one poll (1 ms) at a time: it
    answers each request after `delay` ms, skips sending the items in `lose` (once
    each), and serves requests by its own rules:
    "any"     every request (QGroundControl, pymavlink's mavwp and mission_gcs);
    "inorder" MAVSDK's: a request ahead of the item after the last one it sent is
              ignored, an earlier one moves it back there;
    "mavproxy" MAVProxy's: once it has sent the last item it answers no more."""

    def __init__(self, rig, items, rule="any", delay=2, lose=(), per=0):
        self.r = rig
        self.per = per  # ms an item takes on the air: answers queue one behind another
        self.free = 0
        self.items = items
        self.rule = rule
        self.delay = delay
        self.lose = set(lose)
        self.next = 0
        self.done = False
        self.queue = []  # (due ms, seq)
        self.asked = []  # (ms, seq) of every request seen
        self.sent = []
        self.t = 0

    def run(self, ms_max=20000):
        self.r.take()
        self.r.send("mission_count", 1, 1, len(self.items), 0, run=0)
        while self.t < ms_max:
            self.r.run(1)
            self.t += 1
            for g in self.r.take(["MISSION_REQUEST_INT", "MISSION_ACK"]):
                if g.get_type() == "MISSION_ACK":
                    return g.type
                self.asked.append((self.t, g.seq))
                self.free = max(self.free, self.t + self.delay) + self.per
                self.queue.append((self.free, g.seq))
            while self.queue and self.queue[0][0] <= self.t:
                self.answer(self.queue.pop(0)[1])
        return None

    def answer(self, seq):
        if self.rule == "inorder":
            if seq > self.next:
                return
            self.next = seq + 1
        elif self.rule == "mavproxy":
            if self.done:
                return
            self.done = seq == len(self.items) - 1
        if seq in self.lose:
            self.lose.discard(seq)
            return
        self.sent.append(seq)
        self.r.send("mission_item_int", *self.r.item_args(seq, self.items[seq]), run=0)


@pytest.mark.parametrize("rule", ["any", "inorder", "mavproxy"])
def test_ground_stations_rules_with_lost_items(rig, rule):
    """Whatever rule a ground station serves requests by, lost items (the first, one in
    the middle, two in a row, the one before the last) end in an ACCEPTED upload; a
    MAVSDK-like one has sent the last item last (it checks that on the ACK)."""
    items = plan(40, tag=5)
    peer = Peer(rig, items, rule, delay=3, lose=(0, 17, 25, 26, 38))
    assert peer.run() == ACCEPTED, (peer.asked, peer.sent)
    assert same(rig.download(), items)
    assert peer.sent[-1] == 39
    if rule == "inorder":
        assert peer.next == 40


def test_requests_fly_ahead(rig):
    """A window of 8 requests is kept full: 40 items over a 30 ms round trip take about
    40 / 8 round trips, not 40."""
    items = plan(40, tag=6)
    peer = Peer(rig, items, delay=30)
    assert peer.run() == ACCEPTED
    assert peer.t < 300, peer.t
    assert sorted(s for _, s in peer.asked) == list(range(40))  # nothing asked twice


def test_rerequest_follows_the_round_trip(rig):
    """With a 100 ms round trip nothing is asked twice without cause (the item after
    the lost one is, once, to learn whether the peer serves in order); a lost item is
    asked again once the round trip (and its deviation) has passed, not 250 ms later."""
    items = plan(30, tag=7)
    peer = Peer(rig, items, delay=100, lose=(20,))
    assert peer.run() == ACCEPTED
    times = [t for t, s in peer.asked if s == 20]
    assert len(times) == 2
    assert 100 <= times[1] - times[0] <= 200, times
    assert len(peer.asked) == 32  # item 20 twice, 21 once more (the probe), the others once


def test_items_queued_on_a_slow_link_are_late_not_lost(tmp_path):
    """On a radio an item takes its air time (9 ms at 57600 baud), so the items asked
    together come one behind another and the last of a window of 16 comes ~150 ms after
    its request, far beyond the round trip the first one measured. None of them is
    asked again: the timer runs from when an item became the first missing one."""
    r = Rig(tmp_path, options={"mission_window": "16"})
    items = plan(100, tag=8)
    peer = Peer(r, items, delay=3, per=9)
    assert peer.run() == ACCEPTED
    assert sorted(s for _, s in peer.asked) == list(range(100))
    assert peer.t < 100 * 9 + 100


def test_an_inorder_peer_is_found_in_one_round_trip(rig):
    """A MAVSDK-like station that resends a lost item stands after it, and refuses the
    window asked past it. The vehicle asks for the item after the resent one at once as
    well, and when that alone comes back walks the peer forward: no item waits for the
    timer (MAVSDK gives up after half a second of refused requests)."""
    items = plan(40, tag=9)
    peer = Peer(rig, items, "inorder", delay=3, lose=(17,))
    assert peer.run() == ACCEPTED
    assert same(rig.download(), items)
    resent = [t for t, s in peer.asked if s == 17][1]
    walked = [t for t, s in peer.asked if s == 18 and t > resent]
    assert walked and walked[0] - resent <= 10, (peer.asked, peer.sent)
    assert peer.t < 150, peer.t


def test_a_peer_that_serves_any_request_is_probed_once(rig):
    """A station that answers the window past a resent item is not one that serves in
    order: after the first probe, lost items cost no more requests than themselves."""
    items = plan(60, tag=10)
    peer = Peer(rig, items, "any", delay=3, lose=(10, 30, 50))
    assert peer.run() == ACCEPTED
    assert same(rig.download(), items)
    assert len(peer.asked) == 60 + 3 + 1, peer.asked
