"""Real ground stations move missions to and from the unix vehicle: MAVProxy's `wp load`
and `wp list` with a QGC WPL 110 file, typed on its stdin; MAVSDK's MissionRaw upload
and download (mission, geofence, rally), and its uploads through a lossy relay. A
pymavlink ground station on a second link checks what the vehicle holds afterwards."""
import gcs_tools
from gcs_tools import MavProxy, mavsdk_system
from mission_gcs import MissionClient


# index current frame command p1 p2 p3 p4 x y z autocontinue
WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t47.3977420\t8.5455940\t488.000000\t1
1\t0\t3\t22\t0\t0\t0\t0\t0.0000000\t0.0000000\t20.000000\t1
2\t0\t3\t16\t0\t2\t0\t0\t47.3987420\t8.5455940\t20.000000\t1
3\t0\t3\t16\t1.5\t3\t0\t90\t47.3987420\t8.5475940\t30.000000\t1
4\t0\t2\t177\t2\t1\t0\t0\t0.0000000\t0.0000000\t0.000000\t1
5\t0\t2\t112\t4\t0\t0\t0\t0.0000000\t0.0000000\t0.000000\t1
6\t0\t3\t16\t0\t2\t0\t0\t47.3967420\t8.5445940\t25.000000\t1
7\t0\t3\t21\t0\t0\t0\t0\t47.3977420\t8.5455940\t0.000000\t1
"""


def _wpl_rows():
    rows = []
    for line in WPL.splitlines()[1:]:
        f = line.split("\t")
        rows.append((int(f[2]), int(f[3]), [float(v) for v in f[4:8]], float(f[8]), float(f[9]), float(f[10])))
    return rows


def two_links(vehicle):
    v, port, m = gcs_tools.two_links(vehicle)
    return v, port, MissionClient(m)


def test_mavproxy_wp_load_and_list(vehicle, tmp_path):
    v, port, check = two_links(vehicle)
    (tmp_path / "mission.txt").write_text(WPL)
    mp = MavProxy(port, tmp_path, "wp")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("wp load mission.txt")
        mp.expect(r"Loaded 8 waypoints? from mission.txt")
        mp.expect(r"Sent all 8 waypoints?")
        held = check.download()
        assert held is not None and len(held) == 8
        for item, (frame, command, params, x, y, z) in zip(held, _wpl_rows()):
            assert (item.frame, item.command) == (frame, command)
            assert [round(p, 3) for p in (item.p1, item.p2, item.p3, item.p4)] == params
            assert (item.x, item.y) == (round(x * 1e7), round(y * 1e7))
            assert abs(item.z - z) < 1e-4
        mp.say("wp list")
        mp.expect(r"Requesting 8 waypoints")
        listed = [mp.expect(r"^(\d+) (\d+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) p1=") for _ in range(8)]
        for found, (frame, command, params, x, y, z) in zip(listed, _wpl_rows()):
            assert (int(found.group(1)), int(found.group(2))) == (command, frame)
            assert abs(float(found.group(3)) - x) < 1e-7 and abs(float(found.group(4)) - y) < 1e-7
    finally:
        mp.close()


def test_mavsdk_mission_raw(vehicle):
    from mavsdk.plugins.mission_raw import MissionItem, MissionRaw

    v, port, check = two_links(vehicle)
    with mavsdk_system(port) as system:
        raw = MissionRaw(system)
        items = [MissionItem(i, 6, 16, 1 if i == 0 else 0, 1, 0.0, 2.0, 0.0, float(i), 473977420 + 1000 * i,
                             85455940 - 500 * i, 10.0 + i, 0) for i in range(60)]
        items[10] = MissionItem(10, 2, 178, 0, 1, 1.0, 7.5, -1.0, 0.0, 0, 0, 0.0, 0)  # DO_CHANGE_SPEED
        raw.upload_mission(items)
        got = raw.download_mission()
        assert len(got) == 60
        for a, b in zip(items, got):
            assert (a.seq, a.frame, a.command, a.autocontinue, a.x, a.y) == (b.seq, b.frame, b.command, b.autocontinue, b.x, b.y)
            assert (a.param1, a.param2, a.param3, a.param4, a.z) == (b.param1, b.param2, b.param3, b.param4, b.z)
        fence = [MissionItem(i, 5, 5001, 0, 1, 4.0, 0, 0, 0, 473977420 + d[0], 85455940 + d[1], 0.0, 1)
                 for i, d in enumerate(((0, 0), (3000, 0), (3000, 3000), (0, 3000)))]
        raw.upload_geofence(fence)
        rally = [MissionItem(0, 6, 5100, 0, 1, 0, 0, 0, 0, 473990000, 85460000, 40.0, 2)]
        raw.upload_rally_points(rally)
        assert [(f.command, f.x) for f in raw.download_geofence()] == [(5001, f.x) for f in fence]
        assert [(r.command, r.y, r.z) for r in raw.download_rallypoints()] == [(5100, 85460000, 40.0)]
        assert len(raw.download_mission()) == 60  # the mission is untouched by the others
    held = check.download()
    assert len(held) == 60 and held[59].x == 473977420 + 59000


def test_mavsdk_uploads_through_a_lossy_link(vehicle):
    """MAVSDK answers only the request for the item after the last one it sent (or an
    earlier one) and ignores requests ahead ("sequence incorrect"); the vehicle asks
    several items ahead, so when an item is lost it walks MAVSDK forward from where it
    stands, found within a round trip (MAVSDK gives up after half a second of refused
    requests). Three 60-item uploads with 6% of the frames dropped each way all succeed.
    (MAVSDK sends an item at most four times, so at 10% an upload of 60 items fails
    about once in 150 whatever the vehicle does; and it does not send its last item
    again when the final MISSION_ACK is lost, so that one passes undisturbed.)"""
    from mavsdk.plugins.mission_raw import MissionItem, MissionRaw
    from relay import LossyRelay

    v, port, check = two_links(vehicle)
    relay = LossyRelay(port, rate=0.06, drop_only=True, seed=3, spare=(47,))  # MISSION_ACK
    try:
        with mavsdk_system(relay.port) as system:
            raw = MissionRaw(system)
            for k in range(3):
                items = [MissionItem(i, 6, 16, 1 if i == 0 else 0, 1, float(k), 2.0, 0.0, float(i),
                                     473977420 + 1000 * i, 85455940 - 500 * i, 10.0 + i, 0) for i in range(60)]
                raw.upload_mission(items)  # raises MissionRawError unless it succeeded
                held = check.download()
                assert len(held) == 60 and [h.p1 for h in held] == [float(k)] * 60
                assert [h.x for h in held] == [i.x for i in items]
    finally:
        relay.close()
    assert relay.stats["dropped"] > 20, relay.stats
