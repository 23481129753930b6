"""The seed's remaining messages and commands delivered in steady state under heap_lock().

    seed_steady.py DIALECT [ROUNDS]      DIALECT: common or seed2012
A bench vehicle with the geography, debug, servos, auth, calibration, seed_commands and
seed_telemetry services gets, each round: SET_GPS_GLOBAL_ORIGIN, SAFETY_SET_ALLOWED_AREA,
NAMED_VALUE_FLOAT/INT, DEBUG, DEBUG_VECT, MEMORY_VECT, STATE_CORRECTION (seed set), an
unsigned AUTH_KEY (refused), DO_SET_RELAY, DO_REPEAT_RELAY, DO_SET_SERVO, DO_REPEAT_SERVO,
PREFLIGHT_CALIBRATION, PREFLIGHT_SET_SENSOR_OFFSETS (default: UNSUPPORTED), OVERRIDE_GOTO
hold and continue, NAV_ROI, NAV_PATHPLANNING, DO_CONTROL_VIDEO, CONDITION_YAW, NAV_LAST,
REQUEST_MESSAGE of GPS_GLOBAL_ORIGIN and SAFETY_ALLOWED_AREA; the application's handlers
and the setpoint-echo setters are called too. After a warm-up the rounds run unlocked,
counted with micropython.mem_total(), then under heap_lock(). Prints
`OK requested=0 acks=N ...` (figures of the locked run), or FAIL.
"""
import struct
import sys

import micropython

from harness import Bench

SERVICES = ("status", "commands", "missions", "seed_telemetry", "streams", "geography", "debug", "servos",
            "auth", "calibration", "seed_commands")


class Board:
    NAME = "bench"
    MAV_TYPE = 2
    MAV_AUTOPILOT = 0
    GCS_TIMEOUT_MS = 5000
    OPERATOR_PASSKEY = None
    PARAMS = ()
    RELAYS = 4
    SERVO_CHANNELS = (5, 16)
    AUTH_KEY = "vehicle-key"
    MISSION_CAPACITY = 10
    FENCE_CAPACITY = 4
    RALLY_CAPACITY = 2


COUNTS = [0, 0, 0]
UP_3M = -3.0  # made once: a negative float literal is negated at run time by some compilers (1.25's)
CHECKS = [-1, -1]  # check_item of the record inside, outside  # state corrections, debug values, relay/servo hardware calls


def on_state_correction(link, p):
    COUNTS[0] += 1


def on_debug(link, msgid, p):
    COUNTS[1] += 1


class Rounds:
    def __init__(self, b, frames, geo, echoes, lat, lon):
        self.b = b
        self.frames = frames
        self.geo = geo
        self.echoes = echoes
        self.lat = lat
        self.lon = lon
        self.rec_in = bytearray(32)
        struct.pack_into("<iif", self.rec_in, 16, lat, lon, 50.0)
        self.rec_out = bytearray(self.rec_in)
        struct.pack_into("<i", self.rec_out, 16, 473000000)

    def round(self):
        i = 0
        while i < len(self.frames):
            self.b.send(self.frames[i])
            i += 1
        self.b.run(40, 1)
        self.geo.local_offset(1.0, 2.0, 3.0, 0.1, 0.2, 0.3)
        e = self.echoes
        e.local_setpoint(1, 1.0, 2.0, UP_3M, 0.5)
        e.global_setpoint(0, self.lat, self.lon, 10000, 900)
        e.attitude_setpoint(0.1, 0.2, 0.3, 0.5)
        e.speed_setpoint(0.1, 0.2, 0.3, 0.5)
        e.rates_setpoint(0.1, 0.2, 0.3, 0.5)
        # A mission record inside the area and one south of it (missions' item check)
        CHECKS[0] = self.geo.check_item(self.rec_in, 0)
        CHECKS[1] = self.geo.check_item(self.rec_out, 0)
        self.b.run(30, 1)


