"""Parameter protocol end to end: the unix vehicle over UDP, pymavlink as the ground station."""
import os
import struct
import sys
import time

import pytest

from conftest import ROOT, free_udp_port, recv

sys.path.insert(0, os.path.join(ROOT, "boards"))
import unix_params  # noqa: E402

NAMES = [row[0] for row in unix_params.PARAMS]
N = len(NAMES)


def connect(v, version=2, **kw):
    return v.gcs(version=version, **kw)


def fetch_all(m, timeout=10):
    """PARAM_REQUEST_LIST -> {index: message}; fails on duplicates."""
    m.mav.param_request_list_send(m.target_system, m.target_component)
    got = {}
    deadline = time.time() + timeout
    while len(got) < N and time.time() < deadline:
        msg = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=1)
        if msg is None:
            continue
        assert msg.param_index not in got, "duplicate %s" % msg
        assert msg.param_count == N
        got[msg.param_index] = msg
    return got


def read(m, name=b"", index=-1):
    m.mav.param_request_read_send(m.target_system, m.target_component, name, index)
    return recv(m, "PARAM_VALUE", 3)


def set_param(m, name, value, ptype):
    m.mav.param_set_send(m.target_system, m.target_component, name.encode(), value, ptype)
    return recv(m, "PARAM_VALUE", 3, lambda x: x.param_id == name)


def command(m, cmd, *params):
    params = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(m.target_system, m.target_component, cmd, 0, *params)
    return recv(m, "COMMAND_ACK", 3, lambda a: a.command == cmd)


def raw_value(msg):
    buf = msg.get_msgbuf()
    off = 10 if buf[0] == 0xFD else 6
    return bytes(buf[off:off + 4])


def as_float(fmt, v):
    return struct.unpack("<f", struct.pack(fmt, v).ljust(4, b"\0"))[0]


@pytest.mark.parametrize("version", [1, 2])
def test_list_all(vehicle, version):
    m = connect(vehicle(), version)
    got = fetch_all(m)
    assert sorted(got) == list(range(N))
    assert [got[i].param_id for i in range(N)] == NAMES
    stx = 0xFE if version == 1 else 0xFD
    assert all(msg.get_msgbuf()[0] == stx for msg in got.values())


def test_read_by_name_and_index(vehicle):
    m = vehicle().gcs()
    msg = read(m, b"SIM_GPS_GLITCH_M")  # 16 characters, no NUL
    assert (msg.param_id, msg.param_index, msg.param_value) == ("SIM_GPS_GLITCH_M", NAMES.index("SIM_GPS_GLITCH_M"), 0.0)
    msg = read(m, b"RTL_LOIT_TIME_S")
    assert (msg.param_id, msg.param_value) == ("RTL_LOIT_TIME_S", 5.0)
    msg = read(m, index=NAMES.index("BATT_CAPACITY"))
    assert msg.param_id == "BATT_CAPACITY" and raw_value(msg) == struct.pack("<i", 5000)


def test_unknown_name_gets_statustext_and_no_value(vehicle):
    m = vehicle().gcs()
    m.mav.param_request_read_send(1, 1, b"NO_SUCH_PARAM", -1)
    text = recv(m, "STATUSTEXT", 5, lambda t: "NO_SUCH_PARAM" in t.text)
    assert text is not None
    assert recv(m, "PARAM_VALUE", 0.5) is None


def test_set_float_and_int(vehicle):
    m = vehicle().gcs()
    msg = set_param(m, "SIM_SPEED", 7.5, 9)
    assert msg.param_value == 7.5 and msg.param_type == 9
    msg = set_param(m, "BATT_CAPACITY", as_float("<i", 6100), 6)
    assert raw_value(msg) == struct.pack("<i", 6100) and msg.param_type == 6
    msg = set_param(m, "FLTMODE_CH", as_float("<i", -1), 6)
    assert raw_value(msg) == b"\xff\xff\xff\xff"
    assert read(m, b"SIM_SPEED").param_value == 7.5
    assert raw_value(read(m, b"BATT_CAPACITY")) == struct.pack("<i", 6100)


