"""mavctl mission show (the item table in metres from home, the map as a PNG) from a QGC
WPL file, a .plan and the vehicle over UDP, and mavctl log plot from a telemetry log;
the PNGs are opened and measured; malformed input gets one line and exit status 2."""
import math
import struct

from conftest import free_udp_port
from mavctl_tools import check_png, mavctl, ok, refused, write_test_plan

WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.0\t1
1\t0\t3\t22\t0\t0\t0\t0\t47.3977420\t8.5455940\t10.0\t1
2\t0\t3\t16\t0.5\t2\t0\tnan\t47.3980001\t8.5460003\t15.25\t1
3\t0\t3\t16\t0\t0\t0\t0\t47.3985\t8.5450\t20\t1
4\t0\t2\t177\t1\t-1\t0\t0\t0\t0\t0\t1
5\t0\t3\t21\t0\t0\t0\t0\t47.397742\t8.545594\t0\t1
"""
def rows(out, part):
    return [line.split() for line in out.splitlines() if line.startswith(part + " ")]


def test_mission_show_wpl_file(tmp_path):
    path = tmp_path / "route.waypoints"
    path.write_text(WPL)
    out = ok(mavctl(None, "mission", "show", path, "--png", tmp_path / "m.png", "--size", "640x480"))
    assert out.splitlines()[0].split()[:4] == ["PART", "SEQ", "COMMAND", "FRAME"]
    items = rows(out, "mission")
    assert [r[1] for r in items] == ["0", "1", "2", "3", "4", "5"]
    assert [r[2] for r in items] == ["WAYPOINT", "TAKEOFF", "WAYPOINT", "WAYPOINT", "DO_JUMP", "LAND"]
    # Item 2: 28.7 m north, 30.6 m east of home (item 0); its leg from item 1 is 42 m.
    north, east, leg = (float(v) for v in items[2][-3:])
    assert math.isclose(north, 28.7, abs_tol=0.2) and math.isclose(east, 30.6, abs_tol=0.2)
    assert math.isclose(leg, math.hypot(north, east), abs_tol=0.2)
    assert len(items[4]) == 7  # DO_JUMP: no place, no metres
    check_png(tmp_path / "m.png", 640, 480)


def test_mission_show_plan_with_fence_and_rally(tmp_path):
    plan = write_test_plan(tmp_path / "route.plan")
    out = ok(mavctl(None, "mission", "show", plan, "--png", tmp_path / "p.png"))
    assert len(rows(out, "mission")) == 5
    fence = rows(out, "fence")
    assert [r[2] for r in fence] == ["FENCE_POLYGON_VERTEX_INCLUSION"] * 4 + \
        ["FENCE_POLYGON_VERTEX_EXCLUSION"] * 3 + ["FENCE_CIRCLE_EXCLUSION"]
    # The square's first corner: 82.6 m south, 120.1 m west of the plan's home.
    assert [float(v) for v in fence[0][-2:]] == [-82.6, -120.1]
    assert len(rows(out, "rally")) == 2
    check_png(tmp_path / "p.png", 1000, 800)  # the default size
    # Without --png: the table only.
    assert ok(mavctl(None, "mission", "show", plan)) == out


def test_mission_show_from_the_vehicle_over_udp(vehicle, tmp_path):
    v = vehicle()
    link = "udpout:127.0.0.1:%d" % v.port
    ok(mavctl(link, "mission", "upload", write_test_plan(tmp_path / "route.plan")))
    out = ok(mavctl(link, "mission", "show", "--vehicle", "--png", tmp_path / "v.png", "--size", "500x400"))
    assert len(rows(out, "mission")) == 5 and len(rows(out, "fence")) == 8 and len(rows(out, "rally")) == 2
    check_png(tmp_path / "v.png", 500, 400)
    v.check_alive()


def synthetic_tlog(path, seconds=20):
    """A tlog of a vehicle flying a 100 m circle at 30 m, its battery draining, written
    with mavctl's own TlogWriter (frames packed by pymavlink)."""
    from pymavlink.dialects.v20 import common as mavlink
    from mavctl.tlog import TlogWriter
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    t0 = 1.8e9
    with TlogWriter(str(path)) as log:
        for i in range(seconds * 5):
            t = t0 + i / 5.0
            a = i / (seconds * 5) * 2 * math.pi
            if i % 5 == 0:
                log.write(mav.heartbeat_encode(2, 0, 209, 3, 4, 3).pack(mav), t)
                log.write(gcs.heartbeat_encode(6, 8, 0, 0, 4, 3).pack(gcs), t)
                cells = [4000 - i] * 3 + [0xFFFF] * 7
                log.write(mav.battery_status_encode(0, 0, 0, 0, cells, 1200, -1, -1, 100 - i // 5).pack(mav), t)
            lat = int((47.397742 + 100 * math.sin(a) / 111319.49) * 1e7)
            lon = int((8.545594 + 100 * (1 - math.cos(a)) / 111319.49 / math.cos(math.radians(47.4))) * 1e7)
            log.write(mav.global_position_int_encode(int(i * 200), lat, lon, 518000, 30000, 500, 0, 0, 0)
                      .pack(mav), t)
            log.write(mav.vfr_hud_encode(0, 5.0 + math.sin(a), 0, 50, 30.0, 0).pack(mav), t)
    return path


def test_log_plot_of_a_tlog(tmp_path):
    tlog = synthetic_tlog(tmp_path / "circle.tlog")
    out = ok(mavctl(None, "log", "plot", tlog, "--png", tmp_path / "log.png", "--size", "900x700"))
    assert "drawn to" in out
    check_png(tmp_path / "log.png", 900, 700)
    # The module's own reading of it: 20 s of positions, only the vehicle's.
    from mavctl import plot as mavctl_plot
    series, home = mavctl_plot.read_log(str(tlog))
    assert home is None and len(series["lat"][0]) == 100
    assert math.isclose(series["lat"][0][-1], 19.8, abs_tol=0.01)
    assert series["alt"][1][0] == 30.0 and series["volts"][1][0] == 12.0


def test_plot_refusals(tmp_path):
    refused(mavctl(None, "mission", "show"), 2, "mission show FILE or")
    (tmp_path / "ok.waypoints").write_text(WPL)
    refused(mavctl(None, "mission", "show", tmp_path / "ok.waypoints", "--vehicle"), 2, "mission show FILE or")
    bad = tmp_path / "bad.waypoints"
    bad.write_text(WPL.replace("47.3985\t", "north\t"))
    refused(mavctl(None, "mission", "show", bad), 2, "bad.waypoints:5")
    (tmp_path / "bad.plan").write_text('{"fileType": "Plan", "mission": {"items": [}')
    refused(mavctl(None, "mission", "show", tmp_path / "bad.plan"), 2, "not valid JSON")
    refused(mavctl(None, "mission", "show", tmp_path / "ok.waypoints", "--size", "big"), 2, "--size")
    refused(mavctl(None, "mission", "show", tmp_path / "ok.waypoints", "--png", tmp_path / "no" / "m.png"),
            2, "m.png")
    refused(mavctl(None, "log", "plot", tmp_path / "none.tlog", "--png", tmp_path / "x.png"), 2, "no such file")
    junk = tmp_path / "junk.tlog"
    junk.write_bytes(struct.pack(">Q", 1) + bytes(range(256)) * 8)
    refused(mavctl(None, "log", "plot", junk, "--png", tmp_path / "x.png"), 2, "no GLOBAL_POSITION_INT")
    r = mavctl(None, "log", "plot", junk)
    assert r.returncode == 2 and "required: --png" in r.stderr  # argparse's usage line
    # mission show --vehicle with nothing there: the link's own error and status.
    refused(mavctl("udpin:127.0.0.1:%d" % free_udp_port(), "--timeout", "1", "mission", "show", "--vehicle"),
            5, "no HEARTBEAT")
