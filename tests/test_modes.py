"""The vehicle's flight modes as ground stations set and read them: the unix vehicle's
table (boards/unix.py FLIGHT_MODES) over UDP, with pymavlink, MAVProxy and MAVSDK.

ArduPilot's numbers for a ground station that shows ArduPilot's conventions (MAVProxy's
REQUEST_DATA_STREAM), PX4's main/sub mode for one that shows PX4's (MAVSDK's NaN-filled
commands, a sub mode, a PX4-encoded SET_MODE), whatever its system id; a DO_SET_MODE that
could mean two modes from a station that has shown neither is refused. Standard modes for
anyone. A mode the vehicle does not have is refused and leaves the mode as it was. These
run without the simulator (`application=0`): what the vehicle does in each mode is
tests/test_flight*.py's.
"""
import time

from conftest import recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED, MavProxy, ack,
                       ardupilot_station, mavsdk_system, px4_station, run, start, statustext, two_links,
                       vehicle_heartbeat)

MODE_CUSTOM = 1
MODE_HIL = 32
MODE_STABILIZE = 16
MODE_GUIDED = 8
MODE_AUTO = 4
NO_APP = ("--set", "application=0")
# boards/unix.py FLIGHT_MODES: name -> (number, PX4 main, PX4 sub, standard mode)
TABLE = {
    "STABILIZE": (0, 7, 0, 0), "ALT_HOLD": (2, 2, 0, 4), "POSITION": (16, 3, 0, 1), "AUTO": (3, 4, 4, 6),
    "GUIDED": (4, 4, 3, 0), "LOITER": (5, 4, 3, 0), "RTL": (6, 4, 5, 5), "LAND": (9, 4, 6, 7),
    "TAKEOFF": (4, 4, 2, 8), "OFFBOARD": (4, 6, 0, 0),
}


def px4(name):
    _, main, sub, _ = TABLE[name]
    return main << 16 | sub << 24


def _mode(m):
    hb = vehicle_heartbeat(m)
    return hb.base_mode & 0x7F, hb.custom_mode


def _shows(m, custom, timeout=5.0):
    return vehicle_heartbeat(m, lambda h: h.custom_mode == custom, timeout=timeout)


def test_boots_in_stabilize_and_every_numbered_mode_is_set_and_shown(vehicle):
    m = ardupilot_station(start(vehicle, *NO_APP).gcs())
    assert _mode(m) == (MODE_CUSTOM | 64 | MODE_STABILIZE, 0)
    for name in ("ALT_HOLD", "POSITION", "AUTO", "GUIDED", "LOITER", "RTL", "LAND", "STABILIZE"):
        number = TABLE[name][0]
        assert run(m, 176, MODE_CUSTOM, number) == MAV_RESULT_ACCEPTED, name
        assert _shows(m, number) is not None, name
    # The mode sets its own flags: AUTO's, whatever the request's others.
    assert run(m, 176, MODE_CUSTOM | MODE_GUIDED, 3) == MAV_RESULT_ACCEPTED
    assert _shows(m, 3).base_mode & 0x7F == MODE_CUSTOM | MODE_STABILIZE | MODE_AUTO


def test_unknown_custom_mode_refused_and_nothing_changes(vehicle):
    m = ardupilot_station(start(vehicle, *NO_APP).gcs())
    assert run(m, 176, MODE_CUSTOM, 5) == MAV_RESULT_ACCEPTED
    before = _mode(m)
    assert run(m, 176, MODE_CUSTOM, 7) in (MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED)  # ArduCopter's CIRCLE
    assert statustext(m, "no such mode") is not None
    for _ in range(2):
        assert _mode(m) == before
    m.mav.command_int_send(1, 1, 0, 176, 0, 0, MODE_CUSTOM, 99, 0, 0, 0, 0, 0)  # COMMAND_INT too
    assert ack(m, 176).result in (MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED)
    m.mav.set_mode_send(1, MODE_CUSTOM, 99)  # SET_MODE (#11) has no ACK: a STATUSTEXT says it
    assert statustext(m, "no such mode") is not None
    m.mav.set_mode_send(1, MODE_CUSTOM, 5 << 16)  # PX4 main 5 (ACRO): not ours either
    assert statustext(m, "no such mode") is not None
    # Still LOITER, now shown PX4's way: the request showed the station's convention.
    assert _mode(m) == (before[0], px4("LOITER"))


