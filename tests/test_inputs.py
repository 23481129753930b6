"""Pilot inputs (services/inputs/) over UDP with pymavlink, and the simulated pilot
(firmware/sim/inputs.py) on a fake simulator.

The service: setpoints answered with their target messages (the fields as sent, the
type_mask and frame kept), in today's message set and the seed's; messages for another
vehicle and, under operator control, from a station not in control, not taken; HIL
accepted where the board allows it, then HIL_CONTROLS streamed from the pilot's input.
These run on a heap-locked vehicle without the simulator (`application=0`): every path
they take allocates nothing.
"""
import math
import os
import struct
import sys
import time

import pytest

from conftest import FIRMWARE, recv
from gcs_tools import MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, listen, run, start, statustext

LOCKED = ("--set", "application=0", "--set", "heap_lock=1")
POS_ONLY = 0b100111111000  # x y z and yaw (yaw rate ignored): MAVSDK set_position_ned
VEL_ONLY = 0b010111000111  # vx vy vz and yaw rate (yaw ignored)


def _target_local(m, x, y, z, mask=POS_ONLY, yaw=0.5, ts=None, frame=1):
    m.mav.set_position_target_local_ned_send(0, m.target_system if ts is None else ts, 1, frame, mask,
                                             x, y, z, 0.5, -0.25, 0.125, 0, 0, 0, yaw, 0.0)


def _alive(v):
    v.check_alive()
    assert "MemoryError" not in v.output()


def test_setpoints_answered_with_their_targets(vehicle):
    v = start(vehicle, *LOCKED)
    m = v.gcs()
    _target_local(m, 12.5, -3.25, -10.0)
    t = listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x == 12.5)
    assert t is not None
    assert (t.x, t.y, t.z, t.vx, t.vy, t.vz, t.yaw) == (12.5, -3.25, -10.0, 0.5, -0.25, 0.125, 0.5)
    assert t.type_mask == POS_ONLY and t.coordinate_frame == 1
    m.mav.set_position_target_global_int_send(0, 1, 1, 6, VEL_ONLY, 473977420, 85455940, 30.0,
                                              1.5, 2.5, -0.5, 0, 0, 0, 0, 0.25)
    g = listen(m, "POSITION_TARGET_GLOBAL_INT", 5, lambda t: t.lat_int == 473977420)
    assert g is not None and g.lon_int == 85455940 and g.alt == 30.0
    assert (g.vx, g.vy, g.vz, g.yaw_rate, g.type_mask, g.coordinate_frame) == (1.5, 2.5, -0.5, 0.25, VEL_ONLY, 6)
    m.mav.set_attitude_target_send(0, 1, 1, 0b111, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 0.625)
    a = listen(m, "ATTITUDE_TARGET", 5, lambda t: t.thrust == 0.625)
    assert a is not None and list(a.q) == [1.0, 0.0, 0.0, 0.0] and a.type_mask == 0b111
    _alive(v)


def test_only_what_is_addressed_to_us(vehicle):
    v = start(vehicle, *LOCKED)
    m = v.gcs()
    _target_local(m, 1.0, 2.0, -3.0)
    assert listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x == 1.0) is not None
    _target_local(m, 99.0, 2.0, -3.0, ts=42)  # another vehicle's
    _target_local(m, 7.0, 2.0, -3.0, ts=0)  # broadcast: ours too
    t = listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x != 1.0)
    assert t is not None and t.x == 7.0
    _alive(v)


