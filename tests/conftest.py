"""Shared test helpers: where the repository is, and running code under MicroPython."""
import os
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
MICROPYTHON = os.path.join(ROOT, ".venv", "bin", "micropython")


def run_mpy(code_or_file, *args, timeout=60, cwd=ROOT, path=()):
    """Run a .py file or a code string under MicroPython -> CompletedProcess (text).

    firmware/ and any extra directories in path are importable. The caller checks
    returncode and output.
    """
    if code_or_file.endswith(".py") and os.path.isfile(code_or_file):
        cmd = [MICROPYTHON, code_or_file]
    else:
        cmd = [MICROPYTHON, "-c", code_or_file]
    env = dict(os.environ)
    # Replaces MicroPython's default search path; '' (or the script's directory) stays first.
    env["MICROPYPATH"] = os.pathsep.join(list(path) + [FIRMWARE, ".frozen"])
    return subprocess.run(cmd + [str(a) for a in args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


# --- The unix vehicle as a real process, and a pymavlink ground station -------------
import sys

import pytest

from vehicle import Vehicle, free_udp_port, recv  # noqa: F401  (tests import them from here)

PYTHON = os.path.join(ROOT, ".venv", "bin", "python")
if FIRMWARE not in sys.path:
    sys.path.insert(0, FIRMWARE)


@pytest.fixture
def vehicle(tmp_path):
    """Factory: vehicle(**kw) starts a unix vehicle storing under tmp_path; all stopped after."""
    started = []

    def start(**kw):
        kw.setdefault("storage", tmp_path / "storage")
        v = Vehicle(**kw).start()
        started.append(v)
        return v

    yield start
    for v in started:
        v.stop()
