"""Real transports: a serial link over a real pty and UDP links (udpin and udpout), the
vehicle side in MicroPython (heap locked once the peers are known, both kernel sets)
and in CPython; frames both ways checked with pymavlink."""
import os
import select
import socket
import subprocess
import time

import pytest

from conftest import FIRMWARE, MICROPYTHON, PYTHON, ROOT, free_udp_port
from wire_oracle import MPY_DIR, reference

M2 = reference("common", 2)
PEER = os.path.join(MPY_DIR, "wire_peer.py")
STOP = 31999
RUNTIMES = ["mpy-viper", "mpy-portable", "cpython"]


def start_peer(runtime, specs):
    env = dict(os.environ)
    env.pop("MAVSTACK_PORTABLE", None)
    if runtime == "cpython":
        cmd = [PYTHON, PEER] + specs
        env["PYTHONPATH"] = os.pathsep.join([FIRMWARE, MPY_DIR])
    else:
        cmd = [MICROPYTHON, PEER] + specs + ["--lock"]
        env["MICROPYPATH"] = os.pathsep.join([MPY_DIR, FIRMWARE, ".frozen"])
        if runtime == "mpy-portable":
            env["MAVSTACK_PORTABLE"] = "1"
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    line = proc.stdout.readline()
    if line.strip() != "ready":
        proc.kill()
        raise AssertionError(line + proc.stdout.read())
    return proc


def finish(proc):
    try:
        out, _ = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        raise AssertionError("peer did not stop\n" + out)
    assert proc.returncode == 0, out
    links = {}
    for line in out.split("\n"):
        w = line.split()
        if w and w[0] == "link":
            keys = ("frames", "crc_errors", "bytes_discarded", "unknown_ids", "bad_frames",
                    "lost", "acks", "version", "locked")
            links[w[1]] = dict(zip(keys, map(int, w[2:])))
    return links


class Gcs:
    """pymavlink on one side of a byte channel: packs with its own sequence numbers
    and collects what comes back."""

    def __init__(self, write, read):
        self.write = write
        self.read = read
        self.mav = M2.MAVLink(self, 255, 190)
        self.mav.robust_parsing = True
        self.rx = M2.MAVLink(None, 0, 0)
        self.rx.robust_parsing = True
        self.got = []
        self.keepalive = None  # called every second while pumping

    def send(self, msg, v1=False):
        self.mav.send(msg, force_mavlink1=v1)

    def command(self, cmd, v1=False):
        self.send(M2.MAVLink_command_long_message(1, 1, cmd, 0, 1, 2, 3, 4, 5, 6, 7), v1)

    def pump(self, cond, timeout=10):
        deadline = time.time() + timeout
        beat = time.time() + 1
        while time.time() < deadline:
            if self.keepalive is not None and time.time() > beat:
                self.keepalive()
                beat = time.time() + 1
            data = self.read(0.05)
            if data:
                self.got += [m for m in self.rx.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]
            if cond(self.got):
                return self.got
        raise AssertionError("timed out; got %s" % [m.get_type() for m in self.got][-20:])

    def acks(self):
        return [m for m in self.got if m.get_type() == "COMMAND_ACK"]


def version_of(m):
    return 2 if m.get_msgbuf()[0] == 0xFD else 1


def n_acks(k):
    return lambda got: len([m for m in got if m.get_type() == "COMMAND_ACK"]) >= k


