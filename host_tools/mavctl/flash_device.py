"""The board side of flashing (flash_build.py): reach MicroPython's raw REPL over the
board's serial port, stopping the program that runs there; read the firmware's .mpy
version, CPU and machine; bring a built tree over with mpremote's transport, skipping
files whose SHA-256 the board already has; soft-reset into main.py and wait for the
vehicle's first HEARTBEAT on its MAVLink port.

Every failure is a DeviceError: one line and mavctl's exit status for it.
"""
import errno
import hashlib
import os
import time

from mavctl.errors import EXIT_NO_HEARTBEAT, EXIT_NO_PORT, EXIT_NOT_MICROPYTHON, EXIT_PERMISSION, EXIT_REFUSED

RAW_BANNER = b"raw REPL; CTRL-B to exit"
CHUNK = 1024  # bytes per write command in the raw REPL


class DeviceError(Exception):
    def __init__(self, message, status=EXIT_REFUSED):
        Exception.__init__(self, message)
        self.status = status


def open_error(port, e):
    """The DeviceError for an exception raised while opening the port."""
    code = getattr(e, "errno", None)
    text = str(e)
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return DeviceError("%s: permission denied: add yourself to the device's group (dialout, "
                           "uucp) and log in again" % port, EXIT_PERMISSION)
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO) or "No such file" in text:
        return DeviceError("%s: no such port: is the board plugged in?" % port, EXIT_NO_PORT)
    if code in (errno.EBUSY, errno.EAGAIN) or "lock" in text:
        return DeviceError("%s: port busy: another program (a ground station, mpremote, a serial "
                           "terminal) has it open" % port, EXIT_NO_PORT)
    return DeviceError("cannot open %s: %s" % (port, text), EXIT_NO_PORT)


def default_port():
    """The one USB serial port pyserial lists (several or none: say so)."""
    from serial.tools import list_ports

    ports = sorted(p.device for p in list_ports.comports() if p.vid is not None)
    if len(ports) == 1:
        return ports[0]
    if not ports:
        raise DeviceError("no board found: no USB serial device; plug it in or give --port", EXIT_NO_PORT)
    raise DeviceError("several serial ports: %s; choose one with --port" % ", ".join(ports), EXIT_NO_PORT)


class Board:
    """A MicroPython board's REPL, in the raw REPL once open() returns."""

    def __init__(self, port):
        import serial
        from mpremote.transport_serial import SerialTransport

        self.port = port
        try:  # opened here first: mpremote's own error would not say why
            serial.Serial(port, 115200, exclusive=True).close()
        except (OSError, serial.SerialException) as e:
            raise open_error(port, e.__cause__ if isinstance(e.__cause__, OSError) else e)
        self.t = SerialTransport(port, 115200)

    def open(self, timeout=10.0):
        """Stop what runs (Ctrl-C), enter the raw REPL; nothing answering like MicroPython
        within timeout seconds is refused."""
        s = self.t.serial
        seen = b""
        deadline = time.monotonic() + timeout
        while RAW_BANNER not in seen:
            if time.monotonic() > deadline:
                tail = seen[-60:].decode("ascii", "replace")
                raise DeviceError("%s: no MicroPython REPL answers there (%s): is it a MicroPython "
                                  "board, and its REPL port?" % (
                                      self.port, "it said %r" % tail if seen else "it said nothing"),
                                  EXIT_NOT_MICROPYTHON)
            s.write(b"\r\x03")  # a board reads Ctrl-C between its ticks: give it time
            time.sleep(0.25)
            s.write(b"\r\x01")
            time.sleep(0.35)
            seen += s.read(s.in_waiting)
        self.t.enter_raw_repl(soft_reset=False)
        return self

    def exec(self, code, timeout=60):
        """Run code in the raw REPL -> what it printed (a slow board gets timeout seconds)."""
        from mpremote.transport import TransportError

        try:
            out, err = self.t.exec_raw(code, timeout=timeout)
        except TransportError as e:
            raise DeviceError("%s: the board did not answer: %s" % (self.port, e))
        if err:
            detail = err.decode(errors="replace").strip().splitlines()
            raise DeviceError("%s: the board failed: %s" % (self.port, detail[-1] if detail else "?"))
        return out.decode(errors="replace")

    def info(self):
        """(mpy version, sub-version, arch index or 0, MicroPython version, machine)."""
        out = self.exec("import sys\ni=sys.implementation\n"
                        "print('MPYINFO',getattr(i,'_mpy',0),'.'.join(str(v) for v in i.version[:3]))\n"
                        "print('MACHINE',getattr(i,'_machine',sys.platform))")
        mpy = version = machine = None
        for line in out.splitlines():
            if line.startswith("MPYINFO"):
                _, mpy, version = line.split()
            elif line.startswith("MACHINE "):
                machine = line[8:].strip()
        if mpy is None:
            raise DeviceError("%s: not a MicroPython answer: %r" % (self.port, out[:80]), EXIT_NOT_MICROPYTHON)
        mpy = int(mpy)
        return mpy & 0xFF, (mpy >> 8) & 3, mpy >> 10, version, machine

    def sync(self, out, files, bar):
        """Make the board's tree the build's -> (copied, unchanged, removed) file counts.
        bar(done, total) is told the bytes written."""
        have, removed = self._prepare(files)
        todo = []
        for f in files:
            with open(os.path.join(out, f), "rb") as fh:
                data = fh.read()
            if have.get(f) != _sha256(data):
                todo.append((f, data))
        total = sum(len(d) for _, d in todo)
        done = 0
        for path, data in todo:
            def step(n, _size, base=done):
                bar(base + n, total)
            try:
                self.t.fs_writefile(path, data, CHUNK, step)
            except OSError as e:
                raise DeviceError("%s: writing %s failed: %s (is the board's filesystem full?)"
                                  % (self.port, path, e))
            done += len(data)
        return len(todo), len(files) - len(todo), removed

    def _prepare(self, files):
        """Board side: make the directories, delete stack files the build does not have (a
        stale foo.py would shadow foo.mpy), hash what is there -> ({path: sha256 hex}, removed)."""
        out = self.exec(prepare_script(files))
        if "NOFS" in out:
            raise DeviceError("%s: the board has no writable filesystem to flash to" % self.port)
        have = {}
        for line in out.splitlines():
            if line.startswith("H "):
                _, path, digest = line.split()
                have[path] = digest
        return have, sum(1 for line in out.splitlines() if line.startswith("removed "))

    def reset(self):
        """A soft reset to the friendly REPL: the board runs main.py (from the raw REPL it
        would not)."""
        self.t.exit_raw_repl()
        time.sleep(0.1)
        self.t.serial.write(b"\x04")

    def console(self):
        s = self.t.serial
        return s.read(s.in_waiting).decode(errors="replace")

    def close(self):
        try:
            self.t.close()
        except Exception:
            pass


