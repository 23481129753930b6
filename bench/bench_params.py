"""Parameter list over a link paced as a 57600 baud radio, measured end to end.

The unix vehicle runs with `--set udp_bytes_per_s=5760` (57600 baud, 8N1), so the
parameter service paces its list as it would on a telemetry radio; pymavlink asks for
the list and times it until every parameter has arrived. The line-rate bound is the
bytes those PARAM_VALUE frames took on the wire at 5760 B/s. The service uses about
half the link (the rest stays free for telemetry and commands): expect ~2x the bound.

    .venv/bin/python bench/bench_params.py
"""
import json
import os
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BYTES_PER_S = 5760
RUNS = 3


def _free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _start(port, storage):
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join(
        [os.path.join(ROOT, "firmware"), os.path.join(ROOT, "boards"), ".frozen"])
    cmd = [os.path.join(ROOT, ".venv", "bin", "micropython"), os.path.join(ROOT, "firmware", "main.py"),
           "--board", "unix", "--link", "udpin:127.0.0.1:%d" % port, "--storage", storage,
           "--set", "udp_bytes_per_s=%d" % BYTES_PER_S]
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _connect(port):
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % port, source_system=255,
                                   source_component=190, dialect="common")
    deadline = time.time() + 20
    while time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if hb is not None:
            return m
    raise RuntimeError("no HEARTBEAT from the vehicle")


def _list_once(m):
    """Seconds for a full list, and the bytes its PARAM_VALUE frames took."""
    seen = {}
    wire = 0
    count = None
    start = time.time()
    m.mav.param_request_list_send(1, 1)
    while count is None or len(seen) < count:
        msg = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=10)
        if msg is None:
            raise RuntimeError("list stalled at %d of %s" % (len(seen), count))
        count = msg.param_count
        if msg.param_index not in seen:
            seen[msg.param_index] = True
            wire += len(msg.get_msgbuf())
    return time.time() - start, wire, count


def run():
    import tempfile

    port = _free_port()
    with tempfile.TemporaryDirectory() as storage:
        proc = _start(port, storage)
        try:
            m = _connect(port)
            times = []
            for _ in range(RUNS):
                seconds, wire, count = _list_once(m)
                times.append(seconds)
                time.sleep(0.2)
            m.close()
        finally:
            proc.terminate()
            proc.wait(10)
    times.sort()
    seconds = times[len(times) // 2]
    bound = wire / BYTES_PER_S
    return {
        "param_list_s_57600": round(seconds, 3),
        "param_list_bound_s_57600": round(bound, 3),
        "param_list_ratio_57600": round(seconds / bound, 2),
        "param_list_count": count,
    }


def floors(results):
    ratio = results["param_list_s_57600"] / results["param_list_bound_s_57600"]
    return [("param list at 57600 baud within 2.5x its line-rate bound (%.2fx)" % ratio, ratio <= 2.5)]


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    print(json.dumps(run(), indent=1))