def exchange(gcs, first_command=31000, v1_phase=True):
    """MAVLink 1 commands until the GCS speaks 2, then MAVLink 2 with noise and a damaged
    frame in between. Returns the bytes of noise and damage sent."""
    gcs.pump(lambda got: any(m.get_type() == "HEARTBEAT" for m in got))
    sent = 0
    if v1_phase:
        assert all(version_of(m) == 1 for m in gcs.got)  # MAVLink 1 until told otherwise
        for i in range(20):
            gcs.command(first_command + i, v1=True)
        gcs.pump(n_acks(20))
        assert [a.command for a in gcs.acks()] == [first_command + i for i in range(20)]
        assert all(version_of(a) == 1 for a in gcs.acks())
    gcs.send(M2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
    noise = bytes(range(0x20, 0x20 + 37))
    gcs.write(noise)
    bad = bytearray(M2.MAVLink_command_long_message(1, 1, 31500, 0, 0, 0, 0, 0, 0, 0, 0).pack(gcs.mav))
    gcs.mav.seq = (gcs.mav.seq + 1) & 0xFF
    bad[-1] ^= 0xFF
    gcs.write(bytes(bad))
    sent += len(noise) + len(bad)
    before = len(gcs.acks())
    for i in range(20):
        gcs.command(first_command + 100 + i)
    gcs.pump(n_acks(before + 20))
    v2 = gcs.acks()[before:]
    assert [a.command for a in v2] == [first_command + 100 + i for i in range(20)]
    assert all(version_of(a) == 2 and (a.target_system, a.target_component) == (255, 190) for a in v2)
    gcs.pump(lambda got: version_of([m for m in got if m.get_type() == "HEARTBEAT"][-1]) == 2)
    return sent


@pytest.mark.parametrize("runtime", RUNTIMES)
def test_serial_link_over_a_real_pty(runtime):
    master, slave = os.openpty()
    try:
        os.set_blocking(master, False)
        device = os.ttyname(slave)

        def read(timeout):
            r, _, _ = select.select([master], [], [], timeout)
            return os.read(master, 4096) if r else b""

        def write(data):
            view = memoryview(data)
            while view:
                select.select([], [master], [], 1)
                view = view[os.write(master, view):]

        proc = start_peer(runtime, ["serial:%s:57600" % device])
        try:
            gcs = Gcs(write, read)
            damage = exchange(gcs)
            gcs.command(STOP)
        finally:
            links = finish(proc)
    finally:
        os.close(master)
        os.close(slave)
    [stats] = links.values()
    assert stats["frames"] == 20 + 1 + 20 + 1 and stats["acks"] == 41
    assert stats["crc_errors"] == 1 and stats["bytes_discarded"] == damage and stats["lost"] == 1
    assert stats["version"] == 2
    assert stats["locked"] == (0 if runtime == "cpython" else 1)


@pytest.mark.parametrize("runtime", RUNTIMES)
def test_udp_links_udpin_and_udpout(runtime):
    port_in, port_out = free_udp_port(), free_udp_port()
    s_out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # where the vehicle's udpout sends
    s_out.bind(("127.0.0.1", port_out))
    s_in = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a GCS calling the vehicle's udpin
    s_in.bind(("127.0.0.1", 0))
    out_peer = []

    def reader(s):
        def read(timeout):
            r, _, _ = select.select([s], [], [], timeout)
            if not r:
                return b""
            data, addr = s.recvfrom(65536)
            if s is s_out and not out_peer:
                out_peer.append(addr)
            return data
        return read

    def write_in(data):
        s_in.sendto(data, ("127.0.0.1", port_in))

    def write_out(data):
        s_out.sendto(data, out_peer[0])

    proc = start_peer(runtime, ["udpin:127.0.0.1:%d" % port_in, "udpout:127.0.0.1:%d" % port_out])
    try:
        g_out = Gcs(write_out, reader(s_out))
        g_out.pump(lambda got: any(m.get_type() == "HEARTBEAT" for m in got))  # udpout calls first
        g_in = Gcs(write_in, reader(s_in))
        g_in.send(M2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), v1=True)  # udpin hears first
        g_in.pump(lambda got: any(m.get_type() == "HEARTBEAT" for m in got))
        # Both peers keep talking while the other link is exercised.
        g_out.keepalive = lambda: g_in.send(M2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), v1=True)
        g_in.keepalive = lambda: g_out.send(M2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        damage_out = exchange(g_out, 32000)
        damage_in = exchange(g_in, 33000)
        # A burst far larger than one read: on MicroPython a read takes every queued
        # datagram that fits, so a small read buffer would cut one short.
        before = len(g_in.acks())
        for i in range(80):
            g_in.command(34000 + i)
        g_in.pump(n_acks(before + 80))
        assert [a.command for a in g_in.acks()[before:]] == list(range(34000, 34080))
        assert not [a for a in g_in.acks() if a.command < 33000]  # answers go to their own link
        assert not [a for a in g_out.acks() if a.command >= 33000]
        g_in.command(STOP)
    finally:
        links = finish(proc)
        s_in.close()
        s_out.close()
    s_in_stats = links["udpin:127.0.0.1:%d" % port_in]
    s_out_stats = links["udpout:127.0.0.1:%d" % port_out]
    # Every frame each GCS sent arrived (the damaged one is not counted as sent).
    assert s_in_stats["frames"] == g_in.mav.total_packets_sent and s_in_stats["acks"] == 121
    assert s_out_stats["frames"] == g_out.mav.total_packets_sent and s_out_stats["acks"] == 40
    for stats, damage in ((s_in_stats, damage_in), (s_out_stats, damage_out)):
        assert stats["crc_errors"] == 1 and stats["bytes_discarded"] == damage
        assert stats["lost"] == 1 and stats["version"] == 2
        assert stats["locked"] == (0 if runtime == "cpython" else 1)
