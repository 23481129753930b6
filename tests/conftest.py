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


SEED_XML = os.path.join(os.path.dirname(ROOT), "shared", "spec", "common-2012.xml")


@pytest.fixture(scope="session")
def seedmav(tmp_path_factory):
    """pymavlink's generated module for the seed's message set (MAVLink 1.0): what a
    seed-era ground station speaks (tests/test_seed_*.py)."""
    import importlib.util

    from pymavlink.generator import mavgen

    out = str(tmp_path_factory.mktemp("seedmav") / "seed2012mav.py")
    mavgen.mavgen(mavgen.Opts(output=out, wire_protocol="1.0", language="Python3", validate=False), [SEED_XML])
    spec = importlib.util.spec_from_file_location("seed2012mav", out)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
