"""Missions end to end over UDP: pymavlink ground stations against the unix vehicle
(micropython firmware/main.py --board unix). Round trips of 1, 100 and 500 items in both
item forms, clear, partial transfers, the current item, fence and rally, two ground
stations (and one in control while another floods list requests), a ground station
that goes silent, and 50 uploads and downloads through a relay that drops, duplicates
and reorders frames."""
import concurrent.futures
import time

import pytest

from conftest import free_udp_port, recv
from mission_gcs import Item, MissionClient, mavlink1, plan, same
from relay import LossyRelay

ACCEPTED, UNSUPPORTED, DENIED, OPERATION_CANCELLED = 0, 3, 14, 15


@pytest.fixture(scope="module")
def shared(tmp_path_factory):
    """One vehicle for the round trips (each test leaves a plan of its own making), with
    a link for a MAVLink 2 ground station and one for a MAVLink 1 ground station."""
    from conftest import Vehicle

    ports = free_udp_port(), free_udp_port()
    v = Vehicle(storage=tmp_path_factory.mktemp("missions") / "st",
                links=["udpin:127.0.0.1:%d" % p for p in ports]).start()
    v.ports = ports
    yield v
    v.stop()


@pytest.fixture(scope="module")
def gcs2(shared):
    return MissionClient(shared.gcs(version=2, port=shared.ports[0]))


@pytest.fixture(scope="module")
def gcs1(shared):
    return MissionClient(mavlink1(shared.gcs(version=1, port=shared.ports[1])), form="float")


@pytest.mark.parametrize("n", [1, 100, 500])
def test_round_trip_int(gcs2, n):
    items = plan(n, tag=n)
    assert gcs2.upload(items) == ACCEPTED
    assert same(gcs2.download(), items)


@pytest.mark.parametrize("n", [1, 100, 500])
def test_round_trip_seed_form_mavlink1(gcs1, gcs2, n):
    """A MAVLink 1 ground station of the seed's era: MISSION_COUNT, MISSION_REQUEST,
    MISSION_ITEM with float degrees, no extension fields."""
    items = plan(n, tag=n + 1, form="float")
    assert gcs1.upload(items) == ACCEPTED
    got = gcs1.download()
    assert same(got, items)
    assert all(isinstance(i.x, float) for i in got)
    # The same plan read as MISSION_ITEM_INT: the degrees * 1e7, rounded.
    ints = gcs2.download()
    assert [(i.x, i.y) for i in ints] == [(round(i.x * 1e7), round(i.y * 1e7)) for i in items]


def test_clear(gcs2):
    assert gcs2.upload(plan(5)) == ACCEPTED
    assert gcs2.clear() == ACCEPTED
    assert gcs2.download() == []
    assert gcs2.upload(plan(3)) == ACCEPTED
    assert gcs2.upload([]) == ACCEPTED  # count 0 clears too
    assert gcs2.download() == []


def test_partial_write_and_read(gcs2):
    items = plan(20, tag=1)
    assert gcs2.upload(items) == ACCEPTED
    new = plan(20, tag=2)
    assert gcs2.upload(new[5:8], start=5, end=7) == ACCEPTED
    assert same(gcs2.download(), items[:5] + new[5:8] + items[8:])
    assert gcs2.upload(new[:1], start=25, end=25) == 13  # beyond the list: INVALID_SEQUENCE
    m = gcs2.m
    m.mav.mission_request_partial_list_send(1, 1, 10, 13, 0)
    got = [recv(m, "MISSION_ITEM_INT", 5) for _ in range(4)]
    assert [g.seq for g in got] == [10, 11, 12, 13]


def test_set_current(gcs2):
    assert gcs2.upload(plan(8)) == ACCEPTED
    m = gcs2.m
    m.mav.mission_set_current_send(1, 1, 5)
    assert recv(m, "MISSION_CURRENT", 5, lambda c: c.seq == 5) is not None
    m.mav.command_long_send(1, 1, 224, 0, 2, 0, 0, 0, 0, 0, 0)  # MAV_CMD_DO_SET_MISSION_CURRENT
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 224).result == 0
    cur = recv(m, "MISSION_CURRENT", 5, lambda c: c.seq == 2)
    assert cur is not None and cur.total == 8
    # and once a second without a change
    t = time.time()
    assert recv(m, "MISSION_CURRENT", 3) is not None and recv(m, "MISSION_CURRENT", 3) is not None
    assert time.time() - t < 2.5


