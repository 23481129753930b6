"""mavctl watch (the live view on a terminal and in a pipe, line output, --tlog read back by
pymavlink's mavlogdump and mavutil) and mavctl signing (MAVProxy's key from a passphrase,
key files, the current key, the links the board trusts), against the unix vehicle over UDP."""
import hashlib
import os
import select
import signal
import struct
import subprocess
import threading
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from conftest import PYTHON, ROOT, free_udp_port, recv
from mavctl_tools import check_png, mavctl, mavctl_cli_run, mavproxy_key, ok, refused, signed_board
from relay import LossyRelay

RADIO = (51, 68)  # a SiK radio's system and component id


class RadioRelay(LossyRelay):
    """A lossy link whose radio reports RADIO_STATUS to the ground station twice a second."""

    def __init__(self, vehicle_port, rate):
        LossyRelay.__init__(self, vehicle_port, rate=rate, drop_only=True, seed=3)
        self.mav = mavlink.MAVLink(None, srcSystem=RADIO[0], srcComponent=RADIO[1])
        self._radio = threading.Thread(target=self._report, daemon=True)
        self._radio.start()

    def _report(self):
        while not self._stop:
            if self.gcs is not None:
                # rssi, remrssi, txbuf, noise, remnoise, rxerrors, fixed
                frame = self.mav.radio_status_encode(201, 187, 93, 41, 39, 7, 3).pack(self.mav)
                self.send(self.gcs_sock, frame, self.gcs)
            time.sleep(0.5)


@pytest.fixture
def gcs_link_port(vehicle):
    """A vehicle sending (udpout) to a port each mavctl run listens on (udpin)."""

    def start(**kw):
        port = free_udp_port()
        return vehicle(links=["udpout:127.0.0.1:%d" % port], **kw), "udpin:127.0.0.1:%d" % port

    return start


def view_blocks(out):
    """The views a `watch --view` printed in a pipe, each as {first word: line}."""
    blocks = []
    for block in out.split("mavctl watch: ")[1:]:
        lines = {}
        for line in block.splitlines()[1:]:
            if line and not line.startswith(" "):
                lines.setdefault(line.split()[0], line)
        blocks.append(lines)
    return blocks


def test_watch_view_in_a_pipe_shows_radio_and_measured_drops(vehicle):
    v = vehicle()
    relay = RadioRelay(v.port, rate=0.25)
    try:
        out = ok(mavctl("udpout:127.0.0.1:%d" % relay.port, "watch", "--view", "--seconds", "4"))
    finally:
        relay.close()
    blocks = view_blocks(out)
    assert len(blocks) >= 3, out  # once a second, and once at the end
    last = blocks[-1]
    assert "\x1b" not in out  # no terminal codes in a pipe
    assert last["mode"].split()[1:3] == ["STABILIZE", "disarmed"], last["mode"]
    assert "47.39" in last["position"] and "above home" in last["position"]
    assert last["battery"].split()[2] == "V"
    assert "3D fix" in last["gps"] and "12 satellites" in last["gps"]
    assert "rssi 201/187" in last["radio"] and "noise 41/39" in last["radio"]
    assert "rx errors 7" in last["radio"] and "fixed 3" in last["radio"]
    # About a quarter of the vehicle's frames dropped by the relay; measured from sequence numbers.
    overall = float(last["link"].split(",")[1].split("%")[0])
    assert 12 <= overall <= 40, last["link"]
    assert relay.stats["dropped"] > 0
    assert last["MESSAGE"].split() == ["MESSAGE", "COUNT", "HZ"]
    attitude = [line for line in out.splitlines() if line.startswith("ATTITUDE ")][-1]
    assert 2 <= float(attitude.split()[2]) <= 10  # 10 Hz less a quarter (less on a loaded machine)
    v.check_alive()


def test_watch_live_view_on_a_terminal_until_ctrl_c(vehicle, tmp_path):
    """On a tty the view is drawn in place (cursor home, lines cleared) until Ctrl-C, which
    ends the run with status 0, the cursor given back and the tlog complete; the vehicle's
    STATUSTEXT is among the last messages."""
    port = free_udp_port()
    v = vehicle(links=["udpout:127.0.0.1:%d" % port])
    tlog = tmp_path / "tty.tlog"
    master, slave = os.openpty()
    proc = subprocess.Popen([PYTHON, "-m", "mavctl", "--connect", "udpin:127.0.0.1:%d" % port, "watch",
                             "--tlog", tlog], cwd=ROOT, stdout=slave, stderr=subprocess.PIPE,
                            env=dict(os.environ, COLUMNS="120", LINES="40"))
    os.close(slave)
    out = b""
    interrupted = False
    deadline = time.time() + 60
    while time.time() < deadline:
        if not interrupted and out.count(b"\x1b[H") >= 5 and b"GCS heard on" in out.split(b"\x1b[H")[-1]:
            proc.send_signal(signal.SIGINT)  # what Ctrl-C on the terminal sends
            interrupted = True
        ready, _, _ = select.select([master], [], [], 0.5)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the other side has gone
                break
            if not chunk:
                break
            out += chunk
        elif proc.poll() is not None:
            break
    os.close(master)
    assert interrupted, out
    status = proc.wait(30)
    err = proc.stderr.read().decode()
    assert status == 0 and "Traceback" not in err, err
    text = out.decode("utf-8", "replace")
    assert "\x1b[K" in text and text.rstrip().endswith("\x1b[?25h")
    last = text.split("\x1b[H")[-1]
    assert "STABILIZE  disarmed" in last and "3D fix" in last
    assert "GCS heard on udpout" in last  # a STATUSTEXT
    assert "GLOBAL_POSITION_INT" in last  # the rate table
    assert "frames logged to" in err
    log = mavutil.mavlink_connection(str(tlog))
    assert sum(1 for _ in iter(lambda: log.recv_match(type="HEARTBEAT"), None)) >= 3
    v.check_alive()


