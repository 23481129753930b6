"""The unix vehicle's watchdog: a process that runs it and starts it again when its poll
loop stops feeding it, as a board's watchdog resets the board.

    .venv/bin/python host_tools/watchdog.py --board unix --link udpin:0.0.0.0:14550 ...

Its arguments are firmware/main.py's. The vehicle (boards/unix.py, watchdog()) feeds it
with datagrams on the port named in MAVSTACK_WATCHDOG_PORT, each giving the timeout
(WATCHDOG_MS); the first arms it. Armed, it starts the vehicle again when no feed came
for the timeout (it kills it first) or when the vehicle ends without a clean stop (an
exception, a signal); a clean stop (exit status 0: a shutdown, a Ctrl-C) ends it too,
with the vehicle's status. A vehicle that ends before arming it is not started again.
MICROPYTHON names the interpreter (default .venv/bin/micropython). Reference:
docs/reliability.md.
"""
import os
import select
import signal
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAIN = os.path.join(ROOT, "firmware", "main.py")


def say(text):
    sys.stdout.write("watchdog: %s\n" % text)
    sys.stdout.flush()


class Watchdog:
    def __init__(self, argv, micropython=None):
        self.cmd = [micropython or os.environ.get("MICROPYTHON")
                    or os.path.join(ROOT, ".venv", "bin", "micropython"), MAIN] + list(argv)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.env = dict(os.environ, MAVSTACK_WATCHDOG_PORT=str(self.sock.getsockname()[1]))
        self.proc = None
        self.stopping = False
        self.restarts = 0

    def run(self):
        """Run the vehicle until it stops cleanly -> its exit status."""
        while True:
            status = self.supervise()
            if status is not None:
                return status
            self.restarts += 1

    def supervise(self):
        """One run of the vehicle -> its exit status when that ends it all, None when it
        must start again."""
        # Its own process group: a Ctrl-C at the terminal reaches the watchdog alone,
        # which passes it on once (stop()).
        self.proc = subprocess.Popen(self.cmd, env=self.env, process_group=0)
        timeout = None  # not armed
        deadline = 0.0
        while True:
            wait = 0.1 if timeout is None else max(0.0, min(0.1, deadline - time.monotonic()))
            if select.select([self.sock], [], [], wait)[0]:
                beat = self.sock.recv(64)
                ms = int(beat) if beat.isdigit() else 0
                if ms == 0:  # the vehicle stops cleanly: no more feeding
                    timeout = None
                else:
                    timeout = ms / 1000.0
                    deadline = time.monotonic() + timeout
            status = self.proc.poll()
            if status is not None:
                if status == 0 or timeout is None or self.stopping:
                    return status
                say("the vehicle ended (status %d): starting it again" % status)
                return None
            if timeout is not None and time.monotonic() > deadline:
                self.proc.kill()
                status = self.proc.wait()
                if self.stopping:
                    return status
                say("no feed for %d ms: starting the vehicle again" % round(timeout * 1000))
                return None

    def stop(self, _signum, _frame):
        """SIGTERM or SIGINT: the vehicle stops (it gets a SIGINT: a clean stop), and so
        does the watchdog."""
        self.stopping = True
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)


def main(argv):
    dog = Watchdog(argv)
    signal.signal(signal.SIGTERM, dog.stop)
    signal.signal(signal.SIGINT, dog.stop)
    return dog.run()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