def test_fence_and_rally(gcs2):
    fence = [Item(5, 5001, 0, 1, 4.0, 0, 0, 0, 473977420 + a, 85455940 + b, 0.0)
             for a, b in ((0, 0), (2000, 0), (2000, 2000), (0, 2000))]
    rally = [Item(6, 5100, 0, 1, 0, 0, 0, 0, 473987420, 85455940, 30.0)]
    mission = plan(4, tag=9)
    assert gcs2.upload(mission) == ACCEPTED
    assert gcs2.upload(fence, mission_type=1) == ACCEPTED
    assert gcs2.upload(rally, mission_type=2) == ACCEPTED
    assert same(gcs2.download(mission_type=1), fence)
    assert same(gcs2.download(mission_type=2), rally)
    assert same(gcs2.download(), mission)
    assert gcs2.clear(mission_type=1) == ACCEPTED
    assert gcs2.download(mission_type=1) == [] and same(gcs2.download(mission_type=2), rally)


def test_capabilities(gcs2):
    m = gcs2.m
    m.mav.command_long_send(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0)  # REQUEST_MESSAGE AUTOPILOT_VERSION
    av = recv(m, "AUTOPILOT_VERSION", 5)
    assert av is not None
    for bit in (4, 16384, 32768):  # MISSION_INT, MISSION_FENCE, MISSION_RALLY
        assert av.capabilities & bit


def test_two_ground_stations(vehicle):
    """Two ground stations on two links: the second is denied while the first uploads,
    and the first's upload completes undisturbed."""
    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2])
    a = v.gcs(port=p1)
    b = v.gcs(port=p2, source_system=254)
    first = plan(30, tag=1)
    a.mav.mission_count_send(1, 1, 30, 0)
    for seq in range(10):
        req = recv(a, "MISSION_REQUEST_INT", 5, lambda r: r.seq == seq)
        assert req is not None
        MissionClient(a).send_item(seq, first[seq])
    b.mav.mission_count_send(1, 1, 5, 0)
    assert recv(b, "MISSION_ACK", 5).type == DENIED
    b.mav.mission_request_list_send(1, 1, 0)
    assert recv(b, "MISSION_ACK", 5).type == DENIED
    b.mav.mission_clear_all_send(1, 1, 0)
    assert recv(b, "MISSION_ACK", 5).type == DENIED
    ca = MissionClient(a)
    for seq in range(10, 30):
        req = recv(a, "MISSION_REQUEST_INT", 5, lambda r: r.seq == seq)
        assert req is not None, seq
        ca.send_item(seq, first[seq])
    assert recv(a, "MISSION_ACK", 5).type == ACCEPTED
    assert same(MissionClient(b).download(), first)


def test_ground_station_goes_silent(vehicle):
    v = vehicle()
    m = v.gcs()
    c = MissionClient(m)
    old = plan(10, tag=1)
    assert c.upload(old) == ACCEPTED
    new = plan(10, tag=2)
    m.mav.mission_count_send(1, 1, 10, 0)
    for seq in range(4):
        assert recv(m, "MISSION_REQUEST_INT", 5, lambda r: r.seq == seq) is not None
        c.send_item(seq, new[seq])
    t = time.time()
    ack = recv(m, "MISSION_ACK", 8)  # asked again and again, backing off; 5 s after the last item it gives up
    assert ack is not None and ack.type == OPERATION_CANCELLED
    assert 4.5 < time.time() - t < 6.5
    assert same(c.download(), old)
    assert c.upload(new) == ACCEPTED and same(c.download(), new)


