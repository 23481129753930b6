"""A ground station and the missions service on one simulated clock, with a link between
them that drops, duplicates and holds back whole frames, and a vehicle that sometimes
stalls (a busy host, a radio's retries) while frames queue for it: the fault test's
bad link (test_faults.py), made deterministic and hundreds of times faster, so that
rare orderings (a frame of one upload held back into the next) come up in every run.

    w = World(tmp_path, seed=1, rate=0.3, stall=0.0005)
    w.upload(items) -> "accepted" | "refused" | "unsure"      as fault_gcs.Gcs.upload
    w.download() -> item tuples or None
    w.stored() -> the plan in force, read from the store
Items are (frame, command, p1, p2, p3, p4, x, y, z). The ground station numbers its
frames as a real one does (pymavlink's send counts each frame).
"""
import heapq
import math
import random
import struct

from mission_rig import Rig

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


class World:
    def __init__(self, tmp_path, seed, rate=0.3, delay_ms=20, stall=0.0):
        self.rng = random.Random(seed)
        self.r = Rig(tmp_path, name="lossy%d" % seed)
        self.rate = rate
        self.delay_ms = delay_ms
        self.stall = stall  # chance per ms that the vehicle stops for 0.1 .. 3 s
        self.now = 0
        self.n = 0
        self.to_vehicle = []  # heaps of (due ms, order, frame or message)
        self.to_gcs = []
        self.inbox = []
        self.stalled_until = 0

    # --- the link -------------------------------------------------------------------
    def _put(self, queue, what):
        rng = self.rng
        copies, delay = 1, 0
        if rng.random() < self.rate:
            fault = rng.randrange(3)
            if fault == 0:
                return
            if fault == 1:
                copies = 2
            else:
                delay = rng.randint(1, self.delay_ms)
        for _ in range(copies):
            self.n += 1
            heapq.heappush(queue, (self.now + delay, self.n, what))

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
                    self._put(self.to_gcs, m)
        while self.to_gcs and self.to_gcs[0][0] <= self.now:
            self.inbox.append(heapq.heappop(self.to_gcs)[2])
        self.now += 1

    # --- the ground station (as fault_gcs.Gcs, in simulated ms) -----------------------
    def send(self, name, *args):
        mav = self.r.mav(255, 190)
        frame = bytes(getattr(mav, name + "_encode")(*args).pack(mav))
        mav.seq = (mav.seq + 1) & 0xFF  # as pymavlink's send() counts
        self._put(self.to_vehicle, frame)

    def recv(self, types, cond=None, timeout=600):
        end = self.now + timeout
        while self.now < end:
            self.step()
            while self.inbox:
                m = self.inbox.pop(0)
                if m.get_type() in types and (cond is None or cond(m)):
                    return m
        return None

    def ask(self, send, types, cond=None, tries=8):
        for _ in range(tries):
            send()
            got = self.recv(types, cond)
            if got is not None:
                return got
        return None

    def upload(self, items):
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        self.recv((), None, 300)  # MISSION_ACK names no upload: let late ones go by
        got = self.ask(lambda: self.send("mission_count", 1, 1, len(items), 0), kinds)
        last = None
        silent = 0
        while True:
            if got is None:
                silent += 1
                if last is None:
                    return "refused"
                if silent > 4:
                    return "unsure"
                self._item(last, items[last])
                got = self.recv(kinds)
                continue
            silent = 0
            if got.get_type() == "MISSION_ACK":
                if got.type == 0:
                    return "accepted"
                return "refused" if last is None else "unsure"
            if got.seq >= len(items):
                return "unsure"
            self._item(got.seq, items[got.seq])
            last = got.seq
            got = self.recv(kinds, timeout=1200)

    def _item(self, seq, item):
        frame, command, p1, p2, p3, p4, x, y, z = item
        self.send("mission_item_int", 1, 1, seq, frame, command, 0, 1, p1, p2, p3, p4, x, y, z, 0)

    def download(self):
        count = self.ask(lambda: self.send("mission_request_list", 1, 1, 0), ("MISSION_COUNT",))
        if count is None:
            return None
        items = []
        for seq in range(count.count):
            got = self.ask(lambda: self.send("mission_request_int", 1, 1, seq, 0), ("MISSION_ITEM_INT",),
                           lambda m: m.seq == seq)
            if got is None:
                return None
            items.append((got.frame, got.command, got.param1, got.param2, got.param3, got.param4,
                          got.x, got.y, got.z))
        self.send("mission_ack", 1, 1, 0, 0)
        return items

    def stored(self):
        store = self.r.missions.stores[0]
        rec = bytearray(32)
        out = []
        for seq in range(store.count):
            assert store.read(seq, rec)
            p1, p2, p3, p4, x, y, z, command, frame = struct.unpack_from("<ffffiifHB", rec)
            out.append((frame, command, p1, p2, p3, p4, x, y, z))
        return out
