"""The installed `mavctl` command with the ground stations' files, against the unix vehicle
over UDP: QGroundControl .plan (mission, fence polygons and circles, rally points) and QGC
WPL 110 missions, QGroundControl .params and MAVProxy .parm parameter files. Files written
by mavctl are read back by pymavlink's own loaders (mavwp, mavparm); malformed files are
refused with one line naming the line or key, before anything is sent."""
import json
import math
import os
import subprocess

import pytest

from conftest import ROOT, free_udp_port
from plan_samples import qgc_plan, same_numbers

os.environ["MAVLINK20"] = "1"
from pymavlink import mavparm, mavwp  # noqa: E402

MAVCTL = os.path.join(ROOT, ".venv", "bin", "mavctl")


def mavctl(link, *args, timeout=60):
    """The installed command as a user runs it; never a traceback."""
    cmd = [MAVCTL] + (["--connect", link] if link else []) + [str(a) for a in args]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def ok(r):
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    return r.stdout


def refused(r, status, *words):
    assert r.returncode == status, (r.returncode, r.stdout, r.stderr)
    line = r.stderr.strip()
    assert line.startswith("mavctl: ") and "\n" not in line, line
    for w in words:
        assert w in line, (w, line)
    return line


@pytest.fixture
def link(vehicle):
    """A unix vehicle listening on UDP; each mavctl run talks to it with udpout."""
    v = vehicle()
    return "udpout:127.0.0.1:%d" % v.port


def test_plan_round_trip(link, tmp_path):
    """A QGroundControl plan goes up as the three mission types and comes back as one .plan."""
    plan = qgc_plan()
    path = tmp_path / "route.plan"
    path.write_text(json.dumps(plan, indent=4))
    assert "uploaded 5 mission, 9 fence, 2 rally items" in ok(mavctl(link, "mission", "upload", path))
    back = tmp_path / "back.plan"
    ok(mavctl(link, "mission", "download", back))
    doc = json.loads(back.read_text())
    assert doc["fileType"] == "Plan" and doc["version"] == 1
    same_numbers(plan["geoFence"], doc["geoFence"])
    same_numbers(plan["rallyPoints"], doc["rallyPoints"])
    same_numbers(plan["mission"]["items"], doc["mission"]["items"])
    assert len(doc["mission"]["plannedHomePosition"]) == 3

    # The parts as the vehicle holds them, read by pymavlink's mission loaders (QGC WPL).
    wpl = tmp_path / "fence.waypoints"
    ok(mavctl(link, "mission", "download", wpl, "--type", "fence"))
    fence = mavwp.MissionItemProtocol_Fence()
    fence.load(str(wpl))
    commands = [fence.item(i).command for i in range(fence.count())]
    assert commands == [5001] * 4 + [5002] * 3 + [5003, 5004]
    assert fence.item(7).param1 == pytest.approx(400.5)
    rally = tmp_path / "rally.waypoints"
    ok(mavctl(link, "mission", "download", rally, "--type", "rally"))
    loader = mavwp.MissionItemProtocol_Rally()
    loader.load(str(rally))
    assert [(round(loader.item(i).x, 4), loader.item(i).z) for i in range(loader.count())] == [
        (47.3975, 30), (47.3988, 45.5)]
    mission = tmp_path / "mission.waypoints"
    ok(mavctl(link, "mission", "download", mission))
    wp = mavwp.MAVWPLoader()
    assert wp.load(str(mission)) == 5
    assert [wp.wp(i).command for i in range(5)] == [22, 16, 178, 16, 21]
    assert math.isnan(wp.wp(1).param4) and wp.wp(2).param2 == 7.5

    # A WPL file goes up as it is, and the .plan then holds it with the fence kept.
    lines = ["QGC WPL 110"] + ["%d\t0\t3\t16\t0\t0\t0\t0\t%.7f\t8.5455\t%d\t1" % (i, 47.3970 + i * 1e-4, 10 + i)
                               for i in range(3)]
    (tmp_path / "short.waypoints").write_text("\n".join(lines) + "\n")
    assert "uploaded 3 mission items" in ok(mavctl(link, "mission", "upload", tmp_path / "short.waypoints"))
    ok(mavctl(link, "mission", "download", back))
    doc = json.loads(back.read_text())
    assert [i["params"][6] for i in doc["mission"]["items"]] == [10, 11, 12]
    same_numbers(plan["geoFence"], doc["geoFence"])
    # One part of a plan with --type; clear all.
    ok(mavctl(link, "mission", "upload", path, "--type", "rally"))
    assert "cleared the mission, fence, rally" in ok(mavctl(link, "mission", "clear", "--type", "all"))
    ok(mavctl(link, "mission", "download", back))
    doc = json.loads(back.read_text())
    assert doc["mission"]["items"] == [] and doc["rallyPoints"]["points"] == []
    assert doc["geoFence"]["polygons"] == [] and doc["geoFence"]["circles"] == []


