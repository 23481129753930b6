"""Status and command handling in steady state under micropython.heap_lock().

    status_steady.py SERVICES [STORAGE] [ROUNDS]
SERVICES is a comma list (status,commands[,params,...]). A ground station's heartbeat
every simulated second, and a burst of commands each 50 ms: arm/disarm, an unknown
command, REQUEST_MESSAGE (SYS_STATUS, AUTOPILOT_VERSION), COMMAND_INT, SET_MODE, PING,
a corrupted frame, a STATUSTEXT. Prints one line of figures; any allocation raises MemoryError.
"""
import sys

import micropython

from harness import Bench


def build(services, storage):
    b = Bench(services=services, storage=storage)
    g = b.gcs()
    frames = (
        g.heartbeat(),
        g.command(400, 1.0),  # arm
        g.command(400, 0.0),  # disarm
        g.command(31000),  # unknown
        g.command(512, 1.0),  # REQUEST_MESSAGE SYS_STATUS
        g.command(512, 148.0),  # REQUEST_MESSAGE AUTOPILOT_VERSION
        g.command_int(176, 0, 1.0 + 16, 3.0),  # DO_SET_MODE as COMMAND_INT
        g.frame(11, 0, 1, 4 | 16),  # SET_MODE
        g.frame(4, 1234567, 9, 0, 0),  # PING request
        g.command(400, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1, 1, 1),  # arm, confirmation 1
        g.command(400, 0.0, 21196.0),  # forced disarm
    )
    bad = bytearray(frames[3])
    bad[-1] ^= 0xFF  # CRC error
    return b, frames[0], frames[1:], bad


def steady(b, hb, burst, bad, rounds):
    k = 0
    for i in range(rounds):
        if i % 1000 == 0:
            b.send(hb)
        if i % 700 == 0:
            b.ep.statustext(6, b"steady state")
        if i % 50 == 0:
            b.send(burst[k])
            k += 1
            if k == len(burst):
                k = 0
                b.send_raw(bad)
        b.run(1)


def main():
    services = sys.argv[1].split(",") if len(sys.argv) > 1 else ("status", "commands")
    storage = sys.argv[2] if len(sys.argv) > 2 and sys.argv[2] != "-" else None
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 5000
    b, hb, burst, bad = build(services, storage)
    steady(b, hb, burst, bad, 2000)  # warm up: first-time paths may allocate
    acks0 = b.acks
    hb0 = b.seen[0]
    micropython.heap_lock()
    try:
        steady(b, hb, burst, bad, rounds)
    finally:
        micropython.heap_unlock()
    st = b.ep.services["status"]
    print("OK rounds=%d acks=%d heartbeats=%d sys_status=%d version=%d ping=%d errors_comm=%d unsupported=%d text=%d"
          % (rounds, b.acks - acks0, b.seen[0] - hb0, b.seen[1], b.seen[148], b.seen[4], st.errors_comm,
             b.results[3], b.seen[253]))


main()
