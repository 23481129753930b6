"""The seed's file transfer (FILE_TRANSFER_START / _DIR_LIST / _RES) against the unix
vehicle running the seed's dialect (`--set dialect=seed2012`), from a ground station
built by pymavlink's generator from the seed's own XML: listing, reading and writing
small files (binary-safe, resumed chunk by chunk over a lossy link), the seed's result
codes for paths that leave the folder (2), the stack's own files (1) and a full store (3)."""
import os
import socket
import time

import pytest

from relay import LossyRelay

CHUNK = 240
OK, NOT_PERMITTED, BAD_PATH, NO_SPACE = 0, 1, 2, 3


class SeedGcs:
    """A seed-era ground station on a UDP socket: each transfer retried until its
    result comes, asking again only for the chunks it lacks."""

    def __init__(self, mod, port):
        self.mod = mod
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(0.05)
        self.addr = ("127.0.0.1", port)
        self.mav = mod.MAVLink(None, srcSystem=255, srcComponent=190)
        self.mav.robust_parsing = True
        self.texts = []
        self.uid = 1000
        self.send(mod.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))

    def close(self):
        self.sock.close()

    def send(self, msg):
        self.sock.sendto(msg.pack(self.mav), self.addr)

    def frames(self, wait=0.3):
        """FILE_TRANSFER_* frames received within wait seconds."""
        got = []
        deadline = time.time() + wait
        while time.time() < deadline:
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            for m in self.mav.parse_buffer(data) or []:
                if m.get_type().startswith("FILE_TRANSFER"):
                    got.append(m)
                elif m.get_type() == "STATUSTEXT":
                    self.texts.append(m.text)
        return got

    def next_uid(self):
        self.uid += 1
        return self.uid

    def list(self, path, tries=40):
        uid = self.next_uid()
        chunks = {}
        for _ in range(tries):
            first = len(chunks)  # the chunks come in order: ask from the first missing
            while first in chunks:
                first += 1
            self.send(self.mod.MAVLink_file_transfer_dir_list_message(uid, path, first))
            for m in self.frames():
                if m.transfer_uid != uid:
                    continue
                if m.get_type() == "FILE_TRANSFER_RES":
                    if m.result != OK:
                        return m.result, None
                    if all(k in chunks for k in range(max(chunks, default=-1) + 1)):
                        return OK, b"".join(chunks[k] for k in sorted(chunks))
                elif m.get_type() == "FILE_TRANSFER_DIR_LIST":
                    chunks[m.flags] = bytes(m.get_payload()[8:248]).rstrip(b"\0")
        raise AssertionError("no listing of %r" % path)

    def read(self, path, tries=60):
        uid = self.next_uid()
        chunks, size = {}, None
        for _ in range(tries):
            first = 0
            while first in chunks:
                first += 1
            self.send(self.mod.MAVLink_file_transfer_start_message(uid, path, 1, 0, first))
            for m in self.frames():
                if m.transfer_uid != uid:
                    continue
                if m.get_type() == "FILE_TRANSFER_RES" and m.result != OK:
                    return m.result, None
                if m.get_type() == "FILE_TRANSFER_START" and m.direction == 1:
                    size = m.file_size
                    n = min(CHUNK, size - CHUNK * m.flags)
                    chunks[m.flags] = bytes(m.get_payload()[12:252])[:max(n, 0)]  # raw: binary-safe
            if size is not None and all(k in chunks for k in range(max(1, -(-size // CHUNK)))):
                return OK, b"".join(chunks[k] for k in sorted(chunks))[:size]
        raise AssertionError("could not read %r" % path)

    def write(self, path, data, tries=60):
        uid = self.next_uid()
        n = -(-len(data) // CHUNK)
        start = self.mod.MAVLink_file_transfer_start_message
        for _ in range(tries):  # ask, until echoed or refused
            self.send(start(uid, path, 0, len(data), 0))
            got = [m for m in self.frames() if m.transfer_uid == uid]
            refused = [m.result for m in got if m.get_type() == "FILE_TRANSFER_RES"]
            if refused and refused[0] != OK:
                return refused[0]
            if any(m.get_type() == "FILE_TRANSFER_START" and m.flags == 0 for m in got) or refused:
                break
        acked = set()
        for _ in range(tries):
            for k in range(n):
                if k + 1 not in acked:
                    self.send(start(uid, data[k * CHUNK:(k + 1) * CHUNK], 0, len(data), k + 1))
            if len(acked) == n:  # all in: the result may have been lost, ask with the last again
                self.send(start(uid, data[(n - 1) * CHUNK:], 0, len(data), n))
            for m in self.frames():
                if m.transfer_uid != uid:
                    continue
                if m.get_type() == "FILE_TRANSFER_RES":
                    if m.result != OK or len(acked) >= n - 1:
                        return m.result
                elif m.direction == 0 and m.flags:
                    acked.add(m.flags)
        raise AssertionError("could not write %r" % path)


@pytest.fixture
def seed_vehicle(vehicle, tmp_path, seedmav):
    gcs = []

    def start(files=(), args=(), lossy=False):
        st = tmp_path / "storage"
        st.mkdir(exist_ok=True)
        for name, data in dict(files).items():
            (st / name).parent.mkdir(parents=True, exist_ok=True)
            (st / name).write_bytes(data)
        v = vehicle(storage=st, args=["--set", "dialect=seed2012"] + list(args))
        port = v.port
        if lossy:
            relay = LossyRelay(v.port, rate=0.1, seed=3)
            gcs.append(relay)
            port = relay.port
        g = SeedGcs(seedmav, port)
        g.vehicle = v
        gcs.append(g)
        time.sleep(0.5)  # the vehicle up
        return st, g

    yield start
    for g in gcs:
        g.close()


def test_list_read_and_write_small_files(seed_vehicle):
    blob = bytes(range(256)) * 4 + b"\0\0tail"  # NUL bytes: the raw field carries them
    st, g = seed_vehicle({"blob.bin": blob, "empty.txt": b"", "logs/a.log": b"a" * 10})
    result, text = g.list(b"")
    assert result == OK
    lines = text.decode().splitlines()
    assert "Fblob.bin\t%d" % len(blob) in lines and "Fempty.txt\t0" in lines and "Dlogs" in lines
    assert not [x for x in lines if x[1:].startswith(("mission", "fence", "rally", "params"))]
    assert g.list(b"logs") == (OK, b"Fa.log\t10\n")
    assert g.read(b"blob.bin") == (OK, blob)
    assert g.read(b"empty.txt") == (OK, b"")
    data = os.urandom(3 * CHUNK + 17)
    assert g.write(b"logs/new.bin", data) == OK
    assert (st / "logs" / "new.bin").read_bytes() == data
    assert g.write(b"blob.bin", b"replaced") == OK  # atomically: written aside, then renamed
    assert (st / "blob.bin").read_bytes() == b"replaced" and not (st / "blob.bin.new").exists()
    assert g.write(b"zero.txt", b"") == OK and (st / "zero.txt").read_bytes() == b""
    assert g.read(b"logs/new.bin") == (OK, data)


def test_over_a_lossy_link(seed_vehicle):
    data = os.urandom(6000)
    st, g = seed_vehicle({"big.bin": data}, lossy=True)
    assert g.read(b"big.bin") == (OK, data)
    up = os.urandom(5000)
    assert g.write(b"up.bin", up) == OK
    assert (st / "up.bin").read_bytes() == up


def test_paths_outside_the_folder_are_bad_paths(seed_vehicle, tmp_path):
    (tmp_path / "outside.txt").write_bytes(b"secret")
    st, g = seed_vehicle({"in.txt": b"in"})
    os.symlink(str(tmp_path), str(st / "up"))
    os.symlink(str(tmp_path / "outside.txt"), str(st / "link.txt"))
    for path in (b"../outside.txt", b"/etc/passwd", str(tmp_path / "outside.txt").encode(),
                 b"sub/../../outside.txt", b"up/outside.txt", b"link.txt", b"no_such.txt"):
        assert g.read(path) == (BAD_PATH, None), path
    for path in (b"../new.txt", b"/tmp/new.txt", b"up/new.txt", b"link.txt", b"no_dir/x.txt"):
        assert g.write(path, b"x") == BAD_PATH, path
    for path in (b"..", b"/", b"up", b"in.txt"):
        assert g.list(path) == (BAD_PATH, None), path
    assert (tmp_path / "outside.txt").read_bytes() == b"secret" and not (tmp_path / "new.txt").exists()
    g.frames(0.5)
    assert any("leaves the storage folder" in t for t in g.texts)


def test_the_stacks_own_files_are_not_permitted(seed_vehicle):
    st, g = seed_vehicle({"params": b"P" * 30, "signing_key": b"K" * 42})
    own = {n: (st / n).read_bytes() for n in ("params", "signing_key", "mission.0", "fence.1", "rally.0")}
    for name in list(own) + ["params.new", "mission.1.new"]:
        assert g.read(name.encode()) == (NOT_PERMITTED, None), name
        assert g.write(name.encode(), b"overwritten") == NOT_PERMITTED, name
    for name, data in own.items():
        assert (st / name).read_bytes() == data
    g.frames(0.5)
    assert any("own file" in t for t in g.texts)


def test_a_full_store_is_no_space(seed_vehicle):
    st, g = seed_vehicle({"old.bin": b"o" * 500}, args=["--set", "ftp_space=1500"])
    assert g.write(b"big.bin", b"b" * 1200) == NO_SPACE  # 500 + 1200 > 1500
    assert g.write(b"huge.bin", b"h" * 70000) == NO_SPACE  # past what 255 chunks carry
    assert g.write(b"old.bin", b"n" * 1200) == OK  # replacing a file frees its own bytes
    assert (st / "old.bin").read_bytes() == b"n" * 1200
    assert not (st / "big.bin").exists() and not (st / "big.bin.new").exists()


def test_on_a_heap_locked_vehicle(seed_vehicle):
    data = os.urandom(2000)
    st, g = seed_vehicle({"a.bin": data}, args=["--set", "heap_lock=1", "--set", "application=0"])
    assert g.list(b"") == (OK, b"Fa.bin\t2000\n")
    assert g.read(b"a.bin") == (OK, data)
    assert g.write(b"b.bin", data[:999]) == OK and (st / "b.bin").read_bytes() == data[:999]
    assert g.read(b"../a.bin") == (BAD_PATH, None) and g.read(b"params") == (NOT_PERMITTED, None)
    g.vehicle.check_alive()
    g.vehicle.stop()
    assert "MemoryError" not in g.vehicle.output()
