"""The vehicle the MicroPython engine fuzzes: the unix port running `firmware/main.py` with
the `make run` board (boards/unix.py) and message signing added, its simulator as
application, listening on a udpin link, storing under a directory of its own; one
process per dialect (`--set dialect=seed2012` for the seed's).

A thread reads its console. What it says is kept: every start (the "ready" line, again
after a reboot), every contained fault ("mavstack: Fault: ..."), and anything that looks
like a traceback or an exit, which the engine treats as a failure.
"""
import os
import signal
import subprocess
import threading
import time

from vehicle import free_udp_port  # tests/ is on the path (engine.py, pytest)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
MICROPYTHON = os.path.join(ROOT, ".venv", "bin", "micropython")

BOARD = '''"""The unix vehicle with message signing, set up from any link (the fuzzer's board)."""
from unix import *  # noqa: F401,F403
import unix

NAME = "unix_fuzz"
SERVICES = ("signing",) + unix.SERVICES
'''
BAD = ("Traceback (most recent call last)", "MemoryError")  # console words of a failure


class UnixVehicle:
    def __init__(self, work, dialect="common", options=()):
        self.dialect = dialect
        self.storage = os.path.join(work, "storage-" + dialect)
        self.boards = os.path.join(work, "boards")
        os.makedirs(self.storage, exist_ok=True)
        os.makedirs(self.boards, exist_ok=True)
        with open(os.path.join(self.boards, "unix_fuzz.py"), "w") as f:
            f.write(BOARD)
        self.options = list(options)
        self.port = free_udp_port()
        self.proc = None
        self.lines = []  # the console, line by line
        self.starts = 0  # "ready" lines: 1 + reboots
        self.faults = []  # (time, line) of each "mavstack: Fault:" line
        self.bad = []  # lines that say something escaped
        self._lock = threading.Lock()

    def start(self, timeout=20):
        cmd = [MICROPYTHON, os.path.join(ROOT, "firmware", "main.py"), "--board", "unix_fuzz",
               "--storage", self.storage, "--link", "udpin:127.0.0.1:%d" % self.port]
        if self.dialect != "common":
            cmd += ["--set", "dialect=" + self.dialect]
        for opt in self.options:
            cmd += ["--set", opt]
        env = dict(os.environ)
        env["MICROPYPATH"] = os.pathsep.join([self.boards, os.path.join(ROOT, "firmware"),
                                              os.path.join(ROOT, "boards"), ".frozen"])
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, errors="replace")
        threading.Thread(target=self._read, daemon=True).start()
        deadline = time.time() + timeout
        while self.starts == 0:
            if time.time() > deadline or self.proc.poll() is not None:
                raise RuntimeError("the %s vehicle did not start:\n%s" % (self.dialect, self.console()))
            time.sleep(0.01)
        return self

    def _read(self):
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            with self._lock:
                self.lines.append(line)
                if line.startswith("mavstack: ") and " ready, " in line:
                    self.starts += 1
                elif line.startswith("mavstack: Fault: "):
                    self.faults.append((time.time(), line[len("mavstack: "):]))
                elif any(word in line for word in BAD):
                    self.bad.append(line)

    def console(self, last=60):
        with self._lock:
            return "\n".join(self.lines[-last:])

    def trouble(self):
        """None while the process runs and has printed nothing bad, else what is wrong."""
        if self.bad:
            return "the %s vehicle printed:\n%s" % (self.dialect, self.console())
        if self.proc.poll() is not None:
            return "the %s vehicle exited (status %s):\n%s" % (self.dialect, self.proc.returncode, self.console())
        return None

    def stop(self, timeout=10):
        """SIGINT, as Ctrl-C ends `make run` -> its exit status."""
        if self.proc is None or self.proc.poll() is not None:
            return self.proc.returncode if self.proc else None
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        return self.proc.returncode
