"""Mission upload and download of 500 items over a link paced as a 57600 baud radio,
loss-free and with lost frames.

The unix vehicle (`--set udp_bytes_per_s=5760`) talks to a pymavlink ground station
(tests/mission_gcs.py) through a relay that plays the radio (tests/relay.py: 5760 B/s
each way, a frame arriving when its last byte has), the vehicle's telemetry sharing the
air. The line-rate bound of a transfer is every byte of its own frames at 5760 B/s, one
after the other. Lossy runs drop frames each way: mission_upload_500_lossy_s (10% lost,
bound 2x the loss-free upload) and mission_cancelled_200_lossy20 (of RUNS_20 uploads of
200 items with 20% lost, how many did not end ACCEPTED; floor 0). The figures:
docs/testing.md.

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
N_20 = 200
RUNS_20 = 6
MISSION_IDS = (39, 40, 43, 44, 47, 51, 73)  # the transfer's own frames


def _client(m):
    from mission_gcs import MissionClient

    return MissionClient(m, timeout=0.25, retries=20)


def _transfer(radio, m, what, items):
    from mission_gcs import same

    c = _client(m)
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


def _radio_vehicle(storage, loss, seed=7):
    v = Vehicle(storage, args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S]).start()
    return v, Radio(v.port, BYTES_PER_S, loss, seed=seed, counted=MISSION_IDS)


def _timed(out, loss, runs, items):
    with tempfile.TemporaryDirectory() as storage:
        v, radio = _radio_vehicle(storage, loss)
        try:
            m = v.gcs(port=radio.port)
            for what in runs:
                seconds, bound = _transfer(radio, m, what, items)
                key = "mission_%s_%d%s" % (what, N, "_lossy" if loss else "")
                out[key + "_s"] = round(seconds, 2)
                if not loss:  # the lossy upload's bound is 2x the loss-free one (run())
                    out[key + "_bound_s"] = round(bound, 2)
                    out[key + "_ratio"] = round(seconds / bound, 2)
        finally:
            v.stop()
            radio.close()


def _cancelled(runs, loss):
    """Uploads of N_20 items through a radio losing `loss` of the frames -> how many did
    not end ACCEPTED, and the seconds they took in all."""
    from mission_gcs import plan

    failed = 0
    start = time.time()
    with tempfile.TemporaryDirectory() as storage:
        v, radio = _radio_vehicle(storage, loss, seed=20)
        try:
            m = v.gcs(port=radio.port)
            for k in range(runs):
                c = _client(m)
                c.drain(0.3)
                if c.upload(plan(N_20, tag=k + 1)) != 0:
                    failed += 1
        finally:
            v.stop()
            radio.close()
    return failed, time.time() - start


def run():
    from mission_gcs import plan

    out = {}
    items = plan(N, tag=1)
    _timed(out, 0.0, ("upload", "download"), items)
    _timed(out, 0.1, ("upload",), items)
    out["mission_upload_500_lossy_bound_s"] = round(2 * out["mission_upload_500_s"], 2)
    out["mission_upload_500_lossy_ratio"] = round(out["mission_upload_500_lossy_s"]
                                                  / out["mission_upload_500_s"], 2)
    failed, seconds = _cancelled(RUNS_20, 0.2)
    out["mission_cancelled_200_lossy20"] = failed
    out["mission_uploads_200_lossy20"] = RUNS_20
    out["mission_upload_200_lossy20_mean_s"] = round(seconds / RUNS_20, 2)
    return out


def floors(results):
    out = []
    for what in ("upload", "download"):
        ratio = results["mission_%s_%d_s" % (what, N)] / results["mission_%s_%d_bound_s" % (what, N)]
        out.append(("mission %s of %d items at 57600 baud within 1.5x its line-rate bound (%.2fx)"
                    % (what, N, ratio), ratio <= 1.5))
    ratio = results["mission_upload_500_lossy_ratio"]
    out.append(("mission upload of %d items with 10%% of frames lost within 2x the loss-free time (%.2fx)"
                % (N, ratio), ratio <= 2.0))
    failed = results["mission_cancelled_200_lossy20"]
    out.append(("no upload of %d items with 20%% of frames lost cancelled (%d of %d)"
                % (N_20, failed, results["mission_uploads_200_lossy20"]), failed == 0))
    return out


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
