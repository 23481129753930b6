"""Full parameter download over a 57600 baud radio, with telemetry flowing, measured
end to end.

The unix vehicle runs with `--set udp_bytes_per_s=5760` behind a relay that plays the
radio (tests/relay.py: 5760 B/s each way), with the telemetry a radio board sends by
default (boards/radio.py), asked for as a ground station would. pymavlink asks for the
list through the radio and times it until every parameter has arrived: the median of
five lists, back to back. The line-rate bound is the bytes those PARAM_VALUE frames took
at 5760 B/s; the ATTITUDE frames received all the while (their rate against the 4 Hz
set, the longest gap) show the telemetry kept flowing. The figures: docs/testing.md.

    .venv/bin/python bench/bench_params.py
"""
import json
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from vehicle import Vehicle  # noqa: E402
from relay import Radio  # noqa: E402
BYTES_PER_S = 5760
RUNS = 5
ATTITUDE_HZ = 4.0
# boards/radio.py's DEFAULT_STREAMS: (message id, Hz)
RADIO_STREAMS = ((1, 1), (42, 1), (24, 1), (30, ATTITUDE_HZ), (33, 2), (74, 2), (147, 0.5), (245, 0.5), (242, 0.2))


def _radio_telemetry(m):
    """Every stream off, then the radio board's set, as a ground station sets them."""
    m.mav.request_data_stream_send(1, 1, 0, 0, 0)  # MAV_DATA_STREAM_ALL, stop
    for msgid, hz in RADIO_STREAMS:
        m.mav.command_long_send(1, 1, 511, 0, msgid, 1e6 / hz, 0, 0, 0, 0, 0)  # SET_MESSAGE_INTERVAL
        m.recv_match(type="COMMAND_ACK", blocking=True, timeout=2)
    time.sleep(2.0)  # the streams settle at their rates


def _list_once(m, attitude):
    """Seconds for a full list and the bytes its PARAM_VALUE frames took; the
    time_boot_ms of every ATTITUDE received meanwhile goes into attitude."""
    seen = {}
    wire = 0
    count = None
    start = time.time()
    m.mav.param_request_list_send(1, 1)
    while count is None or len(seen) < count:
        msg = m.recv_match(type=["PARAM_VALUE", "ATTITUDE"], blocking=True, timeout=10)
        if msg is None:
            raise RuntimeError("list stalled at %d of %s" % (len(seen), count))
        if msg.get_type() == "ATTITUDE":
            attitude.append(msg.time_boot_ms)
            continue
        count = msg.param_count
        if msg.param_index not in seen:
            seen[msg.param_index] = True
            wire += len(msg.get_msgbuf())
    return time.time() - start, wire, count


def run():
    import tempfile

    with tempfile.TemporaryDirectory() as storage:
        v = Vehicle(storage, args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S]).start()
        radio = Radio(v.port, BYTES_PER_S)
        try:
            m = v.gcs(port=radio.port)
            _radio_telemetry(m)
            while m.recv_match(blocking=False) is not None:
                pass  # what came before the first request is not counted
            times = []
            attitude = []
            for _ in range(RUNS):  # back to back: ATTITUDE is watched all along
                seconds, wire, count = _list_once(m, attitude)
                times.append(seconds)
        finally:
            v.stop()
            radio.close()
    times.sort()
    seconds = times[len(times) // 2]
    bound = wire / BYTES_PER_S
    # The rate ATTITUDE was produced at while the lists went out, from its own clock
    # (the radio delays frames, so arrival times would blur it), and its longest gap.
    span_ms = attitude[-1] - attitude[0]
    gaps = [b - a for a, b in zip(attitude, attitude[1:])]
    return {
        "param_list_s_57600": round(seconds, 3),
        "param_list_bound_s_57600": round(bound, 3),
        "param_list_ratio_57600": round(seconds / bound, 2),
        "param_list_count": count,
        "param_list_attitude_hz": round((len(attitude) - 1) * 1000.0 / span_ms, 2),
        "param_list_attitude_set_hz": ATTITUDE_HZ,
        "param_list_attitude_max_gap_ms": max(gaps),
    }


def floors(results):
    ratio = results["param_list_s_57600"] / results["param_list_bound_s_57600"]
    hz = results["param_list_attitude_hz"]
    return [
        ("param list at 57600 baud within 1.25x its line-rate bound (%.2fx)" % ratio, ratio <= 1.25),
        ("ATTITUDE keeps flowing during the lists, >= 3/4 of its %g Hz (%.2f Hz, longest gap %d ms)"
         % (ATTITUDE_HZ, hz, results["param_list_attitude_max_gap_ms"]), hz >= 0.75 * ATTITUDE_HZ),
    ]


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("ok  " if ok else "MISS", text)
