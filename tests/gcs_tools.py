"""Ground-station moves shared by the end-to-end tests (pymavlink against the unix vehicle)."""
import contextlib
import os
import queue
import re
import socket
import subprocess
import threading
import time

from conftest import PYTHON, ROOT, free_udp_port, recv

MAVPROXY = os.path.join(ROOT, ".venv", "bin", "mavproxy.py")


class UdpSender:
    """A thread sending datagrams to the vehicle's udpin port from an address of its own,
    until the `with` block ends: a subclass's _run() sends from self._sock while
    self._stop is not set, counting in self.sent."""

    def __init__(self, port):
        self.port = port
        self.sent = 0
        self._stop = threading.Event()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1", 0))
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._sock.close()

MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3
MAV_RESULT_FAILED = 4


def start(vehicle, *args, **kw):
    """A unix vehicle with extra main.py arguments (e.g. "--set", "arm_veto=1")."""
    return vehicle(args=list(args), **kw)


def command(m, cmd, *params, target=None, confirmation=0):
    """COMMAND_LONG with params 1..7 (missing ones 0) to target (system, component)."""
    ts, tc = target if target is not None else (m.target_system, m.target_component)
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(ts, tc, cmd, confirmation, *p)


def ack(m, cmd, timeout=5.0):
    return recv(m, "COMMAND_ACK", timeout, lambda a: a.command == cmd)


def run(m, cmd, *params, **kw):
    """Send a command and return its COMMAND_ACK's result (None: no ACK)."""
    timeout = kw.pop("timeout", 5.0)
    command(m, cmd, *params, **kw)
    a = ack(m, cmd, timeout)
    return None if a is None else a.result


def listen(m, type, timeout=5.0, cond=None, beat=0.5):
    """recv() that keeps sending GCS heartbeats, so the vehicle keeps hearing us."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        msg = recv(m, type, min(beat, max(0.01, deadline - time.time())), cond)
        if msg is not None:
            return msg
    return None


def vehicle_heartbeat(m, cond=None, timeout=5.0):
    return listen(m, "HEARTBEAT", timeout,
                  lambda h: h.get_srcSystem() == m.target_system and h.get_srcComponent() == 1
                  and (cond is None or cond(h)))


def request(m, msgid, timeout=5.0):
    """REQUEST_MESSAGE msgid -> (ack result, the message or None)."""
    from pymavlink.dialects.v20 import common

    name = common.mavlink_map[msgid].msgname
    command(m, 512, msgid)
    a = ack(m, 512, timeout)
    msg = recv(m, name, timeout) if a is not None and a.result == MAV_RESULT_ACCEPTED else None
    return (None if a is None else a.result), msg


def ardupilot_station(m):
    """The pymavlink station m does what MAVProxy and Mission Planner do on connecting:
    REQUEST_DATA_STREAM, ArduPilot's way to ask for telemetry. From then on the vehicle
    reads and reports modes by ArduPilot's numbers on its link, and its integers C-cast
    (services/status/conventions.py)."""
    m.mav.request_data_stream_send(m.target_system, m.target_component, 0, 4, 1)
    return m


def px4_station(m):
    """The pymavlink station m does what MAVSDK does on connecting: REQUEST_MESSAGE
    AUTOPILOT_VERSION with NaN in the parameters it does not use. From then on its link
    reads and sets modes PX4's way (main and sub mode), its integers bytewise."""
    nan = float("nan")
    m.mav.command_long_send(m.target_system, m.target_component, 512, 0, 148, nan, nan, nan, nan, nan, nan)
    ack(m, 512)
    return m


def statustext(m, contains, timeout=5.0):
    return listen(m, "STATUSTEXT", timeout, lambda s: contains in s.text)


def two_links(vehicle, *args):
    """A vehicle with a link for the ground station under test and one for pymavlink."""
    ports = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p for p in ports], args=list(args))
    return v, ports[0], v.gcs(port=ports[1])


class MavProxy:
    """MAVProxy as a user runs it, typing commands; its output read line by line."""

    def __init__(self, port, tmp_path, modules):
        cmd = [PYTHON, MAVPROXY, "--master=udpout:127.0.0.1:%d" % port,
               "--default-modules=" + modules, "--state-basedir=%s" % tmp_path, "--no-state"]
        self.proc = subprocess.Popen(cmd, cwd=str(tmp_path), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines = queue.Queue()
        self.seen = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.put(line)

    def say(self, line):
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def expect(self, pattern, timeout=20):
        deadline = time.time() + timeout
        while time.time() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                continue
            self.seen.append(line)
            found = re.search(pattern, line)
            if found:
                return found
        raise AssertionError("MAVProxy never printed %r:\n%s" % (pattern, "".join(self.seen)))

    def close(self):
        try:
            self.proc.stdin.close()  # end of input: MAVProxy stops
            self.proc.wait(10)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()


@contextlib.contextmanager
def mavsdk_system(port, identity=None):
    """MAVSDK as a ground station sending to the vehicle's udpin port: yields its System.
    identity (sysid, compid) replaces its own 245/190, as `mavsdk_server --sysid 255
    --compid 1` does (a ground station still: its heartbeats say MAV_TYPE_GCS)."""
    import mavsdk

    config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    if identity is not None:
        config.system_id, config.component_id = identity
    sdk = mavsdk.Mavsdk(config)
    try:
        sdk.add_any_connection("udpout://127.0.0.1:%d" % port)
        system = sdk.first_autopilot(20.0)
        assert system is not None, "MAVSDK found no autopilot"
        system.sdk = sdk  # (what else it sees: system.sdk.get_systems())
        yield system
    finally:
        sdk.destroy()
