"""Mission upload and download of 500 items over a link paced as a 57600 baud radio.

The unix vehicle (`--set udp_bytes_per_s=5760`) talks to a pymavlink ground station
(tests/mission_gcs.py) through a relay that plays the radio (tests/relay.py): each way carries
5760 bytes a second (57600 baud, 8N1), a frame leaves when the one before it has gone
and arrives when its last byte has; the vehicle's telemetry shares the air as on a
real radio. The protocol is lock-step (one item per request), so its line-rate bound
is every byte of the transfer's own frames (MISSION_COUNT, requests, items, ACK) at
5760 B/s, one after the other. The lossy run drops 10% of the frames each way (they
still take their air time); the vehicle re-requests after its default 250 ms, the
ground station re-sends requests after 250 ms too.

    .venv/bin/python bench/bench_missions.py
"""
import json
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from relay import Radio  # noqa: E402
from vehicle import Vehicle  # noqa: E402
BYTES_PER_S = 5760
N = 500
MISSION_IDS = (39, 40, 43, 44, 47, 51, 73)  # the transfer's own frames


def _transfer(radio, m, what, items):
    from mission_gcs import MissionClient, same

    c = MissionClient(m, timeout=0.25, retries=20)
    c.drain(0.3)
    radio.counted_bytes = 0
    start = time.time()
    if what == "upload":
        ok = c.upload(items) == 0
    else:
        got = c.download(ack=True)
        ok = got is not None and same(got, items)
    seconds = time.time() - start
    if not ok:
        raise RuntimeError("%s of %d items failed" % (what, len(items)))
    return seconds, radio.counted_bytes / BYTES_PER_S


def run():
    from mission_gcs import plan

    out = {}
    items = plan(N, tag=1)
    for loss, runs in ((0.0, ("upload", "download")), (0.1, ("upload",))):
        with tempfile.TemporaryDirectory() as storage:
            v = Vehicle(storage, args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S]).start()
            radio = Radio(v.port, BYTES_PER_S, loss, counted=MISSION_IDS)
            try:
                m = v.gcs(port=radio.port)
                for what in runs:
                    seconds, bound = _transfer(radio, m, what, items)
                    key = "mission_%s_%d%s" % (what, N, "_lossy" if loss else "")
                    out[key + "_s"] = round(seconds, 2)
                    out[key + "_bound_s"] = round(bound, 2)
                    out[key + "_ratio"] = round(seconds / bound, 2)
            finally:
                v.stop()
                radio.close()
    return out


def floors(results):
    out = []
    for what in ("upload", "download"):
        ratio = results["mission_%s_%d_s" % (what, N)] / results["mission_%s_%d_bound_s" % (what, N)]
        out.append(("mission %s of %d items at 57600 baud within 1.5x its line-rate bound (%.2fx)"
                    % (what, N, ratio), ratio <= 1.5))
    return out


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
