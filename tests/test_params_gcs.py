"""Real ground stations edit the unix vehicle's parameters: MAVProxy scripted over its
stdin, and MAVSDK's Param plugin. A pymavlink ground station on a second link checks
what the vehicle says afterwards."""
import os
import sys

import pytest

from conftest import ROOT, recv
from gcs_tools import MavProxy, two_links, mavsdk_system

sys.path.insert(0, os.path.join(ROOT, "boards"))
import unix_params  # noqa: E402

N = len(unix_params.PARAMS)


@pytest.mark.parametrize("encoding", ["bytewise", "c_cast"])
def test_mavproxy_fetches_sets_and_commands(vehicle, tmp_path, encoding):
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
        if encoding == "c_cast":
            # MAVProxy sends every value as a float tagged REAL32: C-cast takes it as the number.
            mp.say("param show BATT_CAPACITY")
            assert float(mp.expect(r"BATT_CAPACITY\s+(\S+)").group(1)) == 5000
            mp.say("param set BATT_CAPACITY 4200")
            msg = recv(check, "PARAM_VALUE", 10, lambda m: m.param_id == "BATT_CAPACITY")
            assert msg is not None and msg.param_value == 4200.0
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
