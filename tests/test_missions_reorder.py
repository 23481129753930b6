"""Frames held back across transfers: MISSION_ITEM(_INT) names no upload, so a copy of an
earlier upload's item (or MISSION_COUNT) that a link held back must not be taken into
the next upload. The vehicle tells them by the sender's packet sequence number
(parser.late_at, services/missions/upload.py). These tests send such frames by hand, then run
the fault test's lossy link (lossy_world.py) on a simulated clock for many rounds,
where an accepted upload must be stored exactly, and any other outcome leave the old
plan or the new."""
import pytest

from lossy_world import World, items_for, outcome_holds, plan_in_force, same_items
from mission_rig import Rig

ACCEPTED = 0


def frame(rig, name, *args, seq):
    mav = rig.mav(255, 190)
    mav.seq = seq & 0xFF
    return bytearray(getattr(mav, name + "_encode")(*args).pack(mav))


def item_frame(rig, seq, item, pseq):
    f, command, p1, p2, p3, p4, x, y, z = item
    return frame(rig, "mission_item_int", 1, 1, seq, f, command, 0, 1, p1, p2, p3, p4, x, y, z, 0, seq=pseq)


def upload(rig, items, pseq, meanwhile=()):
    """MISSION_COUNT numbered pseq, then the frames a link held back (meanwhile), then the
    vehicle's requests answered with fresh frames numbered on from pseq -> the
    MISSION_ACK type (None: none came)."""
    rig.b.send_raw(frame(rig, "mission_count", 1, 1, len(items), 0, seq=pseq))
    rig.run(2)
    for late in meanwhile:  # arrive in this upload, which has asked for their items
        rig.b.send_raw(late)
        rig.run(2)
    for _ in range(1000):
        rig.run(5)
        got = rig.take(["MISSION_REQUEST_INT", "MISSION_ACK"])
        for m in got:
            if m.get_type() == "MISSION_ACK":
                return m.type
        for m in got:
            pseq += 1
            rig.b.send_raw(item_frame(rig, m.seq, items[m.seq], pseq))
    return None


def test_an_item_sent_before_the_upload_began_is_not_taken(tmp_path):
    rig = Rig(tmp_path)
    old, new = items_for(101, 4), items_for(201, 4)
    assert upload(rig, old, 10) == ACCEPTED
    late = item_frame(rig, 2, old[2], 14)  # a copy of the old item 2 the link held back
    assert upload(rig, new, 40, [late]) == ACCEPTED
    assert same_items(plan_in_force(rig), new)


def test_a_count_sent_before_the_upload_began_does_not_restart_it(tmp_path):
    rig = Rig(tmp_path)
    new = items_for(301, 6)
    stale_count = frame(rig, "mission_count", 1, 1, 3, 0, seq=200)
    assert upload(rig, new, 210, [stale_count]) == ACCEPTED
    assert same_items(plan_in_force(rig), new)  # all six: not cut to the stale count's three


def test_a_ground_station_started_again_uploads_at_once(tmp_path):
    # mavctl is a new process each run: its numbers start again from 0, below the last
    # ones the vehicle had from the same sysid and compid. Its frames read as late, but
    # none was sent before its own upload began.
    rig = Rig(tmp_path)
    first, second = items_for(11, 5), items_for(21, 4)
    assert upload(rig, first, 40) == ACCEPTED
    assert upload(rig, second, 2) == ACCEPTED
    assert same_items(plan_in_force(rig), second)


def test_packet_numbers_wrap_in_a_long_upload(tmp_path):
    # 400 items: the ground station's 8-bit numbers wrap once and a half.
    rig = Rig(tmp_path)
    items = items_for(7, 400)
    assert upload(rig, items, 250) == ACCEPTED
    assert same_items(plan_in_force(rig), items)


def test_a_ground_station_with_one_fixed_packet_number_still_uploads(tmp_path):
    rig = Rig(tmp_path)  # the rig's own upload numbers every frame 0
    items = items_for(9, 12)
    from mission_gcs import Item
    as_items = [Item(f, c, 0, 1, p1, p2, p3, p4, x, y, z) for f, c, p1, p2, p3, p4, x, y, z in items]
    assert rig.upload(as_items) == ACCEPTED
    assert same_items(plan_in_force(rig), items)


@pytest.mark.parametrize("seed", range(12))
def test_uploads_through_a_reordering_link_never_mix(tmp_path, seed):
    # Items to the vehicle held back up to 1.5 s, longer than the ground station waits
    # for late answers before an upload (fault_gcs: 0.3 s): without the vehicle's check
    # some of these seeds store a mix and say ACCEPTED.
    w = World(tmp_path, seed=seed, rate=0.3, stall=0.001, hold_ms=1500)
    old = w.stored()
    outcomes = []
    for round_ in range(30):
        new = items_for(100 * round_ + 1, 3 + 2 * (round_ % 5))
        outcome = w.gcs.upload(new)
        for _ in range(w.rng.choice((0, 300, 6000))):  # another station reads, or not
            w.step()
        now = w.stored()
        outcomes.append(outcome)
        assert outcome_holds(outcome, now, new, old), (round_, outcome, now)
        got = w.gcs.download()
        if outcome == "unsure":  # a stalled vehicle may finish the upload late: new, then
            now = w.stored()
            assert outcome_holds(outcome, now, new, old), (round_, outcome, now)
        if got is not None:
            assert same_items(got, now), (round_, got)
        old = now
    assert outcomes.count("accepted") > 15, outcomes
