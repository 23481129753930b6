"""package.json: mavstack as MicroPython's `mip` installs it. The committed file is what
host_tools/mip_package.py makes of today's tree; and `mpremote mip install` from that local
path puts a working vehicle on the emulated Cortex-M3 board with a filesystem (the firmware
`mavctl flash` writes to, nothing of mavstack frozen in), beside a board profile copied as
board.py: after a soft reset it runs main.py, sends HEARTBEAT and answers a parameter read.
"""
import os
import re
import struct
import subprocess
import sys
import time

import pytest

from conftest import PYTHON, ROOT
from test_mcu import _gate

sys.path.insert(0, os.path.join(ROOT, "mcu"))
sys.path.insert(0, os.path.join(ROOT, "host_tools"))
import firmware  # noqa: E402
from mavctl.flash_device import Board, wait_heartbeat  # noqa: E402

MPREMOTE = os.path.join(ROOT, ".venv", "bin", "mpremote")


def test_committed_package_json_is_current():
    r = subprocess.run([PYTHON, os.path.join(ROOT, "host_tools", "mip_package.py"), "--check"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.fixture(scope="module")
def board():
    """The board with a filesystem, freshly powered (an empty /flash): (REPL pty, MAVLink pty)."""
    _gate()
    elf = firmware.build_with_filesystem("qemu_m3")
    proc = subprocess.Popen(firmware.qemu_command("qemu_m3", elf, ["pty", "pty"]),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    ptys = []
    try:
        while len(ptys) < 2:
            line = proc.stdout.readline()
            assert line, "qemu exited: %s" % proc.poll()
            m = re.search(r"(/dev/pts/\d+)", line)
            if m:
                ptys.append(m.group(1))
        yield ptys
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def mpremote(port, *args, timeout=600):
    r = subprocess.run([MPREMOTE, "connect", port] + [str(a) for a in args], capture_output=True,
                       text=True, timeout=timeout, cwd=ROOT)
    assert r.returncode == 0 and "Traceback" not in r.stdout + r.stderr, (r.stdout, r.stderr)
    return r.stdout


def test_mip_install_from_the_checkout_runs_the_vehicle(board):
    repl_pty, mav_pty = board
    out = mpremote(repl_pty, "mip", "install", "--target", "/flash", os.path.join(ROOT, "package.json"))
    assert "Installing: /flash/mavstack/endpoint.py" in out, out
    # The board's profile as board.py, and the sibling modules it imports (BOARD_MODULES).
    boards = os.path.join(ROOT, "boards")
    mpremote(repl_pty, "fs", "cp", os.path.join(boards, "qemu_m3.py"), ":/flash/board.py", "+",
             "fs", "cp", os.path.join(boards, "qemu.py"), ":/flash/qemu.py", "+",
             "fs", "cp", os.path.join(boards, "qemu_params_block.py"), ":/flash/qemu_params_block.py")
    b = Board(repl_pty).open()
    try:
        listing = b.exec("import os\nprint(sorted(os.listdir('/flash')), len(os.listdir('/flash/mavstack')))")
        assert "'main.py'" in listing and "'mavstack'" in listing and "'board.py'" in listing, listing
        b.reset()  # a soft reset to the friendly REPL: main.py runs from /flash
        hb, lines = wait_heartbeat(mav_pty, 240, b)
        # The REPL's UART is read apart from MAVLink's: on a busy machine its line may come
        # later than the first HEARTBEAT, and than wait_heartbeat's moment more.
        end = time.time() + 10
        while not any("qemu_m3 ready" in line for line in lines) and time.time() < end:
            time.sleep(0.2)
            lines += [line.strip() for line in b.console().splitlines() if line.strip()]
    finally:
        b.close()
    assert hb.type == 10 and hb.autopilot == 0  # boards/qemu.py: a ground rover, generic
    assert any("qemu_m3 ready" in line for line in lines), lines
    from pymavlink import mavutil

    m = mavutil.mavlink_connection(mav_pty, baud=115200, source_system=255, source_component=190,
                                   dialect="common", autoreconnect=False)
    try:
        value = None
        for _ in range(5):
            m.mav.param_request_read_send(1, 1, b"MAV_SYS_ID", -1)
            value = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=5)
            if value is not None:
                break
        assert value is not None and value.param_id == "MAV_SYS_ID"
        # bytewise (the profile's PARAM_ENCODING): the uint8's bytes in the float's place
        assert struct.unpack("<I", struct.pack("<f", value.param_value))[0] == 1
    finally:
        m.close()