def _lines(console):
    return [l.strip() for l in console.splitlines() if l.strip() and l.strip() != ">>>"]


def prepare_script(files):
    """The board-side script of Board._prepare for the tree's files."""
    keep = sorted(f for f in files if f.startswith("mavstack/"))
    dirs = sorted({f.rsplit("/", 1)[0] for f in files if "/" in f})
    return _PREPARE % (keep, dirs, files)


def _sha256(data):
    return hashlib.sha256(data).hexdigest()


_PREPARE = """import os
keep=set(%r)
for d in %r:
 p=''
 for part in d.split('/'):
  p=p+part
  try:
   os.mkdir(p)
  except OSError:
   pass
  p=p+'/'
def walk(d):
 for e in os.ilistdir(d):
  p=d+'/'+e[0]
  if e[1]==0x4000:
   walk(p)
  elif p not in keep:
   os.remove(p);print('removed',p)
try:
 walk('mavstack')
except OSError:
 pass
try:
 open('.mavstack-flash','wb').close()
 os.remove('.mavstack-flash')
except OSError:
 print('NOFS')
try:
 import hashlib,binascii
except ImportError:
 hashlib=None
b=bytearray(512)
for p in %r:
 if hashlib is None:
  break
 try:
  f=open(p,'rb')
 except OSError:
  continue
 h=hashlib.sha256()
 while True:
  n=f.readinto(b)
  if not n:
   break
  h.update(memoryview(b)[:n])
 f.close()
 print('H',p,binascii.hexlify(h.digest()).decode())
"""


def wait_heartbeat(device, timeout, board=None):
    """The vehicle's first HEARTBEAT on device (its MAVLink port) -> (the message, the
    lines the board printed on its REPL port meanwhile); none in time is an error that
    quotes the board's last line."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    try:
        conn = mavutil.mavlink_connection(device, baud=115200, source_system=255, source_component=190,
                                          dialect="common", autoreconnect=False)
    except Exception as e:
        raise open_error(device, e)
    console = ""
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            msg = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if board is not None:
                console += board.console()
            if msg is not None and msg.type != mavutil.mavlink.MAV_TYPE_GCS:
                if board is not None:  # the two UARTs' output is not ordered: a moment more
                    time.sleep(0.5)
                    console += board.console()
                return msg, _lines(console)
    finally:
        conn.close()
    last = _lines(console)
    raise DeviceError("no HEARTBEAT on %s within %.0f s after the reset%s" % (
        device, timeout, "; the board said: " + last[-1] if last else ""), EXIT_NO_HEARTBEAT)