@pytest.mark.parametrize("name, value, ptype, why, error", [
    ("SIM_SPEED", 31.0, 9, "range", 2),  # MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    ("SIM_SPEED", float("nan"), 9, "NaN", 2),
    ("BATT_CAPACITY", as_float("<h", 61), 4, "type", 7),  # TYPE_MISMATCH
    ("BATT_CAPACITY", 6100.5, 9, "whole", 2),  # declared a float: cast, not a whole number
    ("BATT_CAPACITY", 3e9, 9, "range", 2),
    ("MAV_SYS_ID", as_float("<i", 9), 6, "read-only", 5),  # READ_ONLY
])
def test_refused_set_answers_value_in_force(vehicle, name, value, ptype, why, error):
    m = vehicle().gcs()
    before = read(m, name.encode())
    m.mav.param_set_send(1, 1, name.encode(), value, ptype)
    err = recv(m, "PARAM_ERROR", 3, lambda x: x.param_id == name)
    assert err is not None and err.error == error and err.target_system == 255
    assert err.param_index == NAMES.index(name)
    msg = recv(m, "PARAM_VALUE", 3, lambda x: x.param_id == name)
    assert raw_value(msg) == raw_value(before)  # (a float for an integer changes no encoding)
    assert recv(m, "STATUSTEXT", 3, lambda t: name in t.text and why in t.text) is not None


def test_unknown_names_get_param_error(vehicle):
    m = vehicle().gcs()
    m.mav.param_set_send(1, 1, b"NO_SUCH_PARAM", 1.0, 9)
    err = recv(m, "PARAM_ERROR", 3)
    assert err.param_id == "NO_SUCH_PARAM" and err.error == 1 and err.param_index == -1  # DOES_NOT_EXIST
    m.mav.param_request_read_send(1, 1, b"NOR_THIS", -1)
    err = recv(m, "PARAM_ERROR", 3)
    assert err.param_id == "NOR_THIS" and err.error == 1
    m.mav.param_request_read_send(1, 1, b"", N + 3)
    err = recv(m, "PARAM_ERROR", 3)
    assert err.param_index == N + 3 and err.error == 1


def test_real32_typed_set_of_an_integer_is_a_cast_and_keeps_the_links_encoding(vehicle):
    """A sender that declares a float for an integer parameter means the number (as
    ArduPilot and pymavlink have it); it changes no link's encoding: each link's integers
    travel as its ground station's conventions say (services/status/conventions.py)."""
    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2])
    a = v.gcs(port=p1)
    b = v.gcs(port=p2, source_system=254)
    assert raw_value(read(a, b"BATT_CAPACITY")) == struct.pack("<i", 5000)
    msg = set_param(a, "BATT_CAPACITY", 6100.0, 9)
    assert msg.param_type == 6 and raw_value(msg) == struct.pack("<i", 6100)  # stored, told bytewise
    assert raw_value(read(a, b"BATT_CAPACITY")) == struct.pack("<i", 6100)  # ... and still so
    assert raw_value(read(a, b"MAV_SYS_ID")) == struct.pack("<B", 1) + bytes(3)
    msg = recv(b, "PARAM_VALUE", 3, lambda x: x.param_id == "BATT_CAPACITY")
    assert raw_value(msg) == struct.pack("<i", 6100)  # the other link: bytewise
    a.mav.request_data_stream_send(1, 1, 0, 4, 1)  # ArduPilot's convention shown: C-cast
    deadline = time.time() + 3
    while time.time() < deadline and read(a, b"BATT_CAPACITY").param_value != 6100.0:
        time.sleep(0.1)
    # Typed as the parameter on a C-cast link: the float holds the number.
    assert set_param(a, "BATT_CAPACITY", 4200.0, 6).param_value == 4200.0
    assert raw_value(read(b, b"BATT_CAPACITY")) == struct.pack("<i", 4200)
    # Bytewise, typed as the parameter: its bytes.
    b.mav.param_set_send(1, 1, b"BATT_CAPACITY", as_float("<i", 3300), 6)
    assert recv(b, "PARAM_VALUE", 3, lambda x: raw_value(x) == struct.pack("<i", 3300)) is not None
    assert recv(a, "PARAM_VALUE", 3, lambda x: x.param_value == 3300.0) is not None