@pytest.mark.parametrize("change, words", [
    (lambda p: p["mission"]["items"][1]["params"].__setitem__(4, "north"), ["mission.items[1].params[4]", "north"]),
    (lambda p: p["mission"]["items"][0]["params"].pop(), ["mission.items[0].params", "7 values"]),
    (lambda p: p["mission"]["items"][2].__setitem__("type", "ComplexItem"), ["mission.items[2]", "ComplexItem"]),
    (lambda p: p["mission"]["items"][3].pop("command"), ["mission.items[3]", "'command'"]),
    (lambda p: p["geoFence"]["polygons"][1]["polygon"].pop(), ["geoFence.polygons[1].polygon", "3 vertices"]),
    (lambda p: p["geoFence"]["circles"][0]["circle"].__setitem__("radius", -3), ["geoFence.circles[0].circle.radius"]),
    (lambda p: p["rallyPoints"]["points"][1].__setitem__(0, 123.0), ["rallyPoints.points[1]", "out of range"]),
    (lambda p: p.__setitem__("fileType", "Mission"), ["fileType", "'Plan'"]),
])
def test_malformed_plan_sends_nothing(tmp_path, change, words):
    """Each fault is one line naming the key; no vehicle is needed, since nothing is sent."""
    plan = qgc_plan()
    change(plan)
    path = tmp_path / "bad.plan"
    path.write_text(json.dumps(plan))
    port = free_udp_port()  # nobody there: a connection attempt would end in "no HEARTBEAT"
    refused(mavctl("udpin:127.0.0.1:%d" % port, "mission", "upload", path), 2, "bad.plan: ", *words)


def test_malformed_files_sent_nothing_to_a_vehicle(link, tmp_path):
    ok(mavctl(link, "mission", "upload", write(tmp_path / "good.plan", json.dumps(qgc_plan()))))
    bad_json = write(tmp_path / "cut.plan", json.dumps(qgc_plan())[:200])
    refused(mavctl(link, "mission", "upload", bad_json), 2, "cut.plan:1:", "not valid JSON")
    bad_wpl = write(tmp_path / "bad.waypoints", "QGC WPL 110\n0\t0\t3\t16\t0\t0\t0\t0\t47\t8\t10\n")
    refused(mavctl(link, "mission", "upload", bad_wpl), 2, "bad.waypoints:2:", "12 columns")
    bad_parm = write(tmp_path / "bad.parm", "SIM_SPEED 6\nWP_SPEED fast\n")
    refused(mavctl(link, "params", "load", bad_parm), 2, "bad.parm:2:", "'fast'")
    bad_params = write(tmp_path / "bad.params", "# x\n1\t1\tSIM_SPEED\t6\n")
    refused(mavctl(link, "params", "load", bad_params), 2, "bad.params:2:", "5 tab-separated")
    unknown = write(tmp_path / "unknown.parm", "SIM_SPEED 6\nNO_SUCH_PARAM 1\n")
    refused(mavctl(link, "params", "load", unknown), 2, "unknown.parm:2: NO_SUCH_PARAM", "no such parameter")
    too_big = write(tmp_path / "big.parm", "SIM_SPEED 6\nSIM_GPS_SATS 2.5\n")
    refused(mavctl(link, "params", "load", too_big), 2, "big.parm:2:", "SIM_GPS_SATS")
    # The vehicle still has the good plan and the first lines' values were not sent.
    assert ok(mavctl(link, "params", "get", "SIM_SPEED")).split() == ["SIM_SPEED", "5.0"]
    doc = json.loads(ok(mavctl(link, "mission", "download", tmp_path / "now.plan")) and
                     (tmp_path / "now.plan").read_text())
    assert len(doc["mission"]["items"]) == 5 and len(doc["geoFence"]["polygons"]) == 2


