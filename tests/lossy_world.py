"""The fault test's bad link (test_faults.py) on a simulated clock: the missions service
in-process (mission_rig.py), fault_gcs.Gcs as the ground station, and between them a
link that drops, duplicates and holds back whole frames, to a vehicle that sometimes
stalls (a busy host, a radio's retries) while frames queue for it. Deterministic and
hundreds of times faster than the real thing, so that rare orderings (a frame of one
upload held back into the next) come up in every run.

    w = World(tmp_path, seed=1, rate=0.3, stall=0.001, hold_ms=1500)
    w.gcs.upload(items), w.gcs.download()     fault_gcs.Gcs, on the simulated clock
    w.stored() -> the plan in force, read from the store (plan_in_force(rig))
    w.step()    one simulated ms
Items are (frame, command, p1, p2, p3, p4, x, y, z), as fault_gcs's.
"""
import heapq
import math
import random
import struct

from fault_gcs import Gcs
from mission_rig import Rig
from pymavlink.dialects.v20 import common as mavlink2

_MISSION_ITEM_INT = 73
_TO_GCS = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "MISSION_COUNT", "MISSION_ITEM_INT")


def items_for(base, n):
    return [(3, 16, 0.0, 2.0, 0.0, float(base), 473977420 + 1000 * i + base, 85455940 + i, 20.0 + i)
            for i in range(n)]


def same_items(a, b):
    if a is None or b is None or len(a) != len(b):
        return False
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            if not (u == v or (isinstance(u, float) and math.isclose(u, v, rel_tol=1e-6, abs_tol=1e-6))):
                return False
    return True


def outcome_holds(outcome, now, new, old):
    """What fault_gcs.Gcs.upload's outcome says the vehicle now holds: "accepted" the new
    plan, "refused" the old one, "unsure" one or the other, never a mix."""
    if outcome == "accepted":
        return same_items(now, new)
    if outcome == "refused":
        return same_items(now, old)
    return same_items(now, new) or same_items(now, old)


class World:
    def __init__(self, tmp_path, seed, rate=0.3, delay_ms=20, stall=0.0, hold_ms=None):
        self.rng = random.Random(seed)
        self.r = Rig(tmp_path, name="lossy%d" % seed)
        self.rate = rate
        self.delay_ms = delay_ms  # the most a frame is held back
        # ... a mission item toward the vehicle (long: into the next upload). Nothing
        # tells a MISSION_COUNT held back past the end of its transfer from a restarted
        # ground station's first one (services/missions/upload.py): those keep to delay_ms.
        self.hold_ms = delay_ms if hold_ms is None else hold_ms
        self.stall = stall  # chance per ms that the vehicle stops for 0.1 .. 3 s
        self.now = 0  # ms
        self.n = 0
        self.to_vehicle = []  # heaps of (due ms, order, frame or message)
        self.to_gcs = []
        self.inbox = []
        self.stalled_until = 0
        # pymavlink's own encoder (it numbers each frame, as a ground station does),
        # writing into the link.
        self.mav = mavlink2.MAVLink(self, srcSystem=255, srcComponent=190)
        self.gcs = Gcs(self, clock=lambda: self.now / 1000.0)

    # --- the link -------------------------------------------------------------------
    def _put(self, queue, what, most):
        rng = self.rng
        copies, delay = 1, 0
        if rng.random() < self.rate:
            fault = rng.randrange(3)
            if fault == 0:
                return
            if fault == 1:
                copies = 2
            else:
                delay = rng.randint(1, most)
        for _ in range(copies):
            self.n += 1
            heapq.heappush(queue, (self.now + delay, self.n, what))

    def write(self, frame):
        """The ground station's pymavlink sends here."""
        frame = bytes(frame)
        self._put(self.to_vehicle, frame, self.hold_ms if frame[7] == _MISSION_ITEM_INT else self.delay_ms)

    def step(self):
        """One ms: frames due reach the vehicle (unless it is stalled), it runs, and what
        it sends starts toward the ground station."""
        if self.stall and self.now >= self.stalled_until and self.rng.random() < self.stall:
            self.stalled_until = self.now + self.rng.randint(100, 3000)
        if self.now >= self.stalled_until:
            while self.to_vehicle and self.to_vehicle[0][0] <= self.now:
                self.r.b.send_raw(bytearray(heapq.heappop(self.to_vehicle)[2]))
            self.r.run(1)
            for m in self.r.take():
                if m.get_type() in _TO_GCS and m.target_system == 255:
                    self._put(self.to_gcs, m, self.delay_ms)
        while self.to_gcs and self.to_gcs[0][0] <= self.now:
            self.inbox.append(heapq.heappop(self.to_gcs)[2])
        self.now += 1

    def recv_match(self, type=None, blocking=True, timeout=None):
        """pymavlink's: the next message of one of the types within timeout (simulated
        seconds); those of other types are passed over."""
        end = self.now + max(1, math.ceil((timeout or 0) * 1000))  # (time moves on each call)
        while True:
            while self.inbox:
                m = self.inbox.pop(0)
                if type is None or m.get_type() in type:
                    return m
            if self.now >= end:
                return None
            self.step()

    def stored(self):
        return plan_in_force(self.r)


def plan_in_force(rig):
    """The mission a Rig's vehicle holds, read from its store, as item tuples."""
    store = rig.missions.stores[0]
    rec = bytearray(32)
    out = []
    for seq in range(store.count):
        assert store.read(seq, rec)
        p1, p2, p3, p4, x, y, z, command, frame = struct.unpack_from("<ffffiifHB", rec)
        out.append((frame, command, p1, p2, p3, p4, x, y, z))
    return out
