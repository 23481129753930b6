"""An emulated board as a test fixture: its firmware under qemu-system-arm, its UARTs on
ptys, the REPL driven by mpremote's raw-REPL transport, MAVLink through pymavlink.

    with EmulatedBoard("qemu_m3") as b:
        b.exec("print(1)")                 -> output (raises BoardError on an exception)
        b.run_script("tests/mpy/x.py", args, files={"name": bytes})   a script, as on unix
        gcs = b.start_vehicle()            the vehicle (firmware/main.py); a pymavlink link
        pty, line = b.start_peripheral()   a peripheral's vehicle; its pty free for a host program
        b.console()                        what the REPL UART printed since (qemu_m3)

qemu_m3 has the REPL on UART 0 and MAVLink on UART 1. qemu_m0 has one UART: once the
vehicle runs, MAVLink has it, and what the board prints goes into the same stream (the
parser skips it, and the test reads it from gcs.console_bytes).
"""
import os
import re
import subprocess
import sys
import time

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "mcu"))
import firmware  # noqa: E402

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")
TEST_MANIFEST = os.path.join(ROOT, "tests", "mcu", "manifest.py")


class BoardError(Exception):
    pass


def skip_reason():
    """Why the MCU stage cannot run here (None: it can)."""
    missing = firmware.tools_missing()
    if missing:
        return "MCU stage skipped: %s not installed (make mcu-deps installs them)" % ", ".join(missing)
    return None


