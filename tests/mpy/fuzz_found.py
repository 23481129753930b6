"""What the fuzzer found on the 32-bit board (tests/test_mcu_fuzz.py), each under
heap_lock: a command parameter of 2^30 or more read as an int (PREFLIGHT_STORAGE,
DO_SET_MISSION_CURRENT), SET_MODE with a custom mode of 2^30 or more, SET_MODE and
DO_SET_MODE with flags a board without a mode table refuses, DO_SET_HOME at a position
(floats, ints past 2^30) and at a float32 altitude of 3e38, and SET_MESSAGE_INTERVAL of
1e9 us while the radio's RADIO_STATUS squeezes the link (the stretched interval passed 2^30
on the way). Each is answered, none is a fault. The frames that are not rare events take
nothing from the heap.

    fuzz_found.py
Prints `ok faults=0 acks=N home_refused=N home=N requested=N`, or FAIL and the same.
"""
import micropython

from harness import Bench, Board, heap_requests
from mavstack.services.params import READ_ONLY, UINT8

_ACK = 77
HOME = [0, 0]  # DO_SET_HOME answers: refused, ACCEPTED


class FlagBoard(Board):
    """No mode table, as the emulated boards: modes are MAV_MODE_FLAG bits alone."""
    NAME = "found"
    PARAMS = (("MAV_SYS_ID", UINT8, 1, 1, 255, READ_ONLY),)
    MISSION_CAPACITY = 4
    FENCE_CAPACITY = 0
    RALLY_CAPACITY = 0
    PARAM_AUTOSAVE_MS = 0


def main():
    b = Bench(services=("status", "params", "commands", "missions", "streams"), board=FlagBoard,
              storage="ram")
    g = b.gcs(255, 190)
    big = 3.0e9
    plain = [
        g.command(245, big),  # PREFLIGHT_STORAGE 3e9
        g.command(224, big),  # DO_SET_MISSION_CURRENT 3e9
        g.command(224, -big),
        g.frame(11, 0xC0000000, 1, 1),  # SET_MODE custom 0xC0000000
        g.frame(11, 0, 1, 0x20),  # SET_MODE: flags a board without a table refuses
        g.command(176, 0x20),  # DO_SET_MODE, the same
    ]
    homes = [  # DO_SET_HOME: refused, refused, ACCEPTED, ACCEPTED
        g.command(179, 0.0, 0.0, 0.0, 0.0, 47.0, 8.0, 3.0e38),  # altitude 3e38
        g.command(179, 0.0, 0.0, 0.0, 0.0, 1.0e30, 8.0, 500.0),  # latitude 1e30
        g.command(179, 0.0, 0.0, 0.0, 0.0, 47.397742, 8.545594, 500.0),
        g.command_int(179, 0, 0.0, 0.0, 0.0, 0.0, 473977420, -1795455940, 500.0),  # past 2^30
    ]
    b.send(g.heartbeat())
    b.run(100)

    def plain_frames(_):
        for f in plain:
            b.send(f)
            b.run(2)

    plain_frames(0)  # warm-up: every path once
    acks = b.acks
    requested = heap_requests(plain_frames, 0)
    acks = b.acks - acks
    micropython.heap_lock()  # DO_SET_HOME opens the heap for itself (a rare event)
    try:
        for f in homes:
            b.send(f)
            b.run(2)
            if b.ack_command == 179:
                HOME[b.ack_result == 0] += 1
    finally:
        micropython.heap_unlock()
    radio = b.gcs(51, 68)  # a SiK radio: its buffer full, the link's budget squeezed
    squeeze = [radio.frame(109, 0, 0, 100, 100, 0, 0, 0) for _ in range(6)]
    squeeze += [g.command(511, 30.0, 1.0e9), g.command(511, 33.0, 1000.0), g.command(511, 24.0, 1000.0)]
    micropython.heap_lock()
    try:
        for f in squeeze:
            b.send(f)
            b.run(2)
    finally:
        micropython.heap_unlock()
    faults = sum(b.ep.faults.counts)
    good = faults == 0 and acks == 2 * 4 and HOME[0] == 2 and HOME[1] == 2 and requested == 0
    print("%s faults=%d acks=%d home_refused=%d home=%d requested=%d" % (
        "ok" if good else "FAIL", faults, acks, HOME[0], HOME[1], requested))


main()