def test_auto_encoding_follows_what_the_ground_station_does(vehicle):
    m = vehicle().gcs()
    assert raw_value(read(m, b"BATT_CAPACITY")) == struct.pack("<i", 5000)  # nothing heard: bytewise
    m.mav.request_data_stream_send(1, 1, 0, 4, 1)  # ArduPilot's convention: C-cast
    deadline = time.time() + 3
    while time.time() < deadline and read(m, b"BATT_CAPACITY").param_value != 5000.0:
        time.sleep(0.1)
    assert read(m, b"BATT_CAPACITY").param_value == 5000.0
    assert command(m, 512, 148) is not None  # asks for AUTOPILOT_VERSION: ArduPilot's do too
    assert read(m, b"BATT_CAPACITY").param_value == 5000.0
    # NaN in the parameters a command does not use: MAVSDK's way, PX4's convention:
    # bytewise, and a float for an integer refused as PX4 does (TYPE_MISMATCH, not stored).
    nan = float("nan")
    m.mav.command_long_send(1, 1, 512, 0, 148, nan, nan, nan, nan, nan, nan)
    assert recv(m, "COMMAND_ACK", 3) is not None
    assert raw_value(read(m, b"BATT_CAPACITY")) == struct.pack("<i", 5000)
    m.mav.param_set_send(1, 1, b"BATT_CAPACITY", 4100.0, 9)
    err = recv(m, "PARAM_ERROR", 3)
    assert err.param_id == "BATT_CAPACITY" and err.error == 7  # TYPE_MISMATCH
    assert recv(m, "STATUSTEXT", 3, lambda t: "BATT_CAPACITY not set: type 9, expected 6" in t.text)
    assert raw_value(read(m, b"BATT_CAPACITY")) == struct.pack("<i", 5000)


def test_persist_across_restart_and_reload(vehicle, tmp_path):
    storage = tmp_path / "persist"
    v = vehicle(storage=storage, args=["--set", "param_autosave_ms=0"])
    m = v.gcs()
    set_param(m, "WP_SPEED", 12.5, 9)
    set_param(m, "SIM_SEED", as_float("<i", 777), 6)
    assert command(m, 245, 1).result == 0
    set_param(m, "WP_SPEED", 3.5, 9)  # not saved
    v.stop()
    v = vehicle(storage=storage, args=["--set", "param_autosave_ms=0"])
    m = v.gcs()
    assert read(m, b"WP_SPEED").param_value == 12.5
    assert raw_value(read(m, b"SIM_SEED")) == struct.pack("<i", 777)
    set_param(m, "WP_SPEED", 4.5, 9)
    assert command(m, 245, 0).result == 0  # reload
    assert read(m, b"WP_SPEED").param_value == 12.5


def test_autosave(vehicle, tmp_path):
    storage = tmp_path / "auto"
    v = vehicle(storage=storage, args=["--set", "param_autosave_ms=100"])
    m = v.gcs()
    set_param(m, "WP_SPEED", 6.5, 9)
    deadline = time.time() + 10
    while not (storage / "params").exists() and time.time() < deadline:
        time.sleep(0.05)
    v.stop()
    m = vehicle(storage=storage).gcs()
    assert read(m, b"WP_SPEED").param_value == 6.5


