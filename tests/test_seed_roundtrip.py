"""A seed-era ground station (pymavlink generated from ../shared/spec/common-2012.xml,
MAVLink 1) against the unix vehicle running the seed's message set
(`--set dialect=seed2012`): the whole parameter, mission and command round trip."""
import math

from test_seed_misc import SeedStation, seed_station  # noqa: F401  (a fixture)

MAV_PARAM_TYPE_REAL32 = 9


def _params(g):
    got = {}
    g.send(g.mod.MAVLink_param_request_list_message(1, 1))
    while True:
        p = g.recv("PARAM_VALUE", 5.0)
        assert p is not None, "PARAM_VALUE stopped after %d" % len(got)
        got[p.param_id] = p
        if len(got) == p.param_count:
            return got


def test_parameters_mission_and_commands(seed_station):
    # seed: PARAM_REQUEST_LIST, PARAM_VALUE, PARAM_SET, MISSION_COUNT, MISSION_REQUEST
    # seed: MISSION_ITEM, MISSION_ACK, MISSION_REQUEST_LIST, COMMAND_LONG, COMMAND_ACK
    g = seed_station
    mod = g.mod
    params = _params(g)
    assert len(params) >= 100 and "SIM_SPEED" in params
    g.send(mod.MAVLink_param_set_message(1, 1, b"SIM_SPEED", 7.5, MAV_PARAM_TYPE_REAL32))
    p = g.recv("PARAM_VALUE", 5.0, lambda p: p.param_id == "SIM_SPEED")
    assert p is not None and p.param_value == 7.5

    # A mission up, as the seed's protocol has it (MISSION_ITEM, floats), and back.
    items = [(3, 22, 0, 0, 0, 0, 0.0, 0.0, 10.0), (3, 16, 0, 2.0, 0, 0, 47.3990, 8.5460, 20.0),
             (3, 16, 0, 0, 0, 0, 47.4000, 8.5470, 25.0), (3, 21, 0, 0, 0, 0, 47.4000, 8.5470, 0.0)]
    g.send(mod.MAVLink_mission_count_message(1, 1, len(items)))
    done = None
    while done is None:
        r = g.recv("MISSION_REQUEST", 5.0)
        if r is None:
            break
        frame, cmd, cur, p1, p2, p3, x, y, z = items[r.seq]
        g.send(mod.MAVLink_mission_item_message(1, 1, r.seq, frame, cmd, cur, 1, p1, p2, p3, 0.0, x, y, z))
        if r.seq == len(items) - 1:
            done = g.recv("MISSION_ACK", 5.0)
    assert done is not None and done.type == 0  # MAV_MISSION_ACCEPTED
    g.send(mod.MAVLink_mission_request_list_message(1, 1))
    count = g.recv("MISSION_COUNT", 5.0)
    assert count is not None and count.count == len(items)
    for seq, (frame, cmd, _, p1, _, _, x, y, z) in enumerate(items):
        g.send(mod.MAVLink_mission_request_message(1, 1, seq))
        it = g.recv("MISSION_ITEM", 5.0, lambda m, s=seq: m.seq == s)
        assert it is not None, seq
        assert (it.frame, it.command, it.param1) == (frame, cmd, p1)
        assert math.isclose(it.x, x, abs_tol=1e-5) and math.isclose(it.y, y, abs_tol=1e-5)  # (float32) and it.z == z
    g.send(mod.MAVLink_mission_ack_message(1, 1, 0))

    # Commands: arm, a mode, disarm (COMMAND_LONG / COMMAND_ACK), an unknown one.
    g.command(400, 1.0)
    a = g.recv("COMMAND_ACK", 5.0, lambda a: a.command == 400)
    assert a is not None and a.result == 0
    hb = g.recv("HEARTBEAT", 5.0, lambda h: h.base_mode & 128)
    assert hb is not None
    g.send(mod.MAVLink_request_data_stream_message(1, 1, 0, 4, 1))  # as its planners did: ArduPilot's numbers
    g.command(176, 1.0, 5.0)  # DO_SET_MODE: LOITER
    a = g.recv("COMMAND_ACK", 5.0, lambda a: a.command == 176)
    assert a is not None and a.result == 0
    assert g.recv("HEARTBEAT", 5.0, lambda h: h.custom_mode == 5) is not None
    g.command(400, 0.0)
    a = g.recv("COMMAND_ACK", 5.0, lambda a: a.command == 400)
    assert a is not None and a.result == 0
    g.command(31999)
    a = g.recv("COMMAND_ACK", 5.0, lambda a: a.command == 31999)
    assert a is not None and a.result == 3  # MAV_RESULT_UNSUPPORTED