def write(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize("suffix", [".params", ".parm"])
def test_params_files_round_trip(link, tmp_path, suffix):
    path = tmp_path / ("vehicle" + suffix)
    listing = dict(line.split() for line in ok(mavctl(link, "params", "list")).splitlines())
    n = len(listing)
    assert ok(mavctl(link, "params", "save", path)).startswith("saved %d parameters" % n)
    # pymavlink reads what mavctl wrote: mavparm the .parm format, the .params columns by hand.
    if suffix == ".parm":
        loaded = mavparm.MAVParmDict()
        assert loaded.load(str(path))
        saved = {k: str(v) for k, v in loaded.items()}
    else:
        rows = [line.split("\t") for line in path.read_text().splitlines() if not line.startswith("#")]
        assert all(len(r) == 5 and r[0] == "1" and r[1] == "1" and r[4] in ("6", "9") for r in rows)
        saved = {r[2]: r[3] for r in rows}
    assert set(saved) == set(listing)
    for name, text in listing.items():
        assert float(saved[name]) == pytest.approx(float(text), rel=1e-7), name

    # Changed on the vehicle, then the file loaded back: only what differs is set.
    ok(mavctl(link, "params", "set", "SIM_SPEED", "7.25"))
    ok(mavctl(link, "params", "set", "SIM_SEED", "-5000000"))
    diff = ok(mavctl(link, "params", "diff", path)).splitlines()
    assert sorted(line.split()[0] for line in diff[1:]) == ["SIM_SEED", "SIM_SPEED"]
    out = ok(mavctl(link, "params", "load", path))
    assert "SIM_SPEED        7.25 -> 5.0" in out and "SIM_SEED         -5000000 -> 12345" in out
    assert out.splitlines()[-1] == "%s: 2 changed, %d unchanged, 0 refused" % (path, n - 2)
    assert ok(mavctl(link, "params", "diff", path)).splitlines()[1:] == []
    # A file from another vehicle: a read-only value differs, the vehicle keeps its own.
    other = tmp_path / ("other" + suffix)
    text = path.read_text().replace("MAV_SYS_ID\t1\t", "MAV_SYS_ID\t7\t")
    text = "\n".join("MAV_SYS_ID       7" if line.startswith("MAV_SYS_ID ") else line
                     for line in text.splitlines()) + "\n"
    other.write_text(text)
    r = mavctl(link, "params", "load", other)
    assert r.returncode == 1 and "0 changed, %d unchanged, 1 refused: MAV_SYS_ID" % (n - 1) in r.stdout, r


def test_params_diff_defaults_and_mavproxy_file(link, tmp_path):
    assert ok(mavctl(link, "params", "diff", "--defaults")).splitlines()[1:] == []
    ok(mavctl(link, "params", "set", "WP_SPEED", "7.5"))
    lines = ok(mavctl(link, "params", "diff", "--defaults")).splitlines()
    assert [line.split() for line in lines[1:]] == [["WP_SPEED", "7.5", "5.0"]]
    # A file as MAVProxy writes it (pymavlink's mavparm: %f values, integers too).
    parm = mavparm.MAVParmDict()
    parm["WP_SPEED"] = 5.0
    parm["SIM_GPS_SATS"] = 9
    parm["WP_YAW_BEHAVIOR"] = 2.0
    parm.save(str(tmp_path / "mavproxy.parm"))
    out = ok(mavctl(link, "params", "load", tmp_path / "mavproxy.parm"))
    assert out.splitlines()[-1].endswith(": 3 changed, 0 unchanged, 0 refused")
    assert ok(mavctl(link, "params", "get", "SIM_GPS_SATS")).split() == ["SIM_GPS_SATS", "9"]
    refused(mavctl(link, "params", "diff"), 2, "params diff FILE")


def test_plan_as_mavsdk_reads_it(vehicle, tmp_path):
    """MAVSDK's QGroundControl plan importer as the oracle for .plan files: what it makes of
    a plan is what mavctl put on the vehicle (MAVSDK downloads the three parts), and what it
    makes of the plan mavctl downloads back is the same again."""
    from gcs_tools import mavsdk_system
    from mavsdk.plugins.mission_raw import MissionRaw

    def rows(items):
        return [(i.seq, i.frame, i.command, i.autocontinue, i.param1, i.param2, i.param3,
                 "nan" if math.isnan(i.param4) else i.param4, i.x, i.y, i.z, i.mission_type)
                for i in items]

    v = vehicle()
    link = "udpout:127.0.0.1:%d" % v.port
    path = write(tmp_path / "route.plan", json.dumps(qgc_plan()))
    with mavsdk_system(v.port) as system:
        raw = MissionRaw(system)
        want = raw.import_qgroundcontrol_mission(str(path))
        ok(mavctl(link, "mission", "upload", path))
        assert rows(raw.download_mission()) == rows(want.mission_items)
        assert rows(raw.download_geofence()) == rows(want.geofence_items)
        assert rows(raw.download_rallypoints()) == rows(want.rally_items)
        ok(mavctl(link, "mission", "download", tmp_path / "back.plan"))
        back = raw.import_qgroundcontrol_mission(str(tmp_path / "back.plan"))
        for part in ("mission_items", "geofence_items", "rally_items"):
            assert rows(getattr(back, part)) == rows(getattr(want, part)), part
        assert len(want.mission_items) == 5 and len(want.geofence_items) == 9