def test_setpoints_outside_the_safety_area_are_dropped(vehicle):
    # seed: SAFETY_SET_ALLOWED_AREA
    # A global area around the field (MSL 400-600 m): a global setpoint outside it is
    # dropped and told once; one inside is taken. A local area gates local setpoints.
    v = start(vehicle, *LOCKED)
    m = v.gcs()
    m.mav.safety_set_allowed_area_send(1, 1, 6, 47.39, 8.54, 400.0, 47.41, 8.56, 600.0)
    assert listen(m, "SAFETY_ALLOWED_AREA", 5, lambda a: a.p2z == 600.0) is not None
    m.mav.set_position_target_global_int_send(0, 1, 1, 6, POS_ONLY, 474977420, 85455940, 500.0,
                                              0, 0, 0, 0, 0, 0, 0, 0)  # 11 km north
    assert statustext(m, "Setpoint outside the allowed area") is not None
    m.mav.set_position_target_global_int_send(0, 1, 1, 6, POS_ONLY, 473977420, 85455940, 700.0,
                                              0, 0, 0, 0, 0, 0, 0, 0)  # too high
    m.mav.set_position_target_global_int_send(0, 1, 1, 6, POS_ONLY, 473977420, 85455940, 500.0,
                                              0, 0, 0, 0, 0, 0, 0, 0)  # inside
    g = listen(m, "POSITION_TARGET_GLOBAL_INT", 5, lambda t: t.lat_int != 0)
    assert g is not None and (g.lat_int, g.alt) == (473977420, 500.0)  # the only one taken
    # A local area (MAV_FRAME_LOCAL_NED, 20 m around the origin): local setpoints too.
    m.mav.safety_set_allowed_area_send(1, 1, 1, -20.0, -20.0, -30.0, 20.0, 20.0, 0.0)
    assert listen(m, "SAFETY_ALLOWED_AREA", 5, lambda a: a.frame == 1) is not None
    _target_local(m, 25.0, 0.0, -5.0)
    assert statustext(m, "Setpoint outside the allowed area") is not None
    _target_local(m, 5.0, 0.0, -5.0)
    t = listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x != 0)
    assert t is not None and t.x == 5.0
    _target_local(m, 99.0, 0.0, -5.0, frame=8)  # BODY_NED: relative to the vehicle, not checked
    assert listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x == 99.0) is not None
    _alive(v)


def test_operator_control_keeps_others_out(vehicle):
    v = start(vehicle, *LOCKED, "--set", "operator_passkey=secret")
    m = v.gcs()
    other = v.gcs(source_system=200, source_component=1)
    m.mav.change_operator_control_send(1, 0, 0, b"secret")
    assert recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5, lambda a: a.ack == 0) is not None
    _target_local(other, 50.0, 0.0, -5.0)  # from the station not in control: not taken
    _target_local(m, 5.0, 0.0, -5.0)
    t = listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.x != 0.0)
    assert t is not None and t.x == 5.0
    deadline = time.time() + 1.5
    while time.time() < deadline:
        t = recv(m, "POSITION_TARGET_LOCAL_NED", 0.3)
        assert t is None or t.x == 5.0
    _alive(v)


def test_hil_accepted_where_the_board_allows_it(vehicle):
    v = start(vehicle, *LOCKED, "--set", "mode_flags=125")
    m = v.gcs()
    assert run(m, 176, 32 | 1, 0) == MAV_RESULT_ACCEPTED  # DO_SET_MODE HIL_ENABLED, STABILIZE
    hb = listen(m, "HEARTBEAT", 5, lambda h: h.get_srcSystem() == 1 and h.base_mode & 32)
    assert hb is not None
    deadline = time.time() + 5
    while time.time() < deadline:
        m.mav.manual_control_send(1, 500, -250, 750, 1000, 0)
        h = recv(m, "HIL_CONTROLS", 0.2, lambda h: h.throttle == 0.75)
        if h is not None:
            break
    assert h is not None and (h.roll_ailerons, h.pitch_elevator, h.yaw_rudder) == (-0.25, 0.5, 1.0)
    assert h.mode & 32
    assert run(m, 176, 1, 0) == MAV_RESULT_ACCEPTED  # out of HIL
    assert listen(m, "HEARTBEAT", 5, lambda h: h.get_srcSystem() == 1 and not h.base_mode & 32) is not None
    _alive(v)


def test_hil_refused_on_the_default_unix_board(vehicle):
    m = start(vehicle, *LOCKED).gcs()
    assert run(m, 176, 32 | 1, 0) == MAV_RESULT_DENIED
    assert statustext(m, "HIL not supported") is not None


# --- the simulated pilot, in-process -------------------------------------------------

def _bench(**kw):
    path = os.path.join(os.path.dirname(__file__), "mpy")
    for p in (path, FIRMWARE):
        if p not in sys.path:
            sys.path.insert(0, p)
    from harness import Bench

    return Bench(**kw)


@pytest.fixture
def bench():
    return _bench(services=("status", "commands", "inputs"))