def test_watch_lines_and_a_tlog_pymavlink_reads_back(gcs_link_port, tmp_path):
    v, link = gcs_link_port()
    tlog = tmp_path / "flight.tlog"
    t0 = time.time()
    out = ok(mavctl(link, "watch", "HEARTBEAT", "SYS_STATUS", "--seconds", "2.5", "--tlog", tlog))
    t1 = time.time()
    lines = out.splitlines()
    assert sum(line.startswith("HEARTBEAT {type : 2,") for line in lines) >= 2
    assert all(line.split()[0] in ("HEARTBEAT", "SYS_STATUS") for line in lines)
    raw = tlog.read_bytes()
    usec = struct.unpack(">Q", raw[:8])[0]
    assert t0 - 1 <= usec / 1e6 <= t1 and raw[8] in (0xFD, 0xFE)  # big-endian us, then the frame
    # mavutil reads it as a log: every message, not only those printed, and ours too.
    log = mavutil.mavlink_connection(str(tlog))
    kinds, stamps, ours = {}, [], 0
    while True:
        m = log.recv_match()
        if m is None:
            break
        kinds[m.get_type()] = kinds.get(m.get_type(), 0) + 1
        stamps.append(m._timestamp)
        ours += m.get_srcSystem() == 255
    assert kinds["HEARTBEAT"] >= 4 and kinds["ATTITUDE"] >= 15 and kinds["GLOBAL_POSITION_INT"] >= 8
    assert ours >= 2 and stamps == sorted(stamps) and t0 - 1 <= stamps[0] and stamps[-1] <= t1
    # pymavlink's mavlogdump, as a user runs it.
    dump = subprocess.run([os.path.join(ROOT, ".venv", "bin", "mavlogdump.py"), "--types", "GPS_RAW_INT",
                           str(tlog)], capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0, dump.stderr
    assert sum("GPS_RAW_INT {" in line and "fix_type : 3" in line for line in dump.stdout.splitlines()) >= 3
    # Plotted: a vehicle standing at home (a track of one point, flat lines).
    ok(mavctl(None, "log", "plot", tlog, "--png", tmp_path / "still.png", "--size", "600x450"))
    check_png(tmp_path / "still.png", 600, 450)
    # The rate table.
    rates = ok(mavctl(link, "watch", "--rates", "--seconds", "2")).splitlines()
    assert rates[0].split() == ["MESSAGE", "COUNT", "HZ"]
    hz = {line.split()[0]: float(line.split()[2]) for line in rates[1:]}
    assert 5 <= hz["ATTITUDE"] <= 12
    v.check_alive()


def test_watch_refusals(tmp_path):
    port = free_udp_port()
    link = "udpin:127.0.0.1:%d" % port
    # Found wrong before anything is opened (nothing listens here).
    refused(mavctl_cli_run(link, "watch", "--tlog", tmp_path / "no" / "dir.tlog"), 2, "--tlog")
    refused(mavctl_cli_run(link, "watch", "NOT_A_MESSAGE"), 2, "unknown message")
    refused(mavctl_cli_run(link, "--timeout", "1", "watch"), 5, "no HEARTBEAT")


# --- signing ----------------------------------------------------------------------------

def signs_with(v, key, port=None, seconds=5.0):
    """Does the vehicle sign with key? (a pymavlink station holding key hears its HEARTBEAT
    signed and checked)."""
    m = v.gcs(port=port, wait=False)
    m.setup_signing(key, sign_outgoing=True)
    deadline = time.time() + seconds
    hb = None
    while hb is None and time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)  # a udpin link answers who speaks to it
        hb = recv(m, "HEARTBEAT", 0.5, lambda h: h.get_srcSystem() == 1)
    m.close()
    return hb is not None and hb._signed and m.mav.signing.goodsig_count > 0