def test_do_set_parameter(vehicle):
    m = vehicle().gcs()
    ack = command(m, 180, NAMES.index("RTL_ALT"), 25.0)
    assert ack.result == 0
    assert read(m, b"RTL_ALT").param_value == 25.0
    assert command(m, 180, NAMES.index("RTL_ALT"), 1000.0).result == 2
    assert command(m, 180, N + 5, 1.0).result == 2
    assert read(m, b"RTL_ALT").param_value == 25.0


def test_change_broadcast_to_every_link(vehicle):
    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2])
    a = v.gcs(port=p1)
    b = connect(v, 1, port=p2, source_system=254)
    assert set_param(a, "WP_ACCEPT_RAD", 4.0, 9).param_value == 4.0
    msg = recv(b, "PARAM_VALUE", 3, lambda x: x.param_id == "WP_ACCEPT_RAD")
    assert msg is not None and msg.param_value == 4.0
    # A list on one link while the other keeps working.
    b.mav.param_request_list_send(1, 1)
    assert len(fetch_all(a)) == N


def test_c_cast_option(vehicle):
    m = vehicle(args=["--set", "param_encoding=c_cast"]).gcs()
    assert read(m, b"BATT_CAPACITY").param_value == 5000.0
    assert set_param(m, "BATT_CAPACITY", 4200.0, 6).param_value == 4200.0


def test_garbage_file_means_defaults_then_saves(vehicle, tmp_path):
    storage = tmp_path / "garbage"
    storage.mkdir()
    (storage / "params").write_bytes(os.urandom(700))
    v = vehicle(storage=storage, args=["--set", "param_autosave_ms=0"])
    m = v.gcs()
    assert read(m, b"WP_SPEED").param_value == 5.0
    set_param(m, "WP_SPEED", 8.0, 9)
    assert command(m, 245, 1).result == 0
    v.stop()
    m = vehicle(storage=storage).gcs()
    assert read(m, b"WP_SPEED").param_value == 8.0


def test_interrupted_save_keeps_previous_file(vehicle, tmp_path):
    storage = tmp_path / "cut"
    v = vehicle(storage=storage)
    m = v.gcs()
    set_param(m, "WP_SPEED", 9.0, 9)
    assert command(m, 245, 1).result == 0
    v.stop()
    (storage / "params.new").write_bytes(os.urandom(123))  # killed while writing
    m = vehicle(storage=storage).gcs()
    assert read(m, b"WP_SPEED").param_value == 9.0


def test_operator_control_gates_changes(vehicle):
    p1, p2 = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p1, "udpin:127.0.0.1:%d" % p2], args=["--set", "operator_passkey=secret"])
    boss = v.gcs(port=p1, source_system=200)
    other = v.gcs(port=p2, source_system=201)
    boss.mav.change_operator_control_send(1, 0, 0, b"secret")
    assert recv(boss, "CHANGE_OPERATOR_CONTROL_ACK", 5).ack == 0
    msg = set_param(other, "WP_SPEED", 9.0, 9)
    assert msg.param_value == 5.0  # refused: the value in force
    assert recv(other, "STATUSTEXT", 5, lambda t: "not in control" in t.text) is not None
    assert command(other, 180, NAMES.index("WP_SPEED"), 9.0).result == 2  # DENIED
    boss.mav.heartbeat_send(6, 8, 0, 0, 0)  # still here: control stays with boss
    assert set_param(boss, "WP_SPEED", 9.5, 9).param_value == 9.5
    msg = recv(other, "PARAM_VALUE", 5, lambda m: m.param_id == "WP_SPEED" and m.param_value == 9.5)
    assert msg is not None  # the change reaches the other ground station too


def test_sys_id_parameter_mirrors_the_system_id(vehicle):
    m = vehicle(args=["--sysid", "7"]).gcs()
    assert m.target_system == 7
    msg = read(m, b"MAV_SYS_ID")
    assert msg.get_srcSystem() == 7 and raw_value(msg) == struct.pack("<i", 7)
