"""Faults contained on MicroPython: beside status, params, commands, missions and streams, a
handler that raises on one message id (NAMED_VALUE_INT) and a service whose tick raises on
every 100th call.

    faults_steady.py ROUNDS
A round is 50 simulated ms: a parameter read, a whole download of the 3-item mission
(MISSION_REQUEST_LIST, MISSION_REQUEST_INT 0-2, MISSION_ACK), ATTITUDE streamed at 10 Hz, a
HEARTBEAT each second. First ROUNDS rounds without faults, twice (heap_requests: counted
with mem_total, then under heap_lock): the normal path asks nothing of the heap. Then ROUNDS
rounds with a NAMED_VALUE_INT each round and the faulty tick, under heap_lock: every read
answered, every download whole, streams flowing, the faults counted (SYS_STATUS
errors_count2, errors_count3) and reported (STATUSTEXT "Fault: ...").
Prints `ok rounds=N params=N downloads=N attitude=N msg_faults=N tick_faults=N texts=N
errors2=N errors3=N requested=N`, or FAIL and the same.
"""
import sys

import micropython

from harness import Bench, Board, heap_requests
from mavstack.faults import MESSAGE, TICK
from mavstack.services.params import READ_ONLY, REAL32, UINT8


class FaultsBoard(Board):
    NAME = "faults"
    PARAMS = (("MAV_SYS_ID", UINT8, 1, 1, 255, READ_ONLY), ("WP_SPEED", REAL32, 2.0, 0.1, 20.0),
              ("FS_HOLD_S", REAL32, 5.0, 0.0, 60.0))
    DEFAULT_STREAMS = ((30, 10), (1, 1))  # ATTITUDE, SYS_STATUS
    MISSION_CAPACITY = 20
    FENCE_CAPACITY = 0
    RALLY_CAPACITY = 0
    PARAM_AUTOSAVE_MS = 0


class Faulty:
    """A service with bugs: its handler of NAMED_VALUE_INT raises, and so does every 100th
    tick while `on`."""

    NAME = "faulty"
    CLOCK = False

    def __init__(self):
        self.on = False
        self.n = 0

    def attach(self, ep):
        ep.on(252, self.handle)

    def handle(self, link, p):
        raise ValueError

    def tick(self, now):
        if self.on:
            self.n += 1
            if self.n == 100:
                self.n = 0
                raise RuntimeError


GOT = [0, 0, 0, 0, 0]  # PARAM_VALUE, downloads done, ATTITUDE, STATUSTEXT "Fault", errors_count2
ERRORS3 = [0]


class Station:
    def __init__(self, b):
        self.b = b
        g = b.gcs(255, 190)
        self.hb = g.heartbeat()
        self.reads = [g.frame(20, i, 1, 1, b"") for i in range(3)]
        self.list = g.frame(43, 1, 1, 0)
        self.reqs = [g.frame(51, k, 1, 1, 0) for k in range(3)]
        self.ack = g.frame(47, 1, 1, 0, 0)
        self.bad = g.frame(252, 0, 7, b"fault")
        one, ten = 1.0, 10.0
        self.items = [g.frame(73, one, 0.0, 0.0, 0.0, 473977420 + k, 85455940, ten, k, 16, 1, 1, 3, 0, 1, 0)
                      for k in range(3)]
        self.count = g.frame(44, 3, 1, 1, 0)
        self.faults = False

    def watch(self, msgid, p):
        if msgid == 22:
            GOT[0] += 1
        elif msgid == 44 and p[2] == 255:  # MISSION_COUNT to us: ask for the items
            self.b.send(self.reqs[0])
        elif msgid == 73 and p[32] == 255:  # MISSION_ITEM_INT
            seq = p[28] | p[29] << 8
            if seq < 2:
                self.b.send(self.reqs[seq + 1])
            else:
                self.b.send(self.ack)
                GOT[1] += 1
        elif msgid == 51 and p[2] == 255:  # MISSION_REQUEST_INT during the upload
            self.b.send(self.items[p[0]])
        elif msgid == 30:
            GOT[2] += 1
        elif msgid == 253 and p[1] == 70 and p[2] == 97:  # "Fa(ult: ...)"
            GOT[3] += 1
        elif msgid == 1:
            GOT[4] = p[24] | p[25] << 8
            ERRORS3[0] = p[26] | p[27] << 8

    def rounds(self, n):
        r = 0
        while r < n:
            if r % 20 == 0:
                self.b.send(self.hb)
            self.b.send(self.reads[r % 3])
            self.b.send(self.list)
            if self.faults:
                self.b.send(self.bad)
            self.b.run(50)
            r += 1


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    b = Bench(services=("status", "params", "commands", "missions", "streams"), board=FaultsBoard,
              storage="ram")
    faulty = b.ep.add(Faulty())
    st = Station(b)
    b.watch = st.watch
    z = 0.0
    b.ep.telemetry.attitude(z, z, z, z, z, z)  # the slot's value: streamed from now on
    b.send(st.count)  # the mission the rounds download
    b.run(200)
    st.rounds(20)  # warm-up: every path once
    GOT[0] = GOT[1] = GOT[2] = 0
    requested = heap_requests(st.rounds, rounds)
    clean = GOT[0] == 2 * rounds and GOT[1] == 2 * rounds and b.ep.faults.counts[MESSAGE] == 0
    GOT[0] = GOT[1] = GOT[2] = GOT[3] = 0
    faulty.on = True
    st.faults = True
    micropython.heap_lock()
    try:
        st.rounds(rounds)
    finally:
        micropython.heap_unlock()
    faulty.on = False
    b.run(2000)  # the last report, and SYS_STATUS with the counts
    faults = b.ep.faults
    msg_faults = faults.source_count(MESSAGE, 252)
    tick_faults = faults.counts[TICK]
    good = (clean and GOT[0] == rounds and GOT[1] == rounds and GOT[2] >= rounds * 4 // 10
            and msg_faults == rounds and tick_faults >= rounds * 50 // 100 - 1 and GOT[3] >= 1
            and GOT[4] == msg_faults and ERRORS3[0] == tick_faults and requested == 0)
    print("%s rounds=%d params=%d downloads=%d attitude=%d msg_faults=%d tick_faults=%d texts=%d "
          "errors2=%d errors3=%d requested=%d" % ("ok" if good else "FAIL", rounds, GOT[0], GOT[1], GOT[2],
                                                  msg_faults, tick_faults, GOT[3], GOT[4], ERRORS3[0], requested))


main()
