"""A peripheral (the peripheral, params, commands and camera services) in steady state
under micropython.heap_lock().

    peripheral_steady.py [ROUNDS]
Built with SYSID "follow": it must send nothing until an autopilot's HEARTBEAT (system 7)
comes, then stamp 7 on everything. Then each 1 ms round: the application's
DISTANCE_SENSOR every 20 ms and NAMED_VALUE_FLOAT/INT every 100 ms; the interval
capture's CAMERA_IMAGE_CAPTURED every 50 ms; and a burst every 25 rounds: HEARTBEATs of
the autopilot and a ground station, PARAM_REQUEST_READ by index and by name, a
PARAM_REQUEST_LIST to component 0, REQUEST_MESSAGE (DISTANCE_SENSOR, CAMERA_INFORMATION,
CAMERA_SETTINGS, CAMERA_CAPTURE_STATUS, STORAGE_INFORMATION), a single IMAGE_START_CAPTURE, the application's
own command, an unknown one for component 0 (no ACK) and one for the autopilot (not ours).
Rounds run twice: unlocked, counted with micropython.mem_total(), then under heap_lock().
Prints `OK silent=N sysid=7 ... requested=0` (figures of the locked run), or FAIL.
"""
import sys

import micropython

from harness import Bench
from mavstack.services.params import INT32

COMPID = 158
_CMD_USER_1 = 31010


class Board:
    NAME = "peripheral_bench"
    MAV_TYPE = 0
    ACK_UNSUPPORTED_BROADCAST = False
    PARAM_ENCODING = "bytewise"
    PARAMS = (
        ("RNGFND_RATE_HZ", INT32, 50, 1, 50),
        ("RNGFND_MIN_CM", INT32, 20, 0, 65535),
        ("RNGFND_MAX_CM", INT32, 700, 1, 65535),
    )


class App:
    """DISTANCE_SENSOR each 20 ms, NAMED_VALUE_FLOAT and _INT each 100 ms; its own command."""

    def __init__(self, ep):
        per = ep.services["peripheral"]
        self.sensor = per.distance_sensor(20, 700)
        self.temp = per.named_float("TEMP")
        self.count = per.named_int("COUNT")
        self.celsius = 21.5  # made once: a float is a heap object
        self.n = 0
        self.d = 150
        self.paused = 0
        ep.commands[_CMD_USER_1] = self.command

    def command(self, cmd):
        self.paused = cmd.int(1) == 0
        return 0

    def tick(self, now):
        self.n += 1
        if self.paused or self.n % 20:
            return
        self.d = 100 + (self.d + 7) % 300
        self.sensor.send(self.d, 90)
        if self.n % 100 == 0:
            self.temp.send(self.celsius)
            self.count.send(self.n & 0xFFFF)


class Steady:
    def __init__(self, b, frames):
        self.b = b
        self.frames = frames
        self.k = 0


def build():
    b = Bench(services=("peripheral", "params", "commands", "camera"), board=Board, sysid=0, compid=COMPID, app=App)
    ap = b.gcs(7, 1)
    g = b.gcs(255, 190)
    to = 7
    frames = (
        ap.frame(0, 0, 2, 3, 0, 4, 3),  # the autopilot's HEARTBEAT (a quadrotor, ArduPilot)
        g.heartbeat(),
        g.frame(20, 1, to, COMPID, b""),  # PARAM_REQUEST_READ by index
        g.frame(20, -1, to, COMPID, b"RNGFND_MAX_CM"),  # ... by name
        g.frame(21, to, 0),  # PARAM_REQUEST_LIST to component 0
        g.command(512, 132.0, target_system=to, target_component=COMPID),  # REQUEST_MESSAGE
        g.command(512, 259.0, target_system=to, target_component=COMPID),  # CAMERA_INFORMATION
        g.command(512, 260.0, target_system=to, target_component=COMPID),  # CAMERA_SETTINGS
        g.command(527, 1.0, target_system=to, target_component=COMPID),  # CAMERA_CAPTURE_STATUS
        g.command(512, 261.0, target_system=to, target_component=COMPID),  # STORAGE_INFORMATION
        g.command(2000, 0.0, 0.0, 1.0, target_system=to, target_component=COMPID),  # one image (refused while capturing)
        g.command(_CMD_USER_1, 1.0, target_system=to, target_component=COMPID),  # the application's own
        g.command(31000, target_system=to, target_component=0),  # unknown, for every component: no ACK
        g.command(400, 1.0, target_system=to, target_component=1),  # the autopilot's: not ours
    )
    return b, frames


def steady(s, rounds):
    i = 0
    while i < rounds:
        if i % 25 == 0:
            s.b.send(s.frames[s.k])
            s.k += 1
            if s.k == len(s.frames):
                s.k = 0
        s.b.run(1)
        i += 1


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
    b, frames = build()
    s = Steady(b, frames)
    # Before the autopilot: GCS heartbeats and requests, and nothing goes out.
    k = 1
    while k < len(frames):
        b.send(frames[k])
        b.run(20)
        k += 1
    silent = 0
    for msgid in b.seen:
        silent += b.seen[msgid]
    b.send(frames[0])
    b.run(5)
    sysid = b.ep.sysid
    # An interval capture running through the rounds: an image each 50 ms, until stopped.
    b.send(b.gcs(255, 190).command(2000, 0.0, 0.05, 0.0, target_system=7, target_component=COMPID))
    steady(s, 1000)  # warm up: first-time paths may allocate
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    seen0 = dict(b.seen)
    acks0 = b.acks
    unsupported0 = b.results[3]
    micropython.heap_lock()
    try:
        steady(s, rounds)
    finally:
        micropython.heap_unlock()
    d = {}
    for msgid in (0, 22, 77, 132, 251, 252, 259, 260, 261, 262, 263):
        d[msgid] = b.seen[msgid] - seen0[msgid]
    ok = (silent == 0 and sysid == 7 and requested == 0 and b.rx.sysid == 7 and b.rx.compid == COMPID
          and d[132] > 0 and d[263] > 0 and d[259] > 0 and d[261] > 0 and d[22] > 0 and b.results[3] == unsupported0)
    print("%s silent=%d sysid=%d rounds=%d heartbeats=%d param_values=%d acks=%d distance=%d named=%d "
          "camera_info=%d settings=%d storage=%d capture_status=%d captured=%d requested=%d"
          % ("OK" if ok else "FAIL", silent, sysid, rounds, d[0], d[22], b.acks - acks0, d[132], d[251] + d[252],
             d[259], d[260], d[261], d[262], d[263], requested))


main()
