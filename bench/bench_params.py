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
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from vehicle import Vehicle  # noqa: E402
BYTES_PER_S = 5760
RUNS = 3


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

    with tempfile.TemporaryDirectory() as storage:
        v = Vehicle(storage, args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S]).start()
        try:
            m = v.gcs()
            times = []
            for _ in range(RUNS):
                seconds, wire, count = _list_once(m)
                times.append(seconds)
                time.sleep(0.2)
        finally:
            v.stop()
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
