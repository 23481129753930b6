"""Pilot inputs in steady state under micropython.heap_lock().

    inputs_steady.py [ROUNDS] [DIALECT] [MODE]
DIALECT: common (default) or seed2012. MODE "operator": a passkey is set and the
station in control took it; a second station's inputs are refused on the counted path.
MODE "area": a safety area (services/geography.py) that position setpoints are checked
against.
Every simulated ms one input frame arrives, in turn: MANUAL_CONTROL, RC_CHANNELS_OVERRIDE
(ignore, release and set values), MANUAL_SETPOINT, SET_POSITION_TARGET_LOCAL_NED and
_GLOBAL_INT, SET_ATTITUDE_TARGET, HIL_STATE, HIL_RC_INPUTS_RAW, HIL_SENSOR, the vision,
Vicon and optical-flow estimates (in the seed's set its setpoints instead), one for
another vehicle. An arrival callback reads every accessor; every 500 rounds the stream
pauses for longer than INPUT_TIMEOUT_MS so on_input_lost fires; the vehicle is in HIL,
so HIL_CONTROLS is written and streamed with the setpoint echoes.
After a warm-up the rounds run twice: unlocked, counted with micropython.mem_total(),
then under heap_lock(). Prints `OK rounds=N delivered=N lost=N echoes=N hil=N
refused=N requested=0` (the locked run's figures), or FAIL and the same.
"""
import sys

import micropython

from harness import Bench


class Board:
    NAME = "bench"
    MAV_TYPE = 2
    MAV_AUTOPILOT = 0
    GCS_TIMEOUT_MS = 5000
    OPERATOR_PASSKEY = None
    PARAMS = ()
    MODE_FLAGS = 64 | 32 | 16 | 8 | 4 | 1
    INPUT_TIMEOUT_MS = 200
    RC_OVERRIDE_TIMEOUT_MS = 300
    DEFAULT_STREAMS = ((83, 50), (85, 50), (87, 50), (91, 50))  # the seed's set: 51, 52, 91


def frames_common(g, other):
    return [
        g.frame(69, 100, -200, 700, 5, 3, 1, 1, 1, 10, 20, 1, 2, 3, 4, 5, 6),
        g.frame(70, 1500, 65535, 1600, 0, 65535, 65535, 65535, 1900, 1, 1,
                65534, 0, 65535, 1200, 0, 0, 0, 0, 0, 0),
        g.frame(81, 0, 0.1, 0.2, 0.3, 0.5, 1, 0),
        g.frame(84, 0, 10.0, 5.0, -20.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0x9F8, 1, 1, 1),
        g.frame(86, 0, 473977420, 85455940, 30.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0x9F8, 1, 1, 6),
        g.frame(82, 0, 1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3, 0.6, 1, 1, 7),
        g.frame(90, 0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 473977420, 85455940, 488000, 1, 2, 3, 4, 5, 6),
        g.frame(92, 0, 1500, 1500, 1000, 1500, 1000, 1000, 1000, 1000, 0, 0, 0, 0, 200),
        g.frame(107, 0, 0.0, 0.0, -9.8, 0.0, 0.0, 0.0, 0.2, 0.0, 0.4, 1013.0, 0.0, 488.0, 15.0, 0x1FFF, 0),
        g.frame(101, 0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, *((0.0,) * 21 + (0,))),
        g.frame(102, 0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, *((0.0,) * 21 + (0,))),
        g.frame(103, 0, 1.0, 2.0, 3.0, *((0.0,) * 9 + (0,))),
        g.frame(104, 0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, *((0.0,) * 21)),
        g.frame(100, 0, 0.1, 0.2, 1.5, 3, 4, 0, 200, 0.0, 0.0),
        g.frame(69, 900, 900, 900, 900, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0),  # another vehicle's
    ] + ([] if other is None else [  # a station not in control
        other.frame(84, 0, 99.0, 5.0, -20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0x9F8, 1, 1, 1),
        other.frame(69, 900, 900, 900, 900, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0),
    ])


def frames_seed(g, other):
    return [
        g.frame(69, 100, -200, 700, 5, 3, 1),
        g.frame(70, 1500, 65535, 1600, 0, 65535, 65535, 65535, 1900, 1, 1),
        g.frame(81, 0, 0.1, 0.2, 0.3, 0.5, 1, 0),
        g.frame(50, 4.0, 5.0, -6.0, 0.25, 1, 1, 1),
        g.frame(53, 473977420, 85455940, 30000, 9000, 3),
        g.frame(56, 0.1, 0.2, 0.3, 0.5, 1, 1),
        g.frame(57, 0.1, 0.2, 0.3, 0.5, 1, 1),
        g.frame(60, 1100, 1200, 1300, 1400, 1),
        g.frame(61, *((1, 2, 3, 4) * 4 + (1, 1))),
        g.frame(148, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 1),
        g.frame(149, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 1),
        g.frame(90, 0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 473977420, 85455940, 488000, 1, 2, 3, 4, 5, 6),
        g.frame(100, 0, 0.1, 0.2, 1.5, 3, 4, 0, 200),
        g.frame(50, 9.0, 5.0, -6.0, 0.25, 2, 1, 1),  # another vehicle's
    ] + ([] if other is None else [other.frame(50, 99.0, 5.0, -6.0, 0.25, 1, 1, 1)])


