"""Allocation-free per frame, proven on the unix port under micropython.heap_lock() with
both kernel sets: 10,000+ damaged mixed frames parsed, 10,000 frames encoded, and a Link
in an Endpoint dispatching to handlers that read fields and answer; each phase also
run unlocked with micropython.mem_total() counting, which must stay at 0 (frame states
of functions with many locals go on the heap there, call by call)."""
import contextlib
import io
import math
import os
import random
import struct
import subprocess
import sys

import pytest

from conftest import FIRMWARE, MICROPYTHON, ROOT
from wire_oracle import MPY_DIR, classes, corrupt, decode_frames, full_len, pack, random_values

BENCH_IDS = (0, 30, 24, 22, 73, 76)  # HEARTBEAT ATTITUDE GPS_RAW_INT PARAM_VALUE MISSION_ITEM_INT COMMAND_LONG
ACC = ("frames", "custom_mode", "nan_roll", "param_id_len", "lat", "command", "mission_x", "signed", "other")


def mixed_frames(rnd, n):
    """Mostly the usual telemetry and command traffic, some of everything else; MAVLink 1,
    2 (payload tails trimmed where zero), signed 2."""
    by_id = {v: {c.id: c for c in classes("common", v)} for v in (1, 2)}
    out = []
    for i in range(n):
        version = 1 if rnd.random() < 0.3 else 2
        if rnd.random() < 0.75:
            cls = by_id[version][rnd.choice(BENCH_IDS)]
        else:
            cls = rnd.choice(list(by_id[version].values()))
        key = bytes(32) if version == 2 and rnd.random() < 0.1 else None
        out.append(pack("common", version, cls, random_values(cls, rnd), seq=i & 0xFF,
                        sysid=rnd.choice([1, 2, 255]), compid=rnd.choice([1, 190]), sign_key=key))
    return out


@pytest.fixture(scope="module")
def damaged_stream(tmp_path_factory):
    rnd = random.Random(10000)
    frames = mixed_frames(rnd, 11000)
    stream, intact = corrupt(rnd, frames, rate=0.05, garbage_rate=0.1)
    path = tmp_path_factory.mktemp("heaplock") / "stream.bin"
    path.write_bytes(stream + bytes(2000))
    return path, [frames[i] for i in intact]


def expected_acc(frames):
    acc = dict.fromkeys(ACC, 0)
    for f in frames:
        hdr = 10 if f[0] == 0xFD else 6
        msgid = f[5] if hdr == 6 else f[7] | f[8] << 8 | f[9] << 16
        p = f[hdr:hdr + f[1]]
        p += bytes(full_len("common", msgid) - len(p))
        acc["frames"] += 1
        if hdr == 10 and f[2] & 1:
            acc["signed"] += 1
        if msgid == 0:
            acc["custom_mode"] += struct.unpack_from("<I", p, 0)[0]
        elif msgid == 30:
            acc["nan_roll"] += math.isnan(struct.unpack_from("<f", p, 4)[0])
        elif msgid == 22:
            acc["param_id_len"] += len(p[8:24].split(b"\0")[0])
        elif msgid == 24:
            acc["lat"] += struct.unpack_from("<i", p, 8)[0]
        elif msgid == 76:
            acc["command"] += struct.unpack_from("<H", p, 28)[0]
        elif msgid == 73:
            acc["mission_x"] += struct.unpack_from("<i", p, 16)[0]
        else:
            acc["other"] += 1
    return " ".join("%s=%d" % (k, v) for k, v in acc.items())