def test_signing_setup_and_clear_over_udp(vehicle, tmp_path):
    v = vehicle(board="unix_signed", env={"MICROPYPATH": signed_board(tmp_path)})
    link = "udpout:127.0.0.1:%d" % v.port
    out = ok(mavctl(link, "signing", "setup", "correct horse"))
    assert out.startswith("signing on: key %s" % mavproxy_key("correct horse")[:4].hex())
    assert mavproxy_key("correct horse") == hashlib.sha256(b"correct horse").digest()
    assert signs_with(v, mavproxy_key("correct horse"))
    # Every subcommand signs with the global --key (or --key-file); without it the vehicle
    # answers nothing that checks, so nothing is heard.
    assert "SIM_SPEED" in ok(mavctl(link, "--key", "correct horse", "params", "get", "SIM_SPEED"))
    refused(mavctl(link, "--timeout", "2", "--key", "wrong", "params", "get", "SIM_SPEED"), 5, "HEARTBEAT")
    # Now the key is required: without it, and with a wrong one, refused, key unchanged.
    refused(mavctl(link, "signing", "setup", "other"), 2, "--current")
    refused(mavctl(link, "signing", "setup", "other", "--current", "wrong"), 1, "did not take")
    assert signs_with(v, mavproxy_key("correct horse"))
    # A new key from a file (64 hex digits), signed with the current one.
    key = bytes(range(100, 132))
    (tmp_path / "key.hex").write_text(key.hex() + "\n")
    ok(mavctl(link, "signing", "setup", "--key-file", tmp_path / "key.hex", "--current", "correct horse"))
    assert signs_with(v, key)
    # Clear with the current key given as a raw 32-byte file: unsigned again.
    (tmp_path / "key.bin").write_bytes(key)
    assert "signing off" in ok(mavctl(link, "signing", "clear", "--current-key-file", tmp_path / "key.bin"))
    m = v.gcs()
    hb = recv(m, "HEARTBEAT", 5, lambda h: h.get_srcSystem() == 1)
    assert hb is not None and not hb.get_msgbuf()[2] & 1
    assert "SIM_SPEED" in ok(mavctl(link, "params", "get", "SIM_SPEED"))
    v.check_alive()


def test_signing_only_on_the_trusted_link(vehicle, tmp_path):
    """A board that takes keys on its second link only: the first is refused (and the
    vehicle stays unsigned), the second takes it."""
    radio, usb = free_udp_port(), free_udp_port()
    v = vehicle(board="unix_signed", env={"MICROPYPATH": signed_board(tmp_path, setup_links=(1,))},
                links=["udpin:127.0.0.1:%d" % radio, "udpin:127.0.0.1:%d" % usb])
    r = mavctl("udpout:127.0.0.1:%d" % radio, "signing", "setup", "secret")
    refused(r, 1, "SIGNING_SETUP_LINKS")
    assert not signs_with(v, mavproxy_key("secret"), port=radio, seconds=2.0)
    ok(mavctl("udpout:127.0.0.1:%d" % usb, "signing", "setup", "secret"))
    assert signs_with(v, mavproxy_key("secret"), port=radio)
    v.check_alive()


def test_signing_refusals(tmp_path):
    link = "udpin:127.0.0.1:%d" % free_udp_port()
    refused(mavctl(link, "signing", "setup"), 2, "PASSPHRASE or --key-file")
    (tmp_path / "empty").write_text("\n")
    refused(mavctl(link, "signing", "setup", "--key-file", tmp_path / "empty"), 2, "empty")
    refused(mavctl(link, "signing", "setup", "a", "--key-file", tmp_path / "empty"), 2, "not both")
    refused(mavctl(link, "signing", "setup", "--key-file", tmp_path / "missing"), 2, "missing")
    refused(mavctl(link, "signing", "clear", "--current", ""), 2, "empty passphrase")
    refused(mavctl_cli_run(link, "--timeout", "1", "signing", "setup", "x"), 5, "no HEARTBEAT")


def test_mavproxy_talks_to_the_vehicle_with_the_passphrase_mavctl_gave_it(vehicle, tmp_path):
    """mavctl gives the key from a passphrase; MAVProxy given the same passphrase
    (`signing key`; MAVProxy takes one word) sets a parameter the vehicle now takes only signed."""
    from gcs_tools import MavProxy
    v = vehicle(board="unix_signed", env={"MICROPYPATH": signed_board(tmp_path)})
    ok(mavctl("udpout:127.0.0.1:%d" % v.port, "signing", "setup", "shared-secret"))
    mp = MavProxy(v.port, tmp_path, "signing,param")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("signing key shared-secret")
        mp.say("param fetch")
        mp.expect(r"Received \d+ parameters")
        mp.say("param set SIM_SPEED 8.5")
        check = v.gcs(wait=False)
        check.setup_signing(mavproxy_key("shared-secret"), sign_outgoing=True)
        deadline = time.time() + 20
        value = None
        while value != 8.5 and time.time() < deadline:
            check.mav.param_request_read_send(1, 1, b"SIM_SPEED", -1)
            p = recv(check, "PARAM_VALUE", 1.0, lambda p: p.param_id == "SIM_SPEED")
            value = p.param_value if p is not None else value
        assert value == 8.5
    finally:
        mp.close()
    v.check_alive()
