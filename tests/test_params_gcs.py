"""Real ground stations edit the unix vehicle's parameters: MAVProxy scripted over its
stdin, and MAVSDK's Param plugin. A pymavlink ground station on a second link checks
what the vehicle says afterwards."""
import os
import sys

import pytest

from conftest import ROOT, free_udp_port, recv
from gcs_tools import MavProxy, two_links, mavsdk_system

sys.path.insert(0, os.path.join(ROOT, "boards"))
import unix_params  # noqa: E402

N = len(unix_params.PARAMS)


def _shown(mp, name, want, timeout=10):
    """What MAVProxy's `param show` prints for name, asked until it is want or time is up."""
    import time

    deadline = time.time() + timeout
    while True:
        mp.say("param show " + name)
        got = float(mp.expect(name + r"\s+([-\d.e+]+)\s*$").group(1))
        if got == want or time.time() > deadline:
            return got
        time.sleep(0.3)


@pytest.mark.parametrize("encoding", ["auto", "c_cast"])
def test_mavproxy_fetches_sets_and_commands(vehicle, tmp_path, encoding):
    """MAVProxy reads integers C-cast from any autopilot but PX4 and sets every value as a
    float typed REAL32. "auto" (the unix board's default) knows it by its
    REQUEST_DATA_STREAM at connect; the pymavlink link stays bytewise."""
    v, port, check = two_links(vehicle, "--set", "param_encoding=" + encoding, "--set", "param_autosave_ms=0")
    mp = MavProxy(port, tmp_path, "param,cmdlong")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("param fetch")
        assert int(mp.expect(r"Received (\d+) parameters").group(1)) == N
        mp.say("param show SIM_SPEED")
        assert float(mp.expect(r"SIM_SPEED\s+(\S+)").group(1)) == 5.0
        mp.say("param set SIM_SPEED 8.5")
        msg = recv(check, "PARAM_VALUE", 10, lambda m: m.param_id == "SIM_SPEED")
        assert msg is not None and msg.param_value == 8.5
        mp.say("param show BATT_CAPACITY")
        assert float(mp.expect(r"BATT_CAPACITY\s+(\S+)").group(1)) == 5000
        mp.say("param set BATT_CAPACITY 4200")
        msg = recv(check, "PARAM_VALUE", 10, lambda m: m.param_id == "BATT_CAPACITY")
        assert msg is not None
        if encoding == "auto":
            assert msg.get_msgbuf()[10:14] == (4200).to_bytes(4, "little")
        else:
            assert msg.param_value == 4200.0
        assert _shown(mp, "BATT_CAPACITY", 4200) == 4200  # (its own PARAM_VALUE may come after check's)
        mp.say("param set BATT_CAPACITY 4200.5")  # not a whole number: refused, in force stays
        assert recv(check, "STATUSTEXT", 10, lambda m: "BATT_CAPACITY not set" in m.text) is not None
        mp.say("param set BATT_CAPACITY 3000")
        assert recv(check, "PARAM_VALUE", 10, lambda m: m.param_id == "BATT_CAPACITY"
                    and m.get_msgbuf()[10:14] in ((3000).to_bytes(4, "little"), b"\x00\x80\x3b\x45")) is not None
        assert _shown(mp, "BATT_CAPACITY", 3000) == 3000  # (its retries of 4200.5 may still be answered)
        mp.say("long PREFLIGHT_STORAGE 1")
        mp.expect(r"COMMAND_ACK.*PREFLIGHT_STORAGE.*ACCEPTED")
    finally:
        mp.close()
    assert (tmp_path / "storage" / "params").exists()


def test_mavsdk_gets_all_and_sets(vehicle):
    from mavsdk.plugins.param import Param

    v, port, check = two_links(vehicle)
    with mavsdk_system(port) as system:
        param = Param(system)
        every = param.get_all_params()
        ints = {p.name: p.value for p in every.int_params}
        floats = {p.name: p.value for p in every.float_params}
        assert len(ints) + len(floats) == N
        assert ints["BATT_CAPACITY"] == 5000 and floats["SIM_SPEED"] == 5.0
        param.set_param_float("WP_SPEED", 7.25)
        param.set_param_int("BATT_LOW_MAH", 950)
        assert param.get_param_int("BATT_LOW_MAH") == 950
    check.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
    assert recv(check, "PARAM_VALUE", 5, lambda m: m.param_id == "WP_SPEED").param_value == 7.25
    check.mav.param_request_read_send(1, 1, b"BATT_LOW_MAH", -1)
    msg = recv(check, "PARAM_VALUE", 5, lambda m: m.param_id == "BATT_LOW_MAH")
    assert msg.get_msgbuf()[10:14] == (950).to_bytes(4, "little")