def run_heaplock(runtime, portable, stream, out_dir):
    args = [str(stream), str(out_dir), "10000"]
    if runtime == "cpython":
        if MPY_DIR not in sys.path:
            sys.path.insert(0, MPY_DIR)
        import wire_heaplock

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            wire_heaplock.main(args)
        text = buf.getvalue()
    else:
        env = dict(os.environ, MICROPYPATH=os.pathsep.join([MPY_DIR, FIRMWARE, ".frozen"]))
        env.pop("MAVSTACK_PORTABLE", None)
        if portable:
            env["MAVSTACK_PORTABLE"] = "1"
        p = subprocess.run([MICROPYTHON, "-X", "heapsize=16M", os.path.join(MPY_DIR, "wire_heaplock.py")] + args,
                           cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stdout + p.stderr  # a MemoryError under the lock lands here
        text = p.stdout
    return {line.split()[0]: line.split(None, 1)[1] for line in text.strip().split("\n")}


_cpython = {}


@pytest.mark.parametrize("portable", [False, True], ids=["viper", "portable"])
def test_heap_locked_parse_encode_and_link(tmp_path, damaged_stream, portable):
    stream, intact = damaged_stream
    assert len(intact) >= 10000
    kinds = [f[0] for f in intact]
    truncated = [f for f in intact if f[0] == 0xFD and f[1] < full_len("common", f[7] | f[8] << 8 | f[9] << 16)]
    assert kinds.count(0xFE) > 2000 and kinds.count(0xFD) > 6000 and len(truncated) > 2000
    got = run_heaplock("mpy", portable, stream, tmp_path)
    assert got["kernels"] == ("portable" if portable else "viper")
    # Each phase also ran unlocked, counted with mem_total: no frame state on the heap.
    assert got["requested"] == "parse=0 encode=0 link=0"

    # Parsing: every intact frame delivered, fields read as struct reads them.
    want = expected_acc(intact)
    parse_acc, parse_stats = got["parse"].split(" stats ")
    assert parse_acc == want
    stats = [int(x) for x in parse_stats.split()]
    assert stats[0] == len(intact) and stats[1] > 0 and stats[2] > 0  # frames, CRC errors, discarded

    # The same through Link + Endpoint, and the same statistics as on CPython.
    link_acc, link_stats = got["link"].split(" stats ")
    assert link_acc == want and link_stats == parse_stats
    if "cpython" not in _cpython:
        cp = tmp_path / "cpython"
        cp.mkdir()
        _cpython["cpython"] = run_heaplock("cpython", True, stream, cp)
    ref = _cpython["cpython"]
    for key in ("parse", "encode", "link", "link_tx"):
        assert got[key] == ref[key], key

    # Encoding: 10,000 frames, alternately MAVLink 1 and 2, as pymavlink reads them.
    enc_acc, enc_stats = got["encode"].split(" stats ")
    assert enc_stats.split()[:3] == ["10000", "0", "0"] and enc_stats.split()[5] == "0"  # none lost
    msgs = decode_frames("common", 2, (tmp_path / "encoded.bin").read_bytes())
    assert len(msgs) == 10000 and "BAD_DATA" not in {m.get_type() for m in msgs}
    assert [m.get_msgbuf()[0] for m in msgs[:4]] == [0xFE, 0xFD, 0xFE, 0xFD]
    hbs = sorted(m.custom_mode for m in msgs if m.get_type() == "HEARTBEAT")
    assert hbs == list(range(0, 10000, 6))
    params = [m for m in msgs if m.get_type() == "PARAM_VALUE"]
    assert {m.param_id for m in params} == {"SYSID_THISMAV"} and len(params) == 1667

    # The link's answers: a COMMAND_ACK per COMMAND_LONG, MAVLink 1 until the peer spoke 2.
    acks, _, _, version = got["link_tx"].split()
    commands, v2_seen, versions = [], False, []
    for f in intact:
        v2_seen = v2_seen or f[0] == 0xFD
        msgid = f[5] if f[0] == 0xFE else f[7] | f[8] << 8 | f[9] << 16
        if msgid == 76:
            hdr = 10 if f[0] == 0xFD else 6
            p = f[hdr:hdr + f[1]] + bytes(33)
            commands.append(struct.unpack_from("<H", p, 28)[0])
            versions.append(2 if v2_seen else 1)
    tx = (tmp_path / "link_tx.bin").read_bytes()
    answers = decode_frames("common", 2, tx)
    assert int(acks) == len(commands) == len(answers) > 500 and version == "2"
    assert [a.get_type() for a in answers] == ["COMMAND_ACK"] * len(commands)
    assert [a.command for a in answers] == commands
    assert [2 if a.get_msgbuf()[0] == 0xFD else 1 for a in answers] == versions
    assert [a.get_seq() for a in answers] == [i & 0xFF for i in range(len(answers))]