def test_base_flags_alone_pick_the_mode_with_those_flags(vehicle):
    m = start(vehicle, *NO_APP).gcs()
    assert run(m, 176, MODE_GUIDED | MODE_STABILIZE) == MAV_RESULT_ACCEPTED
    assert _shows(m, TABLE["GUIDED"][0]).base_mode & 0x7F == MODE_CUSTOM | MODE_GUIDED | MODE_STABILIZE
    m.mav.set_mode_send(1, MODE_AUTO | 128, 0)  # the armed bit does not arm
    hb = _shows(m, TABLE["AUTO"][0])
    assert hb.base_mode & MODE_AUTO and not hb.base_mode & 128
    m.mav.set_mode_send(1, 64 | MODE_STABILIZE, 0)  # the seed's MAV_MODE_MANUAL
    assert _shows(m, 0) is not None


def test_hil_refused_where_the_board_does_not_allow_it(vehicle):
    m = ardupilot_station(start(vehicle, *NO_APP).gcs())
    before = _mode(m)
    assert run(m, 176, MODE_HIL | MODE_CUSTOM, 5) == MAV_RESULT_DENIED
    assert statustext(m, "HIL not supported") is not None
    assert _mode(m) == before


def test_standard_modes(vehicle):
    m = start(vehicle, *NO_APP).gcs()
    for name in ("AUTO", "RTL", "LAND", "POSITION", "ALT_HOLD", "TAKEOFF"):
        number, _, _, standard = TABLE[name]
        assert run(m, 262, standard) == MAV_RESULT_ACCEPTED, name
        assert _shows(m, number) is not None, name
    assert run(m, 262, 2) == MAV_RESULT_UNSUPPORTED  # ORBIT: not a mode of this vehicle
    assert statustext(m, "no such standard mode") is not None
    assert run(m, 262, 0) == MAV_RESULT_UNSUPPORTED  # NON_STANDARD is no mode to set
    assert _mode(m)[1] == TABLE["TAKEOFF"][0]


def test_px4_convention_learned_from_what_a_station_does_not_its_system_id(vehicle):
    # MAVSDK's own system id says nothing: its REQUEST_MESSAGE with NaN in the parameters
    # it does not use does. A PX4-convention link reads PX4's encoding and sets modes PX4's
    # way (DO_SET_MODE param2 main mode, param3 sub mode); another link keeps ArduPilot's.
    v, port, ardu = two_links(vehicle, *NO_APP)
    ardupilot_station(ardu)
    sdk = v.gcs(port=port, source_system=245, source_component=190)
    assert _shows(sdk, 0) is not None  # not by its id: nothing shown yet, ArduPilot's numbers
    px4_station(sdk)
    assert _shows(sdk, px4("STABILIZE")) is not None
    assert run(sdk, 176, MODE_CUSTOM, 4, 5) == MAV_RESULT_ACCEPTED  # AUTO.RTL
    assert _shows(sdk, px4("RTL")) is not None
    assert _shows(ardu, TABLE["RTL"][0]) is not None
    assert run(sdk, 176, MODE_CUSTOM, 6, 0) == MAV_RESULT_ACCEPTED  # OFFBOARD
    assert _shows(sdk, px4("OFFBOARD")) is not None
    assert _shows(ardu, TABLE["OFFBOARD"][0]) is not None  # GUIDED's number
    assert run(sdk, 176, MODE_CUSTOM, 1, 0) == MAV_RESULT_ACCEPTED  # PX4 MANUAL: stabilized here
    assert _shows(sdk, px4("STABILIZE")) is not None
    assert run(sdk, 176, MODE_CUSTOM, 4, 9) == MAV_RESULT_DENIED  # AUTO.PRECLAND: not ours
    assert run(ardu, 176, MODE_CUSTOM, 6) == MAV_RESULT_ACCEPTED  # ArduPilot's RTL on the other
    assert _shows(sdk, px4("RTL")) is not None
    # A SET_MODE with a PX4-encoded custom mode is understood on any link, and tells it.
    ardu.mav.set_mode_send(1, MODE_CUSTOM, px4("LAND"))
    assert _shows(ardu, px4("LAND")) is not None


