"""UDP relays put between a ground station and a vehicle's udpin port: a lossy link
(drops, duplicates, reorders) for the tests, and a paced radio for the benchmarks.

The ground station talks to relay.port; each MAVLink frame is one datagram. A relay
subclass decides in forward() what becomes of each datagram: send() it now, deliver()
it later, or neither.
"""
import heapq
import random
import select
import socket
import threading
import time

TO_VEHICLE = 0
TO_GCS = 1


class Relay:
    def __init__(self, vehicle_port, seed=1):
        self.rng = random.Random(seed)
        self.gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.gcs_sock.bind(("127.0.0.1", 0))
        self.port = self.gcs_sock.getsockname()[1]
        self.veh_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.veh_sock.bind(("127.0.0.1", 0))
        self.vehicle = ("127.0.0.1", vehicle_port)
        self.gcs = None
        self._later = []  # (time, n, socket, data, address)
        self._n = 0
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def forward(self, way, sock, data, addr):
        self.send(sock, data, addr)

    def send(self, sock, data, addr):
        try:
            sock.sendto(data, addr)
        except OSError:
            pass

    def deliver(self, at, sock, data, addr):
        self._n += 1
        heapq.heappush(self._later, (at, self._n, sock, data, addr))

    def _run(self):
        socks = [self.gcs_sock, self.veh_sock]
        while not self._stop:
            wait = 0.05
            if self._later:
                wait = max(0.0, min(wait, self._later[0][0] - time.time()))
            ready, _, _ = select.select(socks, [], [], wait)
            for s in ready:
                try:
                    data, addr = s.recvfrom(4096)
                except OSError:
                    continue
                if s is self.gcs_sock:
                    self.gcs = addr
                    self.forward(TO_VEHICLE, self.veh_sock, data, self.vehicle)
                elif self.gcs is not None:
                    self.forward(TO_GCS, self.gcs_sock, data, self.gcs)
            now = time.time()
            self.tick(now)
            while self._later and self._later[0][0] <= now:
                _, _, sock, data, addr = heapq.heappop(self._later)
                self.send(sock, data, addr)

    def tick(self, now):
        """Called every 50 ms at most (subclasses with something periodic)."""

    def close(self):
        self._stop = True
        self._thread.join(2)
        self.gcs_sock.close()
        self.veh_sock.close()


class LossyRelay(Relay):
    """Disturbs a frame with probability `rate`, both ways: drops it, duplicates it, or
    holds it back `delay` seconds (so that it arrives out of order). Frames whose
    message id is in `spare` pass undisturbed."""

    def __init__(self, vehicle_port, rate=0.2, delay=(0.001, 0.006), seed=1, drop_only=False, spare=()):
        self.rate = rate
        self.delay = delay
        self.drop_only = drop_only
        self.spare = spare
        self.stats = {"frames": 0, "dropped": 0, "duplicated": 0, "delayed": 0}
        Relay.__init__(self, vehicle_port, seed)

    def forward(self, way, sock, data, addr):
        self.stats["frames"] += 1
        if self.rng.random() < self.rate and not (self.spare and msgid(data) in self.spare):
            what = 0 if self.drop_only else self.rng.randrange(3)
            if what == 0:
                self.stats["dropped"] += 1
                return
            if what == 1:
                self.stats["duplicated"] += 1
                self.send(sock, data, addr)
            else:
                self.stats["delayed"] += 1
                self.deliver(time.time() + self.rng.uniform(*self.delay), sock, data, addr)
                return
        self.send(sock, data, addr)


def msgid(data):
    """The message id of a datagram holding one MAVLink frame, -1 if it holds none."""
    if data[:1] == b"\xfd" and len(data) >= 10:
        return data[7] | data[8] << 8 | data[9] << 16
    if data[:1] == b"\xfe" and len(data) >= 6:
        return data[5]
    return -1


class Radio(Relay):
    """The timing of a full-duplex serial radio: each way carries bytes_per_s; a frame
    leaves when the one before it has gone and arrives when its last byte has. `loss`
    drops that share of frames (they still take their air time). Bytes of frames whose
    id is in `counted` are added up in counted_bytes."""

    def __init__(self, vehicle_port, bytes_per_s, loss=0.0, seed=7, counted=()):
        self.rate = float(bytes_per_s)
        self.loss = loss
        self.counted = counted
        self.counted_bytes = 0
        self.free = {TO_VEHICLE: 0.0, TO_GCS: 0.0}  # when each way's air is free again
        Relay.__init__(self, vehicle_port, seed)

    def forward(self, way, sock, data, addr):
        start = max(time.time(), self.free[way])
        self.free[way] = start + len(data) / self.rate
        if msgid(data) in self.counted:
            self.counted_bytes += len(data)
        if self.loss and self.rng.random() < self.loss:
            return
        self.deliver(self.free[way], sock, data, addr)