def main(dialect_name, rounds):
    dialect = __import__("mavstack.dialects." + dialect_name, None, None, ("CRC_LEN",))
    seed = dialect_name == "seed2012"
    b = Bench(services=SERVICES, board=Board, dialect=dialect, version=1 if seed else 2, storage="ram")
    ep = b.ep
    geo = ep.services["geography"]
    geo.on_state_correction = on_state_correction
    ep.services["debug"].handler = on_debug
    servos = ep.services["servos"]
    echoes = ep.services["seed_telemetry"]
    g = b.gcs()
    lat, lon = 473977420, 85455940
    frames = [
        g.heartbeat(),
        g.frame(48, lat, lon, 12345, 1) if seed else g.frame(48, lat, lon, 12345, 1, 0),
        g.frame(54, 47.39, 8.54, 0.0, 47.41, 8.56, 100.0, 1, 1, 0),
        g.frame(251, 0, 1.5, b"speed"),
        g.frame(252, 0, -7, b"count"),
        g.frame(254, 0, 2.5, 3),
        g.frame(250, 0, 1.0, 2.0, 3.0, b"vec"),
        g.frame(249, 0x100, 1, 0, *range(32)),
        g.frame(7, b"a key sent unsigned"),
        g.command(181, 1.0, 1.0),  # DO_SET_RELAY 1 on
        g.command(182, 2.0, 2.0, 0.01),  # DO_REPEAT_RELAY 2, 2 cycles of 10 ms
        g.command(183, 6.0, 1800.0),  # DO_SET_SERVO 6
        g.command(184, 7.0, 1200.0, 2.0, 0.01),  # DO_REPEAT_SERVO 7
        g.command(183, 2.0, 1800.0),  # a motor output: DENIED
        g.command(241, 1.0),  # PREFLIGHT_CALIBRATION gyro: no handler, UNSUPPORTED
        g.command(242, 0.0, 1.0),  # PREFLIGHT_SET_SENSOR_OFFSETS
        g.command(252, 0.0, 2.0),  # OVERRIDE_GOTO hold here
        g.command(252, 1.0),  # ... continue
        g.command(80, 3.0, 0.0, 0.0, 0.0, 47.4, 8.55, 20.0),  # NAV_ROI at a location
        g.command(81, 1.0, 1.0),  # NAV_PATHPLANNING: UNSUPPORTED
        g.command(200, -1.0, 1.0),  # DO_CONTROL_VIDEO: UNSUPPORTED
        g.command(115, 90.0),  # CONDITION_YAW: a mission item
        g.command(95),  # NAV_LAST: a marker
        g.command(512, 49.0),  # REQUEST_MESSAGE GPS_GLOBAL_ORIGIN
        g.command(512, 55.0),  # ... SAFETY_ALLOWED_AREA
        g.command(512, 7.0),  # ... AUTH_KEY over an unsigned link: DENIED
    ]
    if seed:
        frames.append(g.frame(64, *[0.1] * 9))

    r = Rounds(b, frames, geo, echoes, lat, lon)
    round_ = r.round  # a method, not a closure: calling a closure of many cells allocates
    for _ in range(3):  # warm-up: first-use objects, the statustext queue's steady state
        round_()
    acks0 = b.acks
    before = micropython.mem_total()
    for _ in range(rounds):
        round_()
    requested = micropython.mem_total() - before
    n = 0
    micropython.heap_lock()
    try:
        while n < rounds:
            round_()
            n += 1
    finally:
        micropython.heap_unlock()
    ok = requested == 0
    figures = "requested=%d acks=%d origin=%d area=%d state_corrections=%d debug=%d servo6=%d relays=%d roi=%d " \
              "gps_origin_sent=%d area_sent=%d auth_sent=%d unsupported=%d denied=%d item_in=%d item_out=%d" % (
                  requested, b.acks - acks0, geo.origin_set, geo.area_set, COUNTS[0], COUNTS[1],
                  servos.servo(6), servos.relays, ep.services["seed_commands"].roi,
                  b.seen[49], b.seen[55], b.seen[7], b.results[3], b.results[2], CHECKS[0], CHECKS[1])
    print(("OK " if ok else "FAIL ") + figures)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 3)