def test_a_number_that_could_mean_two_modes_is_refused_until_the_station_shows_its_convention(vehicle):
    """DO_SET_MODE param2 6 with param3 0 is ArduCopter's RTL and PX4's OFFBOARD: from a
    station that has shown neither convention it is refused with a STATUSTEXT saying so;
    one that means the same mode either way (2: ALT_HOLD, PX4's Altitude) or that only
    one convention has (9: LAND) is taken. A sub mode, NaN in the unused parameters (as
    MAVSDK sends), a SET_MODE or REQUEST_DATA_STREAM settle it, whatever the system id."""
    v, port, m = two_links(vehicle, *NO_APP)
    for number, modes in ((6, "ArduPilot RTL or PX4 OFFBOARD"), (3, "ArduPilot AUTO or PX4 POSITION"),
                          (5, "ArduPilot LOITER or PX4 (none)"), (7, "ArduPilot (none) or PX4 STABILIZE")):
        assert run(m, 176, MODE_CUSTOM, number) == MAV_RESULT_DENIED, number
        assert statustext(m, "Mode %d: %s? Refused" % (number, modes)) is not None
    assert _mode(m)[1] == 0  # still STABILIZE, shown by ArduPilot's numbers
    for name in ("ALT_HOLD", "LAND", "GUIDED", "POSITION"):
        assert run(m, 176, MODE_CUSTOM, TABLE[name][0]) == MAV_RESULT_ACCEPTED, name
        assert _shows(m, TABLE[name][0]) is not None, name
    m.mav.set_mode_send(1, MODE_CUSTOM, 6)  # SET_MODE carries PX4's modes encoded: never two
    assert _shows(m, TABLE["RTL"][0]) is not None
    nan = float("nan")
    m.mav.command_long_send(1, 1, 176, 0, MODE_CUSTOM, 4, 3, nan, nan, nan, nan)  # as MAVSDK's hold()
    assert ack(m, 176).result == MAV_RESULT_ACCEPTED
    assert _shows(m, px4("LOITER")) is not None  # ... and the link reads PX4's way from now on
    # MAVSDK's system id on the other link says nothing: refused there until it shows.
    fresh = v.gcs(port=port, source_system=245, source_component=190)
    assert run(fresh, 176, MODE_CUSTOM, 6) == MAV_RESULT_DENIED
    ardupilot_station(fresh)  # REQUEST_DATA_STREAM: ArduPilot's numbers
    assert run(fresh, 176, MODE_CUSTOM, 6) == MAV_RESULT_ACCEPTED
    assert _shows(fresh, TABLE["RTL"][0]) is not None
    assert _shows(m, px4("RTL")) is not None


def test_mavproxy_sets_modes_by_name(vehicle, tmp_path):
    # MAVProxy names a generic multicopter's modes as ArduCopter's.
    v, port, check = two_links(vehicle, *NO_APP)
    mp = MavProxy(port, tmp_path, "mode,cmdlong")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        for name, number in (("GUIDED", 4), ("LOITER", 5), ("ALT_HOLD", 2), ("POSHOLD", 16), ("RTL", 6),
                             ("LAND", 9), ("AUTO", 3), ("STABILIZE", 0)):
            mp.say("mode " + name)
            assert _shows(check, number, timeout=10) is not None, name
        mp.say("mode CIRCLE")  # ArduCopter's, not this vehicle's: refused, the mode stays
        assert recv(check, "STATUSTEXT", 5, lambda s: "no such mode" in s.text) is not None
        assert vehicle_heartbeat(check).custom_mode == 0
    finally:
        mp.close()


