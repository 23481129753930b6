"""The whole vehicle on the emulated boards (boards/qemu_m3.py, qemu_m0.py: status,
params, commands, missions, streams and signing, storage in RAM), with the heap locked
once it is up (HEAP_LOCK): a pymavlink ground station on the board's MAVLink UART lists
and sets parameters (a uint32 past 2^30 among them), saves and reloads them, uploads and
downloads a 100-item mission with coordinates past +-107 degrees and an altitude of
-400 m, arms and disarms, asks for ATTITUDE at 10 Hz and GLOBAL_POSITION_INT at 5 Hz
and reads SYSTEM_TIME. A MemoryError anywhere stops the vehicle, and the test with it.
"""
import os
import struct
import time

import pytest

from conftest import recv
from gcs_tools import command, run
from mcu_rig import EmulatedBoard
from mission_gcs import Item, MissionClient
from test_mcu import BOARDS, _gate

MAV_RESULT_ACCEPTED = 0
UINT32_BIG = 3000000000  # past 2^31 even: a heap int on the board if it ever became one
LONS = (-1224000000, 1512000000, 1799000000)  # -122.4, 151.2 and 179.9 degrees
# The heap these tests run the vehicle in: the profiles' RAM_BUDGET, the smallest heap
# the whole vehicle needs (bench_mcu.py finds it), so that every change is tried there.
HEAP_KB = 60


@pytest.fixture(params=BOARDS)
def vehicle(request):
    _gate()
    # bench/bench_mcu.py bisects the heap size with MCU_VEHICLE_HEAP_KB.
    heap_kb = int(os.environ.get("MCU_VEHICLE_HEAP_KB", "0")) or HEAP_KB
    with EmulatedBoard(request.param, heap_kb) as b:
        yield b


def _bits_as_float(v):
    return struct.unpack("<f", struct.pack("<I", v))[0]


def _float_bits(f):
    return struct.unpack("<I", struct.pack("<f", f))[0]


def _params(gcs, timeout=30):
    """PARAM_REQUEST_LIST to the end -> {name: PARAM_VALUE}."""
    gcs.mav.param_request_list_send(1, 1)
    got = {}
    deadline = time.time() + timeout
    while time.time() < deadline:
        m = recv(gcs, "PARAM_VALUE", 2.0)
        if m is None:
            continue
        got[m.param_id] = m
        if len(got) == m.param_count:
            break
    return got


def _set(gcs, name, value, ptype):
    gcs.mav.param_set_send(1, 1, name.encode(), value, ptype)
    return recv(gcs, "PARAM_VALUE", 5.0, lambda m: m.param_id == name)


def _read(gcs, name):
    gcs.mav.param_request_read_send(1, 1, name.encode(), -1)
    return recv(gcs, "PARAM_VALUE", 5.0, lambda m: m.param_id == name)


def _mission(n=100):
    items = []
    for i in range(n):
        lon = LONS[i % 3] + 17 * i
        lat = (-337000000 if i % 2 else 473977420) + 11 * i
        z = -400.0 if i % 10 == 0 else float(10 + i)
        items.append(Item(3 if i % 10 else 0, 16, 0, 1, 0.0, 2.0, 0.0, 0.0, lat, lon, z))
    return items


def _rate(gcs, msg_type, seconds=4.0):
    """Messages of a type per second, by the vehicle's own time_boot_ms."""
    times = []
    deadline = time.time() + seconds
    while time.time() < deadline:
        m = recv(gcs, msg_type, 1.0)
        if m is not None:
            times.append(m.time_boot_ms)
    assert len(times) > 3, msg_type
    return (len(times) - 1) * 1000.0 / (times[-1] - times[0]), times


def _board_params():
    import sys

    boards = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "boards")
    sys.path.insert(0, boards)
    try:
        # The emulated boards' table (the unix vehicle's, adapted), readable: the boards
        # freeze it compiled (qemu_params_block.py).
        from qemu_params import PARAMS
    finally:
        sys.path.remove(boards)
    return PARAMS


