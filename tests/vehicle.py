"""The unix vehicle as a real process, and a pymavlink ground station talking to it:
what the end-to-end tests and the benchmarks drive."""
import os
import socket
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
MICROPYTHON = os.path.join(ROOT, ".venv", "bin", "micropython")
os.environ.setdefault("MAVLINK20", "1")


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Vehicle:
    """`micropython firmware/main.py --board unix ...` in a subprocess.

    By default it listens (udpin) on a free port; `gcs()` connects a pymavlink
    client to it. Extra links and options pass straight to main.py.
    """

    def __init__(self, storage, board="unix", links=None, args=(), env=None, heapsize=None):
        self.storage = str(storage)
        self.port = free_udp_port()
        self.links = links or ["udpin:127.0.0.1:%d" % self.port]
        self.board = board
        self.args = list(args)
        self.env = env
        self.heapsize = heapsize
        self.proc = None
        self._gcs = []

    def start(self):
        cmd = [MICROPYTHON]
        if self.heapsize:
            cmd += ["-X", "heapsize=%s" % self.heapsize]
        cmd += [os.path.join(FIRMWARE, "main.py"), "--board", self.board, "--storage", self.storage]
        for link in self.links:
            cmd += ["--link", link]
        cmd += self.args
        env = dict(os.environ)
        env["MICROPYPATH"] = os.pathsep.join([FIRMWARE, os.path.join(ROOT, "boards"), ".frozen"])
        env.update(self.env or {})
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        return self

    def gcs(self, version=2, source_system=255, source_component=190, port=None, wait=True, dialect="common"):
        """A pymavlink connection to this vehicle's udpin link, heartbeat seen."""
        from pymavlink import mavutil

        os.environ["MAVLINK20"] = "1"
        m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % (port or self.port),
                                       source_system=source_system,
                                       source_component=source_component,
                                       dialect=dialect)
        if version == 1:
            # pymavlink packs by its module's protocol version: force MAVLink 1 on every send.
            send = m.mav.send
            m.mav.send = lambda msg, force_mavlink1=False: send(msg, force_mavlink1=True)
        self._gcs.append(m)
        if wait:
            deadline = time.time() + 20
            while time.time() < deadline:
                m.mav.heartbeat_send(6, 8, 0, 0, 0)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID
                hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
                if hb is not None:
                    m.target_system = hb.get_srcSystem()
                    m.target_component = hb.get_srcComponent()
                    return m
                self.check_alive()
            raise AssertionError("no HEARTBEAT from the vehicle\n" + self.output())
        return m

    def check_alive(self):
        if self.proc.poll() is not None:
            raise AssertionError("vehicle exited with %s\n%s" % (self.proc.returncode, self.output()))

    def output(self):
        if self.proc.poll() is None:
            return "(running)"
        return self.proc.stdout.read()

    def stop(self, sig=None):
        for m in self._gcs:
            try:
                m.close()
            except Exception:
                pass
        self._gcs = []
        if self.proc and self.proc.poll() is None:
            if sig is None:
                self.proc.terminate()
            else:
                self.proc.send_signal(sig)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def kill(self):
        self.proc.kill()
        self.proc.wait()


def recv(m, type, timeout=5.0, cond=None):
    """Next message of a type (or list of types) matching cond, else None."""
    deadline = time.time() + timeout
    while True:
        left = deadline - time.time()
        if left <= 0:
            return None
        msg = m.recv_match(type=type, blocking=True, timeout=left)
        if msg is not None and (cond is None or cond(msg)):
            return msg
