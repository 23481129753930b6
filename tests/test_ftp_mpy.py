"""MAVLink FTP's per-packet path inside MicroPython: ReadFile, WriteFile, bursts streamed
from the tick, repeats answered from the kept reply, and the NAKs of a bad request, for
thousands of rounds under micropython.heap_lock(), after the same rounds unlocked with
micropython.mem_total() counting what they asked of the heap (0 required); with the
viper kernels and with the portable ones."""
import os

import pytest

from conftest import ROOT, run_mpy

MPY = os.path.join(ROOT, "tests", "mpy")
SCRIPT = os.path.join(MPY, "ftp_steady.py")
ROUNDS = 3000


def parse(out):
    words = out.split()
    info = dict(w.split("=") for w in words[1:])
    return words[0], {k: int(v) for k, v in info.items()}


@pytest.mark.parametrize("kernels", ["viper", "portable"])
def test_ftp_steady_state_under_heap_lock(tmp_path, kernels, monkeypatch):
    if kernels == "portable":
        monkeypatch.setenv("MAVSTACK_PORTABLE", "1")
    r = run_mpy(SCRIPT, str(tmp_path), ROUNDS, timeout=180, path=[MPY])
    assert r.returncode == 0, r.stdout + r.stderr
    verdict, info = parse(r.stdout.strip())
    assert verdict == "OK" and info["requested"] == 0, r.stdout
    assert info["rounds"] == ROUNDS
    # Every request answered: reads, writes and the repeat ACKed, the three bad ones NAKed,
    # and each burst streamed out to the file's end (17 replies, the last short).
    assert info["acks"] > ROUNDS * 0.9, r.stdout
    assert info["naks"] >= ROUNDS * 3 // 42, r.stdout
    assert info["burst"] >= 10 * (ROUNDS // 42), r.stdout
    assert info["read_bytes"] > 100 * ROUNDS, r.stdout