def test_mavsdk_integer_parameters_and_refusals(vehicle):
    """MAVSDK reads and writes integers bytewise from a generic autopilot; a refusal
    reaches it as PARAM_ERROR (its result), not as a timeout after its retries."""
    import time
    from mavsdk.plugins.param import Param, ParamError, ParamResult

    v, port, check = two_links(vehicle)
    with mavsdk_system(port) as system:
        param = Param(system)
        assert param.get_param_int("BATT_CAPACITY") == 5000
        param.set_param_int("BATT_CAPACITY", 6100)
        assert param.get_param_int("BATT_CAPACITY") == 6100
        param.set_param_int("FLTMODE_CH", -1)
        assert param.get_param_int("FLTMODE_CH") == -1
        for name, value, result in (("BATT_CAPACITY", -5, ParamResult.VALUE_OUT_OF_RANGE),
                                    ("MAV_SYS_ID", 9, ParamResult.READ_ONLY),
                                    ("NO_SUCH_PARAM", 1, ParamResult.DOES_NOT_EXIST)):
            t0 = time.monotonic()
            with pytest.raises(ParamError) as e:
                param.set_param_int(name, value)
            assert e.value.result == result and time.monotonic() - t0 < 1.0, (name, e.value.result)
        t0 = time.monotonic()
        with pytest.raises(ParamError) as e:
            param.get_param_int("NO_SUCH_PARAM")
        assert e.value.result == ParamResult.DOES_NOT_EXIST and time.monotonic() - t0 < 1.0
        assert param.get_param_int("BATT_CAPACITY") == 6100
    check.mav.param_request_read_send(1, 1, b"BATT_CAPACITY", -1)
    msg = recv(check, "PARAM_VALUE", 5, lambda m: m.param_id == "BATT_CAPACITY")
    assert msg.get_msgbuf()[10:14] == (6100).to_bytes(4, "little")


@pytest.mark.parametrize("identity", [None, (255, 1)], ids=["245/190", "255/1"])
def test_a_float_for_an_integer_changes_no_encoding(vehicle, tmp_path, identity):
    """MAVSDK's set_param_float on an integer parameter is refused as PX4 refuses it
    (TYPE_MISMATCH, nothing stored), whatever MAVSDK's identity; its link still reads and
    sets integers bytewise (MAV_SYS_ID reads 1, not 1065353216). MAVProxy on the other link
    of the same vehicle sets the same parameter as a float, taken, and reads it C-cast."""
    from mavsdk.plugins.param import Param, ParamError, ParamResult

    ports = free_udp_port(), free_udp_port()
    vehicle(links=["udpin:127.0.0.1:%d" % p for p in ports], args=["--set", "param_autosave_ms=0"])
    with mavsdk_system(ports[0], identity) as system:
        param = Param(system)
        assert param.get_param_int("BATT_CAPACITY") == 5000
        with pytest.raises(ParamError) as e:
            param.set_param_float("BATT_CAPACITY", 4100.0)
        assert e.value.result == ParamResult.TYPE_MISMATCH
        assert param.get_param_int("BATT_CAPACITY") == 5000  # nothing stored
        assert param.get_param_int("MAV_SYS_ID") == 1  # still bytewise
        param.set_param_int("BATT_CAPACITY", 4200)
        assert param.get_param_int("BATT_CAPACITY") == 4200
        mp = MavProxy(ports[1], tmp_path, "param")
        try:
            mp.expect(r"online system 1|Detected vehicle 1:1")
            mp.expect(r"Received %d parameters" % N)  # (its own list, on connecting)
            assert _shown(mp, "BATT_CAPACITY", 4200) == 4200  # C-cast on its link
            mp.say("param set BATT_CAPACITY 4300")  # REAL32, the number: taken
            assert _shown(mp, "BATT_CAPACITY", 4300) == 4300
            assert _shown(mp, "MAV_SYS_ID", 1) == 1
        finally:
            mp.close()
        assert param.get_param_int("BATT_CAPACITY") == 4300
        assert param.get_param_int("MAV_SYS_ID") == 1
