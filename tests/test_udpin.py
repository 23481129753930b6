"""udpin links serve several ground stations and cannot be taken over: an address
becomes a peer only with a CRC-valid frame, junk from elsewhere changes nothing, and a
second real ground station from another address is served beside the first. The unix
vehicle on MicroPython with pymavlink ground stations, and the transport itself on
CPython, all over real UDP sockets."""
import socket
import time

from conftest import free_udp_port, recv
from gcs_tools import UdpSender


class Junk(UdpSender):
    """Non-MAVLink datagrams from an address of its own, every 50 ms, until stopped: a
    single byte, a lone MAVLink 2 start marker, and a header that promises a long frame."""

    KINDS = (b"\x00", b"\xfd", b"\xfd\xff\x00\x00\x00\x07\x07\x00\x00\x00", bytes(range(40)))

    def _run(self):
        while not self._stop.is_set():
            self._sock.sendto(self.KINDS[self.sent % len(self.KINDS)], ("127.0.0.1", self.port))
            self.sent += 1
            self._stop.wait(0.05)


def heartbeats(m, seconds):
    """HEARTBEATs from the vehicle received in the next `seconds`."""
    n = 0
    deadline = time.time() + seconds
    while time.time() < deadline:
        msg = m.recv_match(type="HEARTBEAT", blocking=True, timeout=max(0.01, deadline - time.time()))
        if msg is not None and msg.get_srcSystem() == 1:
            n += 1
    return n


def test_junk_from_another_address_does_not_take_the_link(vehicle):
    v = vehicle()
    gcs = v.gcs()
    with Junk(v.port) as junk:
        time.sleep(0.3)  # junk is already flowing when the count starts
        got = heartbeats(gcs, 5.3)
        v.check_alive()
    assert junk.sent >= 100
    assert got >= 5, got  # 5 of 5: the ground station was never cut off
    gcs.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
    assert recv(gcs, "PARAM_VALUE", timeout=3) is not None  # and it still talks


def test_second_ground_station_from_another_address_is_served_too(vehicle):
    v = vehicle()
    first = v.gcs(source_system=255)
    with Junk(v.port):
        second = v.gcs(source_system=254)  # its own socket: another address
        second.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
        value = recv(second, "PARAM_VALUE", timeout=3)
        assert value is not None and value.param_id == "WP_SPEED"
        second.mav.command_long_send(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0)  # REQUEST_MESSAGE
        ack = recv(second, "COMMAND_ACK", timeout=3, cond=lambda m: m.command == 512)
        assert ack is not None and ack.result == 0
        # Both hear the vehicle, every second, while both are there.
        assert heartbeats(first, 3.2) >= 3
        assert heartbeats(second, 2.2) >= 2
        first.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
        assert recv(first, "PARAM_VALUE", timeout=3) is not None
    v.check_alive()


def test_one_shot_tools_back_to_back_are_each_answered(vehicle):
    # Each run of a tool such as mavctl is a new address that is gone a moment later:
    # more of them than the link has peer slots, within a few seconds, all answered (a
    # peer whose port is closed frees its slot).
    v = vehicle()
    v.gcs()  # up and answering
    for i in range(7):
        m = v.gcs(source_system=255, wait=False)
        m.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
        assert recv(m, "PARAM_VALUE", timeout=3) is not None, i
        m.close()
        v._gcs.remove(m)
        time.sleep(0.3)  # (a tool takes longer than that to start)
    v.check_alive()


def test_transport_on_cpython_adopts_only_valid_frames_and_writes_to_every_peer():
    from pymavlink.dialects.v20 import common as mav
    from mavstack.dialects import common
    from mavstack.endpoint import Endpoint
    from mavstack.transport.udpin import UdpServer

    port = free_udp_port()
    ep = Endpoint(common, 1, 1)
    t = UdpServer("127.0.0.1", port)
    link = ep.add_link(t)
    heard = []
    ep.on(0, lambda link, p: heard.append(link.transport.rx_peer))

    def peer_socket():
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        s.settimeout(1)
        return s

    def pump(ms=50):
        for _ in range(ms):
            ep.poll()
            time.sleep(0.001)

    def frame(sysid):
        return mav.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mav.MAVLink(None, sysid, 190))

    a, b, junk = peer_socket(), peer_socket(), peer_socket()
    try:
        junk.sendto(b"\xfd\x01junk", ("127.0.0.1", port))
        pump()
        assert t.peers() == [] and heard == []  # junk is no peer
        a.sendto(frame(255), ("127.0.0.1", port))
        pump()
        assert heard == [a.getsockname()] and t.peers() == [a.getsockname()]
        junk.sendto(b"\x00", ("127.0.0.1", port))
        b.sendto(frame(254), ("127.0.0.1", port))
        pump()
        assert heard[-1] == b.getsockname()
        assert sorted(t.peers()) == sorted([a.getsockname(), b.getsockname()])
        # One frame out reaches both peers, and nothing reaches the junk's address.
        off = link.begin()
        link.txbuf[off:off + 9] = bytes(9)
        assert link.send(0)
        assert len(a.recv(512)) > 0 and len(b.recv(512)) > 0
        junk.settimeout(0.2)
        try:
            junk.recv(512)
            raise AssertionError("the junk's address got a frame")
        except socket.timeout:
            pass
        # Frames from a peer come in on its own socket: rx_peer says which.
        a.sendto(frame(255), ("127.0.0.1", port))
        pump()
        assert heard[-1] == a.getsockname()
    finally:
        for s in (a, b, junk):
            s.close()
        ep.close()
