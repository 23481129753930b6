"""The emulated Cortex-M0 as a distance-sensor peripheral (boards/qemu_m0_rangefinder.py:
the peripheral, params and commands services, the heap locked once up), a pymavlink peer
on its one UART playing the autopilot (system 7) and a ground station: silent until the
autopilot's HEARTBEAT, then its own HEARTBEAT as component 158 with system 7,
DISTANCE_SENSOR at 10 Hz, its parameters listed for component 0 and set and read by
component, REQUEST_MESSAGE and the application's command answered, arming refused as
unsupported. The UART is a pty QEMU names, opened the way a host program would
(EmulatedBoard.start_peripheral). Prints the heap the peripheral holds."""
import os
import re
import time

from conftest import recv
from mcu_rig import EmulatedBoard
from test_mcu import _gate

BOARD = "qemu_m0_rangefinder"
COMPID = 158


def _autopilot_heartbeat(m):
    m.mav.srcSystem, m.mav.srcComponent = 7, 1
    m.mav.heartbeat_send(2, 3, 0, 0, 3)
    m.mav.srcSystem, m.mav.srcComponent = 255, 190


def test_rangefinder_peripheral_on_the_m0():
    _gate()
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    # bench/bench_mcu.py bisects the heap size with MCU_PERIPHERAL_HEAP_KB.
    heap_kb = int(os.environ.get("MCU_PERIPHERAL_HEAP_KB", "0")) or EmulatedBoard.DEFAULT_HEAP_KB
    with EmulatedBoard(BOARD, heap_kb) as b:
        pty, ready = b.start_peripheral()
        held = re.search(r"ready, (\d+) KB of heap in use \(budget (\d+) KB\)", ready)
        assert held and int(held.group(1)) <= int(held.group(2)), ready
        print("%s: %s" % (BOARD, ready))
        m = mavutil.mavlink_connection(pty, baud=115200, source_system=255, source_component=190)
        try:
            # Nothing before the autopilot is heard: a ground station's HEARTBEAT is not one.
            end = time.time() + 2.0
            while time.time() < end:
                m.mav.heartbeat_send(6, 8, 0, 0, 0)
                assert recv(m, "HEARTBEAT", 0.4) is None
            hb = None
            end = time.time() + 10
            while hb is None and time.time() < end:
                _autopilot_heartbeat(m)
                hb = recv(m, "HEARTBEAT", 0.5, lambda h: h.get_srcComponent() == COMPID)
            assert hb is not None and hb.get_srcSystem() == 7 and hb.autopilot == 8
            # DISTANCE_SENSOR at RNGFND_RATE_HZ (10), by the board's own time_boot_ms.
            times = []
            end = time.time() + 3
            while time.time() < end:
                ds = recv(m, "DISTANCE_SENSOR", 1)
                if ds is not None:
                    assert ds.get_srcSystem() == 7 and ds.get_srcComponent() == COMPID
                    assert 100 <= ds.current_distance <= 400
                    times.append(ds.time_boot_ms)
            rate = (len(times) - 1) * 1000.0 / (times[-1] - times[0])
            assert 8 < rate < 12, rate
            # Parameters for component 0: its own five, from its own component id.
            m.mav.param_request_list_send(7, 0)
            got = {}
            end = time.time() + 10
            while time.time() < end and (not got or len(got) < 5):
                p = recv(m, "PARAM_VALUE", 1)
                if p is not None:
                    assert p.get_srcComponent() == COMPID and p.param_count == 5
                    got[p.param_id] = p
            assert sorted(got) == ["RNGFND_MAX_CM", "RNGFND_MIN_CM", "RNGFND_ORIENT", "RNGFND_RATE_HZ", "RNGFND_TYPE"]
            m.mav.param_set_send(7, COMPID, b"RNGFND_MAX_CM", 550.0, 9)
            p = recv(m, "PARAM_VALUE", 3, lambda p: p.param_id == "RNGFND_MAX_CM")
            assert p is not None and p.param_value == 550.0
            m.mav.param_request_read_send(7, COMPID, b"RNGFND_MAX_CM", -1)
            p = recv(m, "PARAM_VALUE", 3, lambda p: p.param_id == "RNGFND_MAX_CM")
            assert p is not None and p.param_value == 550.0
            assert recv(m, "DISTANCE_SENSOR", 3, lambda d: d.max_distance == 550) is not None
            # Commands addressed to it.
            m.mav.command_long_send(7, COMPID, 512, 0, 132, 0, 0, 0, 0, 0, 0)
            ack = recv(m, "COMMAND_ACK", 3, lambda a: a.command == 512)
            assert ack is not None and ack.result == 0 and ack.get_srcComponent() == COMPID
            m.mav.command_long_send(7, COMPID, 400, 0, 1, 0, 0, 0, 0, 0, 0)
            ack = recv(m, "COMMAND_ACK", 3, lambda a: a.command == 400)
            assert ack is not None and ack.result == 3  # UNSUPPORTED: no arming here
            m.mav.command_long_send(7, COMPID, 31010, 0, 0, 0, 0, 0, 0, 0, 0)  # pause
            ack = recv(m, "COMMAND_ACK", 3, lambda a: a.command == 31010)
            assert ack is not None and ack.result == 0
            hb = recv(m, "HEARTBEAT", 3, lambda h: h.get_srcComponent() == COMPID)
            assert hb is not None  # still alive, heap locked all along
        finally:
            m.close()


def test_the_unix_vehicle_on_the_m0_peripherals_pty(tmp_path):
    """What the end-to-end test through a routing vehicle builds on: the unix vehicle opens
    the emulated M0's UART pty as a serial link (`--link serial:PTY:115200`); the
    peripheral hears its HEARTBEAT and takes its system id (5), which it still stamps on
    its frames once the vehicle has gone and pymavlink opens the pty instead."""
    _gate()
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil
    from vehicle import Vehicle

    with EmulatedBoard(BOARD) as b:
        pty, _ready = b.start_peripheral()
        v = Vehicle(tmp_path / "storage", links=["serial:%s:115200" % pty], args=["--sysid", "5"]).start()
        try:
            time.sleep(4)  # a few of the vehicle's HEARTBEATs (1 Hz) reach the peripheral
            v.check_alive()
        finally:
            v.stop()
        m = mavutil.mavlink_connection(pty, baud=115200, source_system=255, source_component=190)
        try:
            hb = recv(m, "HEARTBEAT", 5, lambda h: h.get_srcComponent() == COMPID)
            assert hb is not None and hb.get_srcSystem() == 5 and hb.autopilot == 8
        finally:
            m.close()