def test_mavsdk_reports_each_mode(vehicle):
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    expected = {
        "STABILIZE": FlightMode.STABILIZED, "ALT_HOLD": FlightMode.ALTCTL, "POSITION": FlightMode.POSCTL,
        "AUTO": FlightMode.MISSION, "GUIDED": FlightMode.HOLD, "LOITER": FlightMode.HOLD,
        "RTL": FlightMode.RETURN_TO_LAUNCH, "LAND": FlightMode.LAND, "TAKEOFF": FlightMode.TAKEOFF,
        "OFFBOARD": FlightMode.OFFBOARD,
    }
    v, port, m = two_links(vehicle, *NO_APP)
    ardupilot_station(m)
    with mavsdk_system(port) as system:
        tel = Telemetry(system)
        for name, mode in expected.items():
            # Set from the other link, by standard mode where the number is GUIDED's.
            if name == "TAKEOFF":
                assert run(m, 262, 8) == MAV_RESULT_ACCEPTED
            elif name == "OFFBOARD":
                m.mav.set_mode_send(1, MODE_CUSTOM, px4("OFFBOARD"))
            else:
                assert run(m, 176, MODE_CUSTOM, TABLE[name][0]) == MAV_RESULT_ACCEPTED, name
            deadline = time.time() + 10
            while tel.flight_mode() != mode and time.time() < deadline:
                time.sleep(0.2)
            assert tel.flight_mode() == mode, (name, tel.flight_mode())


def test_available_and_current_mode_where_the_dialect_has_them(vehicle):
    # The common dialect has neither AVAILABLE_MODES nor CURRENT_MODE: not produced.
    m = start(vehicle, *NO_APP).gcs()
    assert run(m, 512, 435) == MAV_RESULT_DENIED
    assert run(m, 512, 436) == MAV_RESULT_DENIED


def test_available_and_current_mode_in_the_development_dialect(vehicle):
    v = start(vehicle, "--set", "dialect=development", *NO_APP)
    m = v.gcs(dialect="development")
    assert run(m, 512, 435) == MAV_RESULT_ACCEPTED  # param2 0: every mode
    modes = {}
    deadline = time.time() + 5
    while len(modes) < len(TABLE) and time.time() < deadline:
        a = recv(m, "AVAILABLE_MODES", 1)
        if a is not None:
            modes[a.mode_index] = a
    assert sorted(modes) == list(range(1, len(TABLE) + 1))
    by_name = {}
    for a in modes.values():
        assert a.number_modes == len(TABLE)
        name = a.mode_name or {s: n for n, (_, _, _, s) in TABLE.items() if s}[a.standard_mode]
        by_name[name] = a
    assert set(by_name) == set(TABLE)
    for name, (number, _, _, standard) in TABLE.items():
        a = by_name[name]
        assert (a.custom_mode, a.standard_mode) == (number, standard), name
        # TAKEOFF and OFFBOARD share GUIDED's number: not selectable by it.
        assert a.properties == (2 if name in ("TAKEOFF", "OFFBOARD") else 0), name
    # One by index (param2).
    assert run(m, 512, 435, 7) == MAV_RESULT_ACCEPTED
    a = recv(m, "AVAILABLE_MODES", 3)
    assert a is not None and a.mode_index == 7
    assert run(m, 512, 435, 99) == MAV_RESULT_DENIED
    # CURRENT_MODE on request and on a change, with the mode asked for.
    assert run(m, 512, 436) == MAV_RESULT_ACCEPTED
    c = recv(m, "CURRENT_MODE", 3)
    assert c is not None and c.custom_mode == 0 and c.standard_mode == 0
    assert run(m, 262, 5) == MAV_RESULT_ACCEPTED  # standard SAFE_RECOVERY: RTL
    c = recv(m, "CURRENT_MODE", 3, lambda c: c.custom_mode == 6)
    assert c is not None and c.standard_mode == 5 and c.intended_custom_mode == 6
