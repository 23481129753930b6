"""Routing end to end, in the style of mavlink-router's routing test: the unix vehicle
with three UDP links, a pymavlink peer on each (a ground station, a companion, another
system), PINGs broadcast and targeted; each must reach exactly the right peers, the first
targeted to an unknown system none, and nothing come back to its sender."""
import time

from pymavlink import mavutil

from conftest import free_udp_port

PEERS = {"gcs": (255, 190), "companion": (42, 191), "other": (43, 1)}


def connect(port, sysid, compid, mavlink1=False):
    m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % port, source_system=sysid,
                                   source_component=compid, dialect="common")
    if mavlink1:
        send = m.mav.send
        m.mav.send = lambda msg, force_mavlink1=False: send(msg, force_mavlink1=True)
    return m


def collect(peers, seconds=1.0):
    """{name: [(src sysid, src compid, PING seq, target sys, target comp, MAVLink version)]}
    of the PINGs each peer got that the vehicle did not make."""
    got = {name: [] for name in peers}
    deadline = time.time() + seconds
    while time.time() < deadline:
        for name, m in peers.items():
            msg = m.recv_match(type="PING", blocking=False)
            while msg is not None:
                if msg.get_srcSystem() != 1:
                    v = 1 if msg.get_msgbuf()[0] == 0xFE else 2
                    got[name].append((msg.get_srcSystem(), msg.get_srcComponent(), msg.seq,
                                      msg.target_system, msg.target_component, v))
                msg = m.recv_match(type="PING", blocking=False)
        time.sleep(0.01)
    return got


def test_pings_across_three_links(vehicle):
    ports = [free_udp_port() for _ in range(3)]
    v = vehicle(links=["udpin:127.0.0.1:%d" % p for p in ports])
    peers = {name: connect(port, *PEERS[name]) for name, port in zip(PEERS, ports)}
    # Each peer is heard (the vehicle's udpin links answer those heard), and heard of.
    deadline = time.time() + 20
    seen = set()
    while len(seen) < 3 and time.time() < deadline:
        for name, m in peers.items():
            m.mav.heartbeat_send(6 if name == "gcs" else 18, 8, 0, 0, 0)
            if m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2) is not None:
                seen.add(name)
        v.check_alive()
    assert len(seen) == 3, v.output()
    collect(peers, 0.5)
    gcs, comp, other = peers["gcs"], peers["companion"], peers["other"]

    gcs.mav.ping_send(1, 101, 77, 1)  # an unknown system: dropped
    assert collect(peers) == {"gcs": [], "companion": [], "other": []}

    gcs.mav.ping_send(1, 102, 0, 0)  # broadcast: everyone else
    got = collect(peers)
    assert got["gcs"] == [] and got["companion"] == got["other"] == [(255, 190, 102, 0, 0, 2)], got

    gcs.mav.ping_send(1, 103, 42, 191)  # targeted: the companion alone
    got = collect(peers)
    assert got == {"gcs": [], "companion": [(255, 190, 103, 42, 191, 2)], "other": []}, got

    comp.mav.ping_send(1, 104, 255, 190)  # and back
    got = collect(peers)
    assert got == {"gcs": [(42, 191, 104, 255, 190, 2)], "companion": [], "other": []}, got

    other.mav.ping_send(1, 105, 42, 0)  # a system, any component
    got = collect(peers)
    assert got == {"gcs": [], "companion": [(43, 1, 105, 42, 0, 2)], "other": []}, got

    # Signed by the companion (the vehicle holds no key): passes as it came, signature and all.
    comp.mav.signing.secret_key = bytes(range(32))
    comp.mav.signing.sign_outgoing = True
    comp.mav.signing.link_id = 5
    comp.mav.signing.timestamp = 1
    sent = [bytes(comp.mav.ping_encode(1, 107, 0, 0).pack(comp.mav))]
    comp.mav.signing.sign_outgoing = False
    comp.mav.signing.secret_key = None  # (with a key, pymavlink refuses what is unsigned)
    comp.write(sent[0])
    raw = []
    deadline = time.time() + 1.0
    while time.time() < deadline and not raw:
        msg = gcs.recv_match(type="PING", blocking=True, timeout=0.1)
        if msg is not None and msg.seq == 107:
            raw.append(bytes(msg.get_msgbuf()))
    assert sent and sent[0][2] & 1 and raw == sent, (sent, raw)
    collect(peers, 0.3)

    v1 = connect(ports[2], 43, 1, mavlink1=True)  # the same peer, MAVLink 1
    v1.mav.ping_send(1, 106, 0, 0)
    got = collect(peers)
    assert got["gcs"] == got["companion"] == [(43, 1, 106, 0, 0, 1)], got
    v1.close()
    v.check_alive()


def test_companion_on_a_serial_link_and_a_station_on_udp(vehicle):
    """A companion computer on a pty (`serial:` link, 57600 baud) and a ground station on
    UDP reach each other through the vehicle: HEARTBEATs, a command and its ACK; the
    vehicle leaves the command to the companion."""
    from pty_relay import PtyRelay

    cable = PtyRelay(rate=0.0)
    comp = None
    try:
        port = free_udp_port()
        v = vehicle(links=["udpin:127.0.0.1:%d" % port, "serial:%s:57600" % cable.vehicle_dev])
        gcs = connect(port, 255, 190)
        comp = mavutil.mavlink_connection(cable.gcs_dev, baud=57600, source_system=42, source_component=191,
                                          dialect="common")
        seen = None
        deadline = time.time() + 20
        while seen is None and time.time() < deadline:
            gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
            comp.mav.heartbeat_send(18, 8, 0, 0, 4)
            seen = gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=0.3,
                                  condition="HEARTBEAT.get_srcSystem() == 42")
            v.check_alive()
        assert seen is not None and seen.type == 18, v.output()
        # (the station's HEARTBEAT reached the companion too)
        assert comp.recv_match(type="HEARTBEAT", blocking=True, timeout=5,
                               condition="HEARTBEAT.get_srcSystem() == 255") is not None
        gcs.mav.command_long_send(42, 191, 31000, 0, 1, 0, 0, 0, 0, 0, 0)  # MAV_CMD_USER_1
        cmd = comp.recv_match(type="COMMAND_LONG", blocking=True, timeout=5)
        assert cmd is not None and cmd.command == 31000 and cmd.get_srcSystem() == 255
        comp.mav.command_ack_send(31000, 0, 0, 0, 255, 190)
        deadline = time.time() + 5
        acks = []
        while time.time() < deadline and not any(a.get_srcSystem() == 42 for a in acks):
            a = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)
            if a is not None:
                acks.append(a)
        assert [(a.get_srcSystem(), a.command, a.result) for a in acks] == [(42, 31000, 0)], acks
        v.check_alive()
    finally:
        if comp is not None:
            comp.close()
        cable.close()