def test_whole_vehicle_heap_locked(vehicle):
    gcs = vehicle.start_vehicle()
    gcs.mav.heartbeat_send(6, 8, 0, 0, 0)

    # Parameters: all of them, a REAL32 and a uint32 past 2^30 set, saved, reloaded.
    params = _params(gcs)
    assert len(params) == len(_board_params()), sorted(params)  # the unix vehicle's table, 101 now
    assert _set(gcs, "SIM_SPEED", 7.25, 9).param_value == 7.25
    v = _set(gcs, "BRD_SERIAL_NUM", _bits_as_float(UINT32_BIG), 5)  # MAV_PARAM_TYPE_UINT32
    assert v is not None and _float_bits(v.param_value) == UINT32_BIG
    assert run(gcs, 245, 1.0) == MAV_RESULT_ACCEPTED  # save
    assert _set(gcs, "SIM_SPEED", 3.0, 9).param_value == 3.0
    assert _float_bits(_set(gcs, "BRD_SERIAL_NUM", _bits_as_float(5), 5).param_value) == 5
    assert run(gcs, 245, 0.0) == MAV_RESULT_ACCEPTED  # reload what was saved
    assert _read(gcs, "SIM_SPEED").param_value == 7.25
    assert _float_bits(_read(gcs, "BRD_SERIAL_NUM").param_value) == UINT32_BIG

    # A 100-item mission up and down: longitudes past +-107 degrees, -400 m.
    items = _mission()
    client = MissionClient(gcs)
    assert client.upload(items) == 0  # MAV_MISSION_ACCEPTED
    back = client.download()
    assert back is not None and len(back) == 100
    for a, b in zip(items, back):
        assert (a.x, a.y, a.z, a.frame, a.command) == (b.x, b.y, b.z, b.frame, b.command)

    # Arm and disarm.
    assert run(gcs, 400, 1.0) == MAV_RESULT_ACCEPTED
    hb = recv(gcs, "HEARTBEAT", 3.0, lambda h: h.get_srcSystem() == 1 and h.base_mode & 128)
    assert hb is not None
    assert run(gcs, 400, 0.0) == MAV_RESULT_ACCEPTED

    # Streams at the rates asked for.
    assert run(gcs, 511, 30, 100000) == MAV_RESULT_ACCEPTED  # ATTITUDE at 10 Hz
    assert run(gcs, 511, 33, 200000) == MAV_RESULT_ACCEPTED  # GLOBAL_POSITION_INT at 5 Hz
    recv(gcs, "ATTITUDE", 2.0)
    hz, _ = _rate(gcs, "ATTITUDE")
    assert 9.0 <= hz <= 11.0, hz
    hz, _ = _rate(gcs, "GLOBAL_POSITION_INT")
    assert 4.5 <= hz <= 5.5, hz

    # The time of day, from the ground station's SYSTEM_TIME.
    now_us = int(time.time() * 1e6)
    gcs.mav.system_time_send(now_us, 0)
    t = recv(gcs, "SYSTEM_TIME", 5.0, lambda m: m.time_unix_usec > 0)
    assert t is not None and abs(t.time_unix_usec - now_us) < 5e6  # today, to a few seconds

    # Still alive, and nothing was refused for lack of heap.
    assert recv(gcs, "HEARTBEAT", 3.0, lambda h: h.get_srcSystem() == 1) is not None
    assert "MemoryError" not in vehicle.console()


def test_uptime_past_2_30_ms_heap_locked(vehicle):
    """An uptime of 12.7 days: time_boot_ms past 2^30, time_usec past 2^40."""
    offset = 1100000000
    gcs = vehicle.start_vehicle({"uptime_offset_ms": offset})
    gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
    t = recv(gcs, "SYSTEM_TIME", 5.0)
    assert t is not None and offset <= t.time_boot_ms < offset + 60000
    a = recv(gcs, "ATTITUDE", 5.0)
    assert a is not None and a.time_boot_ms >= offset
    g = recv(gcs, "GPS_RAW_INT", 5.0)
    assert g is not None and offset * 1000 <= g.time_usec < (offset + 60000) * 1000
    command(gcs, 512, 24)  # REQUEST_MESSAGE works past it too
    assert recv(gcs, "COMMAND_ACK", 5.0, lambda m: m.command == 512).result == MAV_RESULT_ACCEPTED
    assert recv(gcs, "HEARTBEAT", 3.0, lambda h: h.get_srcSystem() == 1) is not None
    assert "MemoryError" not in vehicle.console()


def test_reboot_keeps_saved_parameters(vehicle):
    """PREFLIGHT_REBOOT_SHUTDOWN 1: the M0 restarts the vehicle in place (one vehicle in
    the heap at a time), the M3 resets by its watchdog (main.py starts again); its UART
    is read by the new one only, and what was saved to the RAM storage is there after
    the restart."""
    gcs = vehicle.start_vehicle()
    assert _set(gcs, "SIM_SPEED", 8.5, 9).param_value == 8.5
    assert run(gcs, 245, 1.0) == MAV_RESULT_ACCEPTED
    assert run(gcs, 246, 1.0) == MAV_RESULT_ACCEPTED
    time.sleep(2)
    assert recv(gcs, "HEARTBEAT", 5.0, lambda h: h.get_srcSystem() == 1) is not None
    got = None
    for _ in range(3):
        got = _read(gcs, "SIM_SPEED")
        if got is not None:
            break
    assert got is not None and got.param_value == 8.5
    assert "MemoryError" not in vehicle.console()