def test_seed_setpoints_answered():
    # The seed's message set (--set dialect=seed2012): its setpoints are inputs, and
    # SET_LOCAL_POSITION_SETPOINT / SET_GLOBAL_POSITION_SETPOINT_INT are answered with
    # LOCAL_POSITION_SETPOINT / GLOBAL_POSITION_SETPOINT_INT as sent.
    from mavstack.dialects import seed2012

    b = _bench(services=("status", "commands", "inputs", "streams"), dialect=seed2012)
    inputs = b.ep.services["inputs"]
    assert inputs.position_local is None and inputs.seed_local is not None
    g = b.gcs()
    got = {}
    b.watch = lambda msgid, p: got.__setitem__(msgid, bytes(p))
    b.send(g.frame(50, 4.0, 5.0, -6.0, 0.25, 1, 1, 1))
    b.send(g.frame(53, 473977420, 85455940, 30000, 9000, 3))
    b.send(g.frame(56, 0.1, 0.2, 0.3, 0.5, 1, 1))
    b.send(g.frame(148, 1, 2, 3, 4, 5, 6, 7, 8, 1))
    b.run(5)
    assert inputs.seed_local.milli(0) == 4000 and inputs.seed_local.milli(8) == -6000
    assert inputs.seed_global.i32(0) == 473977420 and inputs.seed_rpyt.milli(12) == 500
    assert inputs.seed_8dof.milli(28) == 8000
    link = b.ep.links[0]
    assert b.ep.producers[51](link) and b.ep.producers[52](link)
    b.run(5)
    assert struct.unpack("<ffffB", got[51][:17]) == (4.0, 5.0, -6.0, 0.25, 1)
    assert struct.unpack("<iiihB", got[52][:15]) == (473977420, 85455940, 30000, 9000, 3)
    b.send(g.frame(50, 9.0, 5.0, -6.0, 0.25, 2, 1, 1))  # another vehicle's
    b.run(5)
    assert inputs.seed_local.milli(0) == 4000 and inputs.seed_local.count == 1


class FakeSim:
    def __init__(self, ep):
        import sim as simulator

        self.ep = ep
        self.lat, self.lon, self.alt = simulator.HOME_LAT, simulator.HOME_LON, simulator.HOME_ALT
        self.heading = 0.0
        self.reasons = []

    def failsafe(self, reason):
        self.reasons.append(reason)


def test_pilot_manual_control_and_rc_override(bench):
    from sim.inputs import PilotInputs

    sim = FakeSim(bench.ep)
    pilot = PilotInputs(sim)
    g = bench.gcs()
    assert pilot.demand("POSITION", 0.05) is None  # nothing yet: hold
    bench.send(g.frame(69, 1000, 0, 1000, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0))  # full forward, full up
    bench.run(5)
    kind, vn, ve, vd, yr = pilot.demand("POSITION", 0.05)
    assert kind == "vel" and vn == pytest.approx(5.0) and abs(ve) < 1e-9 and vd == pytest.approx(-2.5) and yr == 0
    sim.heading = math.pi / 2  # facing east: forward is east
    _, vn, ve, _, _ = pilot.demand("ALT_HOLD", 0.05)
    assert abs(vn) < 1e-6 and ve == pytest.approx(5.0)
    assert pilot.demand("AUTO", 0.05) is None  # not a pilot's mode
    pilot.demand("POSITION", 0.05)
    bench.run(1100)  # the stream stops: lost, failsafe in a manual mode
    assert sim.reasons == ["Manual control lost"]
    assert pilot.demand("POSITION", 0.05) is None
    # RC override: channel 3 at 1600 climbs at a fifth of the climb rate; others not overridden
    sim.heading = 0.0
    bench.send(g.frame(70, 0, 0, 1600, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0))
    bench.run(5)
    kind, vn, ve, vd, yr = pilot.demand("STABILIZE", 0.05)
    assert kind == "vel" and vd == pytest.approx(-0.5) and vn == 0 and ve == 0


def test_pilot_offboard_setpoints(bench):
    import sim as simulator
    from sim.inputs import PilotInputs

    sim = FakeSim(bench.ep)
    pilot = PilotInputs(sim)
    g = bench.gcs()
    assert pilot.mode_check("OFFBOARD") == "no offboard setpoint"
    bench.send(g.frame(84, 0, 10.0, 5.0, -20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, POS_ONLY, 1, 1, 1))
    bench.run(5)
    assert pilot.mode_check("OFFBOARD") is None
    kind, lat, lon, alt, yaw = pilot.demand("OFFBOARD", 0.05)
    assert kind == "pos" and yaw == 1.0 and alt == pytest.approx(simulator.HOME_ALT + 20.0)
    assert (lat - simulator.HOME_LAT) * math.radians(1) * 6378137.0 == pytest.approx(10.0, rel=1e-3)
    assert (lon - simulator.HOME_LON) > 0
    bench.send(g.frame(84, 0, 0.0, 0.0, 0.0, 1.0, -2.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.3, VEL_ONLY, 1, 1, 1))
    bench.run(5)
    kind, vn, ve, vd, yr = pilot.demand("OFFBOARD", 0.05)
    assert kind == "vel" and (vn, ve, vd) == (1.0, -2.0, 0.5) and yr == pytest.approx(0.3)
    bench.run(1100)
    assert sim.reasons == ["Offboard setpoints lost"]