def _lossy_session(v, relay_port, rounds, tag0):
    m = v.gcs(port=relay_port)
    c = MissionClient(m, timeout=0.012, retries=12)
    stored = None
    out = {"uploads": 0, "failed_uploads": 0, "downloads": 0, "failed_downloads": 0}
    try:
        for r in range(rounds):
            items = plan(100, tag=tag0 + r)
            result = c.upload(items)
            c.drain(0.01)
            got = c.download()
            c.drain(0.01)
            out["uploads" if result == ACCEPTED else "failed_uploads"] += 1
            if got is None:
                out["failed_downloads"] += 1
                continue
            out["downloads"] += 1
            if result == ACCEPTED:
                assert same(got, items), r
            elif result is None:  # no answer at all: either plan, never a mix
                assert same(got, items) or (stored is not None and same(got, stored)), r
            else:  # refused: the old plan is intact
                assert (stored is not None and same(got, stored)) or (stored is None and got == []), r
            stored = got
    finally:
        m.close()
    return out


def test_lossy_link(vehicle, tmp_path):
    """50 uploads and downloads of 100 items through real UDP relays that disturb 20% of
    the frames both ways (dropped, duplicated or held back a few ms, so reordered). Every
    upload ends with the new plan stored, or cleanly refused with the old one intact.
    Two vehicles run side by side to keep the test short."""
    fast = ["--set", "mission_retry_ms=8", "--set", "mission_rto_min_ms=8", "--set", "mission_rto_max_ms=60"]
    sessions = []
    for k in range(2):
        v = vehicle(args=fast, storage=tmp_path / ("st%d" % k))
        relay = LossyRelay(v.port, rate=0.2, seed=k + 1)
        sessions.append((v, relay))
    try:
        with concurrent.futures.ThreadPoolExecutor(2) as pool:
            futures = [pool.submit(_lossy_session, v, relay.port, 25, 1000 * k)
                       for k, (v, relay) in enumerate(sessions)]
            results = [f.result() for f in futures]
    finally:
        for _, relay in sessions:
            relay.close()
    total = {key: sum(r[key] for r in results) for key in results[0]}
    stats = {key: sum(relay.stats[key] for _, relay in sessions) for key in sessions[0][1].stats}
    assert total["uploads"] + total["failed_uploads"] == 50
    assert total["downloads"] + total["failed_downloads"] == 50
    assert stats["dropped"] > 100 and stats["duplicated"] > 100 and stats["delayed"] > 100, stats
    # Clean failures are allowed; a protocol that cannot cope shows as many of them.
    assert total["uploads"] >= 45 and total["downloads"] >= 45, (total, stats)


def test_list_spam_cannot_block_the_ground_station_in_control(vehicle):
    """Operator control on (a passkey): a ground station not in control re-sending
    MISSION_REQUEST_LIST every 20 ms on another link stops none of the uploads of the
    one in control, 5 of 5; its downloads are cancelled and told so."""
    import threading

    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2],
                args=["--set", "operator_passkey=pw"])
    a = v.gcs(port=p1)
    b = v.gcs(port=p2, source_system=254)
    a.mav.change_operator_control_send(1, 0, 0, b"pw")
    assert recv(a, "CHANGE_OPERATOR_CONTROL_ACK", 5).ack == 0
    c = MissionClient(a)
    assert c.upload(plan(50)) == ACCEPTED  # a plan stored: b's lists are downloads under way
    stop = threading.Event()
    listed = threading.Event()  # b's download is under way: the uploads must take it over
    told = []

    def spam():
        while not stop.is_set():
            b.mav.mission_request_list_send(1, 1, 0)
            msg = b.recv_match(type=["MISSION_ACK", "MISSION_COUNT"], blocking=True, timeout=0.02)
            if msg is not None and msg.target_system == 254:
                if msg.get_type() == "MISSION_ACK":
                    told.append(msg.type)
                elif msg.count:
                    listed.set()

    t = threading.Thread(target=spam, daemon=True)
    t.start()
    try:
        assert listed.wait(10)
        results = [c.upload(plan(50, tag=k + 1)) for k in range(5)]
    finally:
        stop.set()
        t.join(2)
    assert results == [ACCEPTED] * 5
    assert same(c.download(), plan(50, tag=5))
    assert OPERATION_CANCELLED in told, told