class EmulatedBoard:
    DEFAULT_HEAP_KB = firmware.DEFAULT_HEAP_KB

    def __init__(self, board, heap_kb=firmware.DEFAULT_HEAP_KB, manifest=None, boot_timeout=20,
                 qemu_args=()):
        self.board = board
        self.qemu_args = list(qemu_args)  # appended to qemu-system-arm's (bench_mcu_ingest.py)
        self.elf = firmware.build(board, heap_kb, manifest=manifest)
        self.uarts = 2 if board == "qemu_m3" else 1
        self.boot_timeout = boot_timeout
        self.proc = None
        self.repl = None
        self.ptys = []

    def __enter__(self):
        from mpremote.transport_serial import SerialTransport

        cmd = firmware.qemu_command(self.board, self.elf, ["pty"] * self.uarts) + self.qemu_args
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        while len(self.ptys) < self.uarts:
            line = self.proc.stdout.readline()
            if not line:
                raise BoardError("qemu exited: %s" % self.proc.poll())
            m = re.search(r"(/dev/pts/\d+)", line)
            if m:
                self.ptys.append(m.group(1))
        self.repl = SerialTransport(self.ptys[0], 115200)
        self.repl.enter_raw_repl(soft_reset=False)
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        if getattr(self, "_mav_serial", None) is not None:
            self._mav_serial.close()
        if self.repl is not None:
            try:
                self.repl.close()
            except Exception:
                pass
            self.repl = None
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc.stdout.close()
            self.proc = None

    def exec(self, code, timeout=60):
        out, err = self.repl.exec_raw(code, timeout=timeout)
        if err:
            raise BoardError(err.decode(errors="replace"))
        return out.decode(errors="replace")

    def run_script(self, path, args=(), timeout=300):
        """A tests/mpy script as MicroPython's unix port would run it: sys.argv set,
        tests/mpy importable (frozen in by tests/mcu/manifest.py)."""
        with open(path) as f:
            return self.exec(self._script(f.read(), args, os.path.basename(path)), timeout=timeout)

    def _script(self, src, args, name="script.py"):
        # The qemu port has no sys.argv: the script's `import sys` finds a stand-in that has
        # one and passes everything else to the real module.
        pre = ("import sys as _sys\nclass _Sys:\n def __getattr__(self, n):\n  return getattr(_sys, n)\n"
               "_s = _Sys()\n_s.argv = %r\n_sys.modules['sys'] = _s\n" % ([name] + [str(a) for a in args]))
        return pre + src

    def start_script(self, src, args=()):
        """Start a script that talks over the MAVLink UART too; finish_script() collects."""
        self.repl.exec_raw_no_follow(self._script(src, args))
        return None

    def mavlink_serial(self):
        """A pyserial port on the board's MAVLink UART (on qemu_m0: the REPL's own)."""
        if self.uarts == 1:
            return self.repl.serial
        import serial

        if getattr(self, "_mav_serial", None) is None:
            self._mav_serial = serial.Serial(self.ptys[1], 115200, timeout=0.05)
        return self._mav_serial

    def finish_script(self, _handle, uart_bytes, timeout=300, expect=b"", times=1):
        """The script's printed text once it is done. On qemu_m0 that text arrives in the
        MAVLink byte stream (uart_bytes, filled by the caller's reader): wait for `expect`
        to appear `times` times there and the raw REPL's end marker after it."""
        end = time.time() + timeout
        if self.uarts == 2:
            out, err = self.repl.follow(timeout)
            if err:
                raise BoardError(err.decode(errors="replace"))
            return out.decode(errors="replace")
        while time.time() < end:
            data = bytes(uart_bytes)
            if data.count(expect) >= times and data.rfind(b"\x04") > data.rfind(expect):
                return data.decode(errors="replace")
            if b"Traceback" in data and data.count(b"\x04>") >= 1:
                break
            time.sleep(0.1)
        raise BoardError("script did not finish: %r" % bytes(uart_bytes)[-2000:])

    def start_vehicle(self, options=None, timeout=20):
        """Boot firmware/main.py (frozen as `main`) and connect a pymavlink ground station."""
        os.environ["MAVLINK20"] = "1"
        from pymavlink import mavutil

        argv = []
        for k, v in (options or {}).items():
            argv += ["--set", "%s=%s" % (k, v)]
        self.repl.exec_raw_no_follow("import main\nmain.main(%r)" % argv)
        if self.uarts == 1:  # the one UART is MAVLink's from now on
            self.repl.close()
            self.repl = None
        gcs = mavutil.mavlink_connection(self.ptys[-1], baud=115200, source_system=255,
                                         source_component=190)
        if gcs.wait_heartbeat(timeout=timeout) is None:
            raise BoardError("no HEARTBEAT from the %s vehicle; console: %r" % (self.board, self.console()))
        return gcs

    def start_peripheral(self, options=None, timeout=20):
        """Boot firmware/main.py on a board whose profile follows its autopilot's system id
        (SYSID "follow": it sends nothing before it hears one), wait for its `ready` line,
        and let go of the UART -> (the MAVLink pty's path, that line). A host program then
        opens the pty: pymavlink's mavlink_connection(path, baud=115200), or the unix
        vehicle's `--link serial:PATH:115200`. On a one-UART board what it prints later
        comes in the same stream, between frames."""
        argv = []
        for k, v in (options or {}).items():
            argv += ["--set", "%s=%s" % (k, v)]
        self.repl.exec_raw_no_follow("import main\nmain.main(%r)" % argv)
        s = self.repl.serial  # what it prints: the REPL's UART (on qemu_m0 the only one)
        got = b""
        end = time.time() + timeout
        while time.time() < end:
            if not s.in_waiting:  # (a read would wait for ever: a board that never gets there)
                time.sleep(0.05)
                continue
            got += s.read(s.in_waiting)
            m = re.search(rb"mavstack: \w+ ready[^\n]*\n", got)
            if m:
                break
        else:
            raise BoardError("the %s vehicle did not say it was ready: %r" % (self.board, got[-500:]))
        if self.uarts == 1:  # the one UART is MAVLink's from now on
            self.repl.close()
            self.repl = None
        return self.ptys[-1], m.group(0).decode().strip()

    def reopen_repl(self):
        """The REPL again on qemu_m0's one UART, once the vehicle has returned to it."""
        from mpremote.transport_serial import SerialTransport

        # Until the vehicle has stopped, what is sent is MAVLink to it: ask for the raw
        # REPL until it answers (mpremote's own entry would wait for ever).
        repl = SerialTransport(self.ptys[0], 115200)
        s = repl.serial
        for _ in range(20):
            s.write(b"\r\x01")
            time.sleep(0.5)
            if b"raw REPL; CTRL-B to exit" in s.read(s.in_waiting):
                repl.enter_raw_repl(soft_reset=False)  # the board listens now: the usual way
                self.repl = repl
                return
        repl.close()
        raise BoardError("the board's REPL did not come back")

    def console(self, wait=0.2):
        """What the REPL UART printed (qemu_m3; qemu_m0 shares it with MAVLink)."""
        if self.repl is None:
            return ""
        time.sleep(wait)
        s = self.repl.serial
        return s.read(s.in_waiting).decode(errors="replace")


if __name__ == "__main__":
    # python tests/mcu_rig.py BOARD SCRIPT [ARGS...]: run a tests/mpy script on a board
    # (heap: MCU_HEAP_KB, default 160), as the MCU tests do; prints what it printed.
    if len(sys.argv) < 3:
        raise SystemExit("usage: tests/mcu_rig.py qemu_m3|qemu_m0 tests/mpy/SCRIPT.py [ARGS...]")
    with EmulatedBoard(sys.argv[1], int(os.environ.get("MCU_HEAP_KB", "160")), TEST_MANIFEST) as _b:
        _t = time.time()
        try:
            print(_b.run_script(sys.argv[2], sys.argv[3:]), end="")
        except BoardError as _e:
            print("BoardError:", _e)
        print("(%.1f s on %s)" % (time.time() - _t, sys.argv[1]))
