"""Mission upload and download of 500 items over a link paced as a 57600 baud radio.

The unix vehicle (`--set udp_bytes_per_s=5760`) talks to a pymavlink ground station
(tests/mission_gcs.py) through a relay that plays the radio: each direction carries
5760 bytes a second (57600 baud, 8N1), a frame leaves when the one before it has gone
and arrives when its last byte has; the vehicle's telemetry shares the air as on a
real radio. The protocol is lock-step (one item per request), so its line-rate bound
is every byte of the transfer's own frames (MISSION_COUNT, requests, items, ACK) at
5760 B/s, one after the other. The lossy run drops 10% of the frames each way (they
still take their air time); the vehicle re-requests after its default 250 ms, the
ground station re-sends requests after 250 ms too.

    .venv/bin/python bench/bench_missions.py
"""
import heapq
import json
import os
import random
import select
import socket
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from vehicle import Vehicle  # noqa: E402
BYTES_PER_S = 5760
N = 500
MISSION_IDS = (39, 40, 43, 44, 47, 51, 73)  # the transfer's own frames


def _msgid(data):
    if data[:1] == b"\xfd" and len(data) >= 10:
        return data[7] | data[8] << 8 | data[9] << 16
    if data[:1] == b"\xfe" and len(data) >= 6:
        return data[5]
    return -1


class Radio:
    """A UDP relay with the timing of a full-duplex serial radio, and optional loss."""

    def __init__(self, vehicle_port, bytes_per_s, loss=0.0, seed=7):
        self.rate = float(bytes_per_s)
        self.loss = loss
        self.rng = random.Random(seed)
        self.gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.gcs_sock.bind(("127.0.0.1", 0))
        self.port = self.gcs_sock.getsockname()[1]
        self.veh_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.veh_sock.bind(("127.0.0.1", 0))
        self.vehicle = ("127.0.0.1", vehicle_port)
        self.gcs = None
        self.free = {0: 0.0, 1: 0.0}  # when each direction's air is free again
        self.queue = []  # (arrival time, n, socket, data, address)
        self.n = 0
        self.mission_bytes = 0  # air time taken by the transfer's own frames, both ways
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _send(self, way, sock, data, addr):
        now = time.time()
        start = max(now, self.free[way])
        self.free[way] = start + len(data) / self.rate
        if _msgid(data) in MISSION_IDS:
            self.mission_bytes += len(data)
        if self.loss and self.rng.random() < self.loss:
            return
        self.n += 1
        heapq.heappush(self.queue, (self.free[way], self.n, sock, data, addr))

    def _run(self):
        socks = [self.gcs_sock, self.veh_sock]
        while not self._stop:
            wait = 0.05
            if self.queue:
                wait = max(0.0, min(wait, self.queue[0][0] - time.time()))
            ready, _, _ = select.select(socks, [], [], wait)
            for s in ready:
                try:
                    data, addr = s.recvfrom(4096)
                except OSError:
                    continue
                if s is self.gcs_sock:
                    self.gcs = addr
                    self._send(0, self.veh_sock, data, self.vehicle)
                elif self.gcs is not None:
                    self._send(1, self.gcs_sock, data, self.gcs)
            now = time.time()
            while self.queue and self.queue[0][0] <= now:
                _, _, sock, data, addr = heapq.heappop(self.queue)
                try:
                    sock.sendto(data, addr)
                except OSError:
                    pass

    def close(self):
        self._stop = True
        self._thread.join(2)
        self.gcs_sock.close()
        self.veh_sock.close()


def _transfer(radio, m, what, items):
    from mission_gcs import MissionClient, same

    c = MissionClient(m, timeout=0.25, retries=20)
    c.drain(0.3)
    radio.mission_bytes = 0
    start = time.time()
    if what == "upload":
        ok = c.upload(items) == 0
    else:
        got = c.download(ack=True)
        ok = got is not None and same(got, items)
    seconds = time.time() - start
    if not ok:
        raise RuntimeError("%s of %d items failed" % (what, len(items)))
    return seconds, radio.mission_bytes / BYTES_PER_S


def run():
    from mission_gcs import plan

    out = {}
    items = plan(N, tag=1)
    for loss, runs in ((0.0, ("upload", "download")), (0.1, ("upload",))):
        with tempfile.TemporaryDirectory() as storage:
            v = Vehicle(storage, args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S]).start()
            radio = Radio(v.port, BYTES_PER_S, loss)
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
