"""`mavctl sim`: the simulated vehicle (MicroPython's unix port running firmware/main.py)
on a serial line of its own, so that everything can be tried over a real tty without
hardware. Two pseudo-terminals joined back to back, as a USB radio pair joins two
computers: the vehicle opens one, and the other's device path is printed for the ground
station (`mavctl --connect serial:DEVICE ...`, MAVProxy, QGroundControl). Ctrl-C (SIGINT)
or SIGTERM stops the vehicle the way it stops itself (it stores what it keeps) and exits 0.
"""
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import termios
import threading
import tty

from mavctl import ROOT
from mavctl.errors import EXIT_OK, Failure, usage

BAUD = 57600  # what the vehicle is told; a pty carries bytes at any speed


def micropython():
    """The unix port: next to this Python (the venv's bin), in the checkout's .venv, or on PATH."""
    for path in (os.path.join(os.path.dirname(sys.executable), "micropython"),
                 os.path.join(ROOT, ".venv", "bin", "micropython")):
        if os.access(path, os.X_OK):
            return path
    found = shutil.which("micropython")
    if found is None:
        raise Failure("no micropython (the unix port): run `make setup` in the checkout", 2)
    return found


def open_pty():
    """(master fd, slave fd, slave path): raw from the start, so nothing is echoed back."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


class PtyPair:
    """Two ptys whose masters a thread joins: bytes written on one slave are read on the
    other. While nobody reads one end, what is written to it is dropped (its queue
    flushed), as a radio with nobody listening loses it, instead of blocking the other."""

    def __init__(self):
        self.vehicle_master, self.vehicle_slave, self.vehicle_dev = open_pty()
        self.gcs_master, self.gcs_slave, self.gcs_dev = open_pty()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._relay, name="pty-relay", daemon=True)
        self._thread.start()

    def _relay(self):
        route = {self.vehicle_master: (self.gcs_master, self.gcs_slave),
                 self.gcs_master: (self.vehicle_master, self.vehicle_slave)}
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select(list(route), [], [], 0.1)
            except (OSError, ValueError):
                return
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:  # EIO while the other side is closed: nothing to carry
                    continue
                out, out_slave = route[fd]
                try:
                    os.write(out, data)
                except BlockingIOError:
                    # Its queue is full: nobody reads that end. Stale frames are no use to
                    # the next reader, so drop them all.
                    termios.tcflush(out_slave, termios.TCIFLUSH)
                except OSError:
                    pass

    def close(self):
        self._stop.set()
        self._thread.join(2)
        for fd in (self.vehicle_master, self.vehicle_slave, self.gcs_master, self.gcs_slave):
            try:
                os.close(fd)
            except OSError:
                pass


def vehicle_command(args, device, storage):
    cmd = [micropython(), os.path.join(ROOT, "firmware", "main.py"), "--board", args.board,
           "--storage", storage, "--sysid", str(args.sysid_vehicle),
           "--link", "serial:%s:%d" % (device, BAUD)]
    for link in args.also:
        cmd += ["--link", link]
    for setting in args.set:
        cmd += ["--set", setting]
    return cmd


def run_sim(args):
    storage = args.storage
    temporary = None
    if storage is None:
        temporary = tempfile.mkdtemp(prefix="mavctl-sim-")
        storage = temporary
    pair = PtyPair()
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join(board_path() + [os.path.join(ROOT, "firmware"), ".frozen"])
    proc = None
    stopping = []

    def stop(signum, frame):
        stopping.append(signum)
        raise KeyboardInterrupt

    # Installed, not inherited: a shell starts background jobs with SIGINT ignored.
    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        # The vehicle gets its own process group: a Ctrl-C on the terminal reaches mavctl
        # alone, and mavctl stops the vehicle in order.
        proc = subprocess.Popen(vehicle_command(args, pair.vehicle_dev, storage), cwd=ROOT, env=env,
                                stdin=subprocess.DEVNULL, start_new_session=True)
        print("mavctl sim: the %s vehicle on %s" % (args.board, pair.gcs_dev))
        print("  try: mavctl --connect serial:%s:%d params list" % (pair.gcs_dev, BAUD))
        print("  Ctrl-C stops it", flush=True)
        status = proc.wait()
        raise Failure("the simulated vehicle stopped (exit status %d)" % status)
    except KeyboardInterrupt:
        print("mavctl sim: stopping", flush=True)
        return EXIT_OK
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if proc is not None and proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # main.py stops its services on KeyboardInterrupt
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        pair.close()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)


def board_path():
    """Where board profiles are looked for: MICROPYPATH's folders (a profile of your own),
    then the checkout's boards/."""
    own = [d for d in os.environ.get("MICROPYPATH", "").split(os.pathsep) if d and d != ".frozen"]
    return own + [os.path.join(ROOT, "boards")]


def check_sim(args):
    if not any(os.path.isfile(os.path.join(d, args.board + ".py")) for d in board_path()):
        raise usage("no board profile %s.py in %s" % (args.board, os.pathsep.join(board_path())))
    for setting in args.set:
        if "=" not in setting:
            raise usage("--set KEY=VALUE, not %r" % setting)


def register(sub):
    p = sub.add_parser("sim", help="the simulated vehicle on a new pty pair: prints the device "
                       "to connect to; Ctrl-C stops it")
    p.add_argument("--board", default="unix",
                   help="board profile (default unix, the simulated quadcopter); your own are "
                   "found through MICROPYPATH")
    p.add_argument("--storage", metavar="DIR",
                   help="where parameters and missions persist (default: a temporary folder, "
                   "removed when the vehicle stops)")
    p.add_argument("--vehicle-sysid", dest="sysid_vehicle", type=int, default=1,
                   help="the vehicle's system id (default 1)")
    p.add_argument("--link", dest="also", action="append", default=[], metavar="SPEC",
                   help="another link for the vehicle as well, e.g. udpout:127.0.0.1:14550")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a board option for the vehicle (e.g. sim_speed=20)")
    p.set_defaults(func=run_sim, check=check_sim)


if __name__ == "__main__":
    from mavctl import cli as mavctl_cli
    sys.exit(mavctl_cli.main(["sim"] + sys.argv[1:]))