class Steady:
    """The bench, its frames and the figures (one argument for steady(): few locals)."""

    def __init__(self, b, frames):
        self.b = b
        self.frames = frames
        self.hb = b.gcs().heartbeat()
        self.inputs = b.ep.services["inputs"]
        self.k = 0
        self.delivered = 0
        self.lost = 0
        self.sum = 0  # what the accessors read, so that nothing is optimised away
        self.echoes = 0
        self.hil = 0


def on_arrival(s):
    def arrived(r):
        s.delivered += 1
        s.sum += r.age_ms() + r.sysid + r.u8(0) + r.i16(0) + r.milli(4)
    return arrived


def read_all(s):
    # A few reads a function: each frame stays within what MicroPython keeps off the heap.
    read_manual(s, s.inputs.manual)
    read_rc(s, s.inputs.rc)
    if s.inputs.position_local is not None:
        read_target(s, s.inputs.position_local)
        read_target(s, s.inputs.position_global)
        read_attitude(s, s.inputs.attitude)
    s.sum &= 0xFFFF


def read_manual(s, m):
    s.sum += m.x() + m.y() + m.z() + m.r()
    s.sum += m.buttons() + m.s() + m.t() + m.aux(6)
    s.sum += m.fresh() + m.age_ms()


def read_rc(s, rc):
    s.sum += rc.channel(1) + rc.channel(3) + rc.channel(8)
    s.sum += rc.channel(9) + rc.channel(12) + rc.overridden(2)


def read_target(s, p):
    s.sum += p.x_milli() + p.vz_milli() + p.yaw_milli()
    s.sum += p.type_mask() + p.uses_position() + p.uses_velocity()
    s.sum += p.lat_hi() + p.lat_lo() + p.lon_hi() + p.lon_lo()  # halves: any value, no heap int


def read_attitude(s, a):
    s.sum += a.q_milli(0) + a.thrust_milli() + a.uses_attitude() + a.rate_milli(2)


def lost(s):
    def on_lost(kind):
        s.lost += 1
    return on_lost


def steady(s, rounds):
    i = 0
    while i < rounds:
        if i % 1000 == 0:
            s.b.send(s.hb)
        if i % 500 < 260:  # then 240 ms of silence: past INPUT_TIMEOUT_MS
            s.b.send(s.frames[s.k])
            s.k += 1
            if s.k == len(s.frames):
                s.k = 0
        if i % 10 == 0:
            read_all(s)
        s.b.run(1)
        i += 1


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5000
    dialect_name = sys.argv[2] if len(sys.argv) > 2 else "common"
    mode = sys.argv[3] if len(sys.argv) > 3 else ""
    dialect = __import__("mavstack.dialects." + dialect_name, None, None, ("CRC_LEN",))
    board = Board
    if mode == "operator":
        board.OPERATOR_PASSKEY = "secret"
    if dialect_name == "seed2012":
        board.DEFAULT_STREAMS = ((51, 50), (52, 50), (91, 50))
    services = ("status", "commands", "inputs", "streams") + (("geography",) if mode == "area" else ())
    b = Bench(services=services, board=board, dialect=dialect, storage="ram" if mode == "area" else None)
    g = b.gcs()
    if mode == "area":  # a safety area around the global target: every one is checked, and taken
        b.send(g.frame(54, 47.39, 8.54, 0.0, 47.41, 8.56, 100.0, 1, 1, 6))
        b.run(5)
    other = b.gcs(200, 1) if mode == "operator" else None
    st = b.ep.services["status"]
    if mode == "operator":
        b.send(g.frame(5, 1, 0, 0, b"secret"))  # CHANGE_OPERATOR_CONTROL: take control
        b.run(5)
    st.set_mode(32 | 16 | 1, 0)  # HIL on: HIL_CONTROLS from now on
    frames = frames_seed(g, other) if dialect_name == "seed2012" else frames_common(g, other)
    s = Steady(b, frames)
    inp = s.inputs
    for r in inp.records:
        inp.on(r.kind, on_arrival(s))
    inp.on_input_lost = lost(s)
    steady(s, 2000)  # warm up: first-time paths may allocate
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    d0, l0 = s.delivered, s.lost
    e0 = b.seen.get(85, 0) + b.seen.get(87, 0) + b.seen.get(83, 0) + b.seen.get(51, 0) + b.seen.get(52, 0)
    h0 = b.seen.get(91, 0)
    m0 = inp.manual.count
    micropython.heap_lock()
    try:
        steady(s, rounds)
    finally:
        micropython.heap_unlock()
    echoes = b.seen.get(85, 0) + b.seen.get(87, 0) + b.seen.get(83, 0) + b.seen.get(51, 0) + b.seen.get(52, 0) - e0
    # the other station's frames under operator control, and the other vehicle's, are refused:
    # the records hold the controlling station's values
    refused = 1 if (inp.manual.x() == 100 and (inp.position_local is None or inp.position_local.x_milli() == 10000)
                    and (inp.seed_local is None or inp.seed_local.milli(0) == 4000)) else 0
    geo = b.ep.services.get("geography")
    if geo is not None and not (geo.area_set and geo.refused == 0):
        refused = 0  # MODE area: the area must be in place, and the (inside) setpoints taken
    ok = requested == 0 and st.hil and refused
    print("%s rounds=%d delivered=%d lost=%d echoes=%d hil=%d refused=%d manual=%d requested=%d"
          % ("OK" if ok else "FAIL", rounds, s.delivered - d0, s.lost - l0, echoes, b.seen.get(91, 0) - h0,
             refused, inp.manual.count - m0, requested))


main()