def test_rc_override_channels_as_mavlink_defines_them(bench):
    rc = bench.ep.services["inputs"].rc
    g = bench.gcs()
    rest = (0,) * 8  # chan11..18: 0 leaves them
    bench.send(g.frame(70, 1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1, 1, 1900, 2000, *rest))
    bench.run(5)
    assert [rc.channel(n) for n in range(1, 13)] == [1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000, 0, 0]
    # UINT16_MAX leaves channels 1-8 as they are, 0 releases them; for 9-18, 0 and
    # UINT16_MAX leave them and UINT16_MAX - 1 releases.
    bench.send(g.frame(70, 65535, 0, 1350, 65535, 65535, 65535, 65535, 65535, 1, 1, 0, 65534, *rest))
    bench.run(5)
    assert [rc.channel(n) for n in (1, 2, 3, 9, 10)] == [1100, 0, 1350, 1900, 0]
    assert not rc.overridden(2) and rc.overridden(1)
    assert rc.channel(0) == 0 and rc.channel(19) == 0
    # Not set again for RC_OVERRIDE_TIMEOUT_MS (3000 here): back to the radio.
    bench.run(2000)
    bench.send(g.frame(70, 65535, 65535, 1360, 65535, 65535, 65535, 65535, 65535, 1, 1, 0, 0, *rest))
    bench.run(1100)
    assert rc.channel(1) == 0 and rc.channel(3) == 1360 and rc.channel(9) == 0
    # Another vehicle's override changes nothing.
    bench.send(g.frame(70, 1999, 1999, 1999, 1999, 0, 0, 0, 0, 7, 1, 0, 0, *rest))
    bench.run(5)
    assert rc.channel(1) == 0 and rc.channel(3) == 1360


def test_manual_control_fields_sender_age_and_callback(bench):
    inputs = bench.ep.services["inputs"]
    m = inputs.manual
    arrived = []
    assert inputs.on(inputs_module().MANUAL, arrived.append)
    assert m.age_ms() == 0x3FFFFFFF and not m.fresh()
    bench.send(bench.gcs(42, 7).frame(69, -1000, 1000, 250, -500, 0x8001, 1, 0x4002, 3, 100, -100,
                                      1, 2, 3, 4, 5, -6))
    bench.run(10)
    assert arrived == [m] and (m.sysid, m.compid, m.link) == (42, 7, 0)
    assert (m.x(), m.y(), m.z(), m.r(), m.buttons()) == (-1000, 1000, 250, -500, 0x8001)
    assert (m.buttons2(), m.extensions(), m.s(), m.t()) == (0x4002, 3, 100, -100)
    assert [m.aux(n) for n in range(1, 7)] == [1, 2, 3, 4, 5, -6]
    assert 0 <= m.age_ms() <= 10 and m.fresh()


def inputs_module():
    from mavstack.services import inputs

    return inputs


def test_milli_reads_floats_as_integers():
    from mavstack.services.inputs.echo import put_f32_milli
    from mavstack.services.inputs.record import milli

    for f in (0.0, -0.0, 1.0, -1.0, 0.0005, -0.0015, 3.14159, 1048.5, -123456.789, 1e-9):
        b = struct.pack("<f", f)
        assert milli(b, 0) == round(struct.unpack("<f", b)[0] * 1000), f
    assert milli(struct.pack("<f", float("nan")), 0) == 0
    assert milli(struct.pack("<f", float("inf")), 0) == 0
    assert milli(struct.pack("<f", 5e6), 0) == 2 ** 30 - 1 and milli(struct.pack("<f", -5e6), 0) == 1 - 2 ** 30
    b = bytearray(4)
    for n in (0, 1, -1, 250, -500, 1000, 32767, -1048575):
        put_f32_milli(b, 0, n)
        assert struct.unpack("<f", b)[0] == struct.unpack("<f", struct.pack("<f", n / 1000))[0], n
