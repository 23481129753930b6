"""Radio flow control: frames lost to a telemetry radio's transmit buffer over 60 s, with
the vehicle's flow control on and off.

The unix vehicle (`--set udp_bytes_per_s=5760`: its serial port to the radio at 57600
baud) behind tests/radio_rig.py's modelled SiK radio (2048-byte buffer, 3500 B/s over the
air, RADIO_STATUS once a second), a pymavlink ground station downloading every parameter
and a 100-item mission over and over, the default streams running. Keys:
radio_overflow_on / _off (frames the radio dropped), radio_overflow_pct_on / _off (of
the frames the vehicle sent it), radio_downloads_on / _off (parameter and mission
downloads completed), radio_flow_min_on (the least scale the vehicle reported, %).
tests/test_radio_flow.py holds the 60 s with flow control on to no loss.

    .venv/bin/python bench/bench_radio.py
"""
import json
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
import radio_rig  # noqa: E402
from vehicle import Vehicle  # noqa: E402

SECONDS = 60


def session(flow):
    args = ["--set", "udp_bytes_per_s=5760"] + ([] if flow else ["--set", "radio_flow=0"])
    with tempfile.TemporaryDirectory() as tmp:
        v = Vehicle(os.path.join(tmp, "storage"), args=args).start()
        try:
            return radio_rig.session(v, SECONDS)
        finally:
            v.stop()


def run():
    r = {}
    for flow, tag in ((True, "on"), (False, "off")):
        s = session(flow)
        r["radio_overflow_" + tag] = s["overflow"]
        r["radio_overflow_pct_" + tag] = round(100.0 * s["overflow"] / max(1, s["frames"]), 2)
        r["radio_downloads_" + tag] = s["params"] + s["missions"]
        if flow:
            r["radio_flow_min_on"] = s["flow_min"]
    return r


def floors(r):
    return [("radio_overflow_on == 0", r["radio_overflow_on"] == 0)]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
