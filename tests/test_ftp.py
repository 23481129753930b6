"""MAVLink FTP against the unix vehicle over UDP: pymavlink's FTP client, MAVProxy's `ftp`
module and MAVSDK's ftp plugin list, read, write, checksum and remove files in the
storage folder, also over a lossy link; paths that leave the folder, the stack's own
files, a full store, unknown opcodes and re-sent requests, byte for byte on the wire."""
import os
import struct
import time
import zlib

from conftest import recv
from gcs_tools import MavProxy, statustext
from relay import LossyRelay

# opcodes and NAK codes (the MAVLink FTP service)
TERMINATE, RESET, LIST, OPEN_RO, READ, CREATE, WRITE, REMOVE = 1, 2, 3, 4, 5, 6, 7, 8
CRC32, BURST, ACK, NAK = 14, 15, 128, 129
FAIL, FAIL_ERRNO, INVALID_SESSION, EOF, UNKNOWN_COMMAND, FILE_PROTECTED, FILE_NOT_FOUND = 1, 2, 4, 6, 7, 9, 10
ENOSPC = 28


def ardupilot_crc32(data):
    """CRC-32 as ArduPilot's crc_crc32 (and MAVProxy's `crclocal`): zlib's, seed and
    final inversion undone."""
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


def soon(cond, timeout=10.0):
    deadline = time.time() + timeout
    while not cond():
        if time.time() > deadline:
            return False
        time.sleep(0.1)
    return True


def storage_with(tmp_path, files):
    st = tmp_path / "storage"
    st.mkdir(exist_ok=True)
    for name, data in files.items():
        (st / name).parent.mkdir(parents=True, exist_ok=True)
        (st / name).write_bytes(data)
    return st


class Raw:
    """FILE_TRANSFER_PROTOCOL requests from pymavlink, each answered by the reply whose
    sequence number is the request's plus one."""

    def __init__(self, m):
        self.m = m
        self.seq = 100

    def request(self, opcode, data=b"", session=0, offset=0, size=None, seq=None):
        seq = self.seq if seq is None else seq
        self.seq = seq + 1
        payload = struct.pack("<HBBBBBBI", seq, session, opcode, len(data) if size is None else size, 0, 0, 0, offset)
        payload = (payload + data).ljust(251, b"\0")
        self.m.mav.file_transfer_protocol_send(0, self.m.target_system, self.m.target_component, payload)
        return seq

    def reply(self, seq, timeout=5.0):
        def mine(r):
            return struct.unpack("<H", bytes(r.payload[0:2]))[0] == (seq + 1) & 0xFFFF

        r = recv(self.m, "FILE_TRANSFER_PROTOCOL", timeout, mine)
        assert r is not None, "no reply to request %d" % seq
        p = bytes(r.payload)
        seq_, session, opcode, size, req_opcode, burst, _, offset = struct.unpack("<HBBBBBBI", p[:12])
        assert (r.target_system, r.target_component) == (255, 190)  # back to the sender
        return {"session": session, "opcode": opcode, "size": size, "req_opcode": req_opcode,
                "offset": offset, "data": p[12:12 + size], "burst": burst}

    def ask(self, opcode, data=b"", **kw):
        return self.reply(self.request(opcode, data, **kw))


def nak(r):
    assert r["opcode"] == NAK, r
    return r["data"][0]


def mavftp(m):
    from pymavlink import mavftp as pymavftp

    # Its defaults but a shorter wait for silence (3.7 s), which ends some operations.
    settings = pymavftp.MAVFTPSettings([
        ("debug", int, 0), ("pkt_loss_tx", int, 0), ("pkt_loss_rx", int, 0), ("max_backlog", int, 5),
        ("burst_read_size", int, 80), ("write_size", int, 80), ("write_qsize", int, 5),
        ("idle_detection_time", float, 1.2), ("read_retry_time", float, 1.0), ("retry_time", float, 0.5)])
    return pymavftp.MAVFTP(m, m.target_system, m.target_component, settings)


def put(ftp, local, remote):
    r = ftp.cmd_put([str(local), remote])
    if r.error_code == 0:
        r = ftp.process_ftp_reply("CreateFile", timeout=60)
    return r


def get(ftp, remote, local):
    r = ftp.cmd_get([remote, str(local)])
    if r.error_code == 0:
        r = ftp.process_ftp_reply("OpenFileRO", timeout=60)
    return r


def test_pymavlink_list_read_write_crc_remove(vehicle, tmp_path):
    hello = b"hello world\n" * 100
    st = storage_with(tmp_path, {"hello.txt": hello, "logs/a.log": b"x" * 10})
    v = vehicle(storage=st)
    m = v.gcs()
    ftp = mavftp(m)
    listing = ftp.cmd_list(["/"]).directory_listing
    names = {(e.name, e.is_dir, e.size_b) for e in listing}
    assert ("hello.txt", False, len(hello)) in names and ("logs", True, 0) in names
    assert not {e.name for e in listing} & {"mission.0", "mission.1", "fence.0", "rally.0", "params"}
    assert [e.name for e in ftp.cmd_list(["/logs"]).directory_listing] == ["a.log"]

    assert ftp.read("hello.txt", 300, 1000) == hello[1000:1200]  # ReadFile-based reads
    assert get(ftp, "hello.txt", tmp_path / "got.txt").error_code == 0  # BurstReadFile
    assert (tmp_path / "got.txt").read_bytes() == hello

    data = os.urandom(20000)
    (tmp_path / "up.bin").write_bytes(data)
    assert put(ftp, tmp_path / "up.bin", "logs/up.bin").error_code == 0
    assert (st / "logs" / "up.bin").read_bytes() == data
    assert ftp.cmd_crc(["logs/up.bin"]).error_code == 0
    raw = Raw(m)
    r = raw.ask(CRC32, b"logs/up.bin")
    assert r["opcode"] == ACK and struct.unpack("<I", r["data"])[0] == ardupilot_crc32(data)
    assert ftp.cmd_rm(["logs/up.bin"]).error_code == 0
    assert not (st / "logs" / "up.bin").exists()
    assert ftp.cmd_rm(["logs/up.bin"]).error_code == FILE_NOT_FOUND


def test_pymavlink_over_a_lossy_link(vehicle, tmp_path):
    st = storage_with(tmp_path, {})
    v = vehicle(storage=st)
    relay = LossyRelay(v.port, rate=0.1, seed=11)
    try:
        m = v.gcs(port=relay.port)
        ftp = mavftp(m)
        data = os.urandom(12000)
        (tmp_path / "up.bin").write_bytes(data)
        # pymavlink's client never sends a lost CreateFile again: its first WriteFile then
        # meets no session (NAK InvalidSession) and the put fails. A user puts again.
        for _ in range(4):
            r = put(ftp, tmp_path / "up.bin", "up.bin")
            if r.error_code != INVALID_SESSION:
                break
        assert r.error_code == 0
        assert (st / "up.bin").read_bytes() == data
        assert get(ftp, "up.bin", tmp_path / "back.bin").error_code == 0
        assert (tmp_path / "back.bin").read_bytes() == data
        assert relay.stats["dropped"] and relay.stats["duplicated"] and relay.stats["delayed"]
    finally:
        relay.close()


def test_mavproxy_ftp_over_a_lossy_link(vehicle, tmp_path):
    st = storage_with(tmp_path, {"notes.txt": b"vehicle notes\n" * 300})
    v = vehicle(storage=st)
    relay = LossyRelay(v.port, rate=0.1, seed=5)
    data = os.urandom(9000)
    (tmp_path / "up.bin").write_bytes(data)
    mp = MavProxy(relay.port, tmp_path, "ftp")
    try:
        mp.expect(r"(?i)online system 1|Detected vehicle|heartbeat", timeout=30)
        mp.say("ftp put up.bin up.bin")
        mp.expect(r"Sent file of length 9000", timeout=60)
        assert (st / "up.bin").read_bytes() == data
        mp.say("ftp get notes.txt got.txt")
        mp.expect(r"Wrote 4200 bytes to got.txt", timeout=60)
        # (MAVProxy prints that line, then closes the file)
        assert soon(lambda: (tmp_path / "got.txt").read_bytes() == (st / "notes.txt").read_bytes())
        mp.say("ftp list /")
        mp.expect(r"notes.txt\s+4200", timeout=60)
        mp.say("ftp crc up.bin")
        mp.expect(r"crc: up.bin 0x%08x" % ardupilot_crc32(data), timeout=60)
        mp.say("ftp rm up.bin")
        assert soon(lambda: not (st / "up.bin").exists(), 30)
    finally:
        mp.close()
        relay.close()


def _mavsdk_wait(start, timeout=30):
    """Run an async MAVSDK FTP call -> its final FtpResult (None: no end in time)."""
    import queue

    from mavsdk.plugins.ftp import FtpResult

    results = queue.Queue()

    def done(result, progress, user_data):
        if result != FtpResult.NEXT:
            results.put(result)

    start(done)
    try:
        return results.get(timeout=timeout)
    except queue.Empty:
        return None


def test_mavsdk_ftp_plugin(vehicle, tmp_path):
    from gcs_tools import mavsdk_system
    from mavsdk.plugins.ftp import Ftp, FtpResult

    alpha = os.urandom(3000)
    st = storage_with(tmp_path, {"a.bin": alpha, "sub/b.txt": b"beta"})
    v = vehicle(storage=st)
    (tmp_path / "dl").mkdir()
    (tmp_path / "up.bin").write_bytes(os.urandom(2000))
    with mavsdk_system(v.port) as system:
        ftp = Ftp(system)
        entries = [str(e) for e in ftp.list_directory("/").entries]
        assert any("a.bin" in e for e in entries) and any("sub" in e for e in entries), entries
        for burst in (True, False):  # BurstReadFile, then ReadFile
            result = _mavsdk_wait(lambda cb: ftp.download_async("/a.bin", str(tmp_path / "dl"), burst, cb))
            assert result == FtpResult.SUCCESS, (burst, result)
            assert (tmp_path / "dl" / "a.bin").read_bytes() == alpha
            (tmp_path / "dl" / "a.bin").unlink()
        result = _mavsdk_wait(lambda cb: ftp.upload_async(str(tmp_path / "up.bin"), "/sub", cb))
        assert result == FtpResult.SUCCESS, result
        assert (st / "sub" / "up.bin").read_bytes() == (tmp_path / "up.bin").read_bytes()
        assert ftp.are_files_identical(str(tmp_path / "up.bin"), "/sub/up.bin")  # CalcFileCRC32
        ftp.remove_file("/sub/b.txt")
        assert not (st / "sub" / "b.txt").exists()


def test_paths_that_leave_the_folder_are_refused(vehicle, tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_bytes(b"secret")
    st = storage_with(tmp_path, {"in.txt": b"inside"})
    os.symlink(str(tmp_path), str(st / "up"))  # a link out of the folder
    os.symlink(str(outside), str(st / "link.txt"))
    v = vehicle(storage=st)
    m = v.gcs()
    raw = Raw(m)
    for path in (b"../outside.txt", b"/../outside.txt", b"sub/../../outside.txt", b"up/outside.txt",
                 b"link.txt", b"up"):
        assert nak(raw.ask(OPEN_RO, path)) == FAIL, path
        assert nak(raw.ask(CREATE, path, session=3)) == FAIL, path
        assert nak(raw.ask(REMOVE, path)) == FAIL, path
        assert nak(raw.ask(CRC32, path)) == FAIL, path
    assert nak(raw.ask(LIST, b"up")) == FAIL
    assert statustext(m, "leaves the storage folder")
    # "/" is the folder itself: an absolute path names a file in it, never the host's.
    assert nak(raw.ask(OPEN_RO, b"/etc/passwd")) == FILE_NOT_FOUND
    assert nak(raw.ask(CREATE, str(outside).encode(), session=3)) == FILE_NOT_FOUND
    r = raw.ask(OPEN_RO, b"/in.txt", session=4)
    assert r["opcode"] == ACK and r["data"] == struct.pack("<I", 6)
    assert outside.read_bytes() == b"secret" and (st / "link.txt").is_symlink()
    listing = raw.ask(LIST, b"/")["data"].split(b"\0")
    assert b"Fin.txt\t6" in listing and not any(e[1:].startswith((b"up", b"link")) for e in listing if e)


def test_the_stacks_own_files_are_protected(vehicle, tmp_path):
    own = {"params": b"P" * 40, "signing_key": b"K" * 42}
    st = storage_with(tmp_path, dict(own, **{"mine.txt": b"ok"}))
    v = vehicle(storage=st)
    m = v.gcs()
    raw = Raw(m)
    own = dict(own, **{n: (st / n).read_bytes() for n in ("mission.0", "mission.1", "fence.0", "rally.1")})
    for name in list(own) + ["params.new", "mission.0.new", "signing_key.new"]:
        for op, kw in ((OPEN_RO, {}), (CREATE, {"session": 2}), (REMOVE, {}), (CRC32, {})):
            assert nak(raw.ask(op, name.encode(), **kw)) == FILE_PROTECTED, (name, op)
            assert nak(raw.ask(op, b"/" + name.encode(), **kw)) == FILE_PROTECTED, (name, op)
    assert statustext(m, "own file")
    listing = raw.ask(LIST, b"/")["data"]
    assert listing == b"Fmine.txt\t2\0"
    for name, data in own.items():
        assert (st / name).read_bytes() == data, name
    assert not (st / "params.new").exists()


def test_a_full_store_is_no_space(vehicle, tmp_path):
    st = storage_with(tmp_path, {"old.bin": b"o" * 1000})
    v = vehicle(storage=st, args=["--set", "ftp_space=4000"])  # the stack's own files do not count
    m = v.gcs()
    ftp = mavftp(m)
    (tmp_path / "big.bin").write_bytes(os.urandom(5000))
    (tmp_path / "small.bin").write_bytes(b"s" * 2500)
    r = put(ftp, tmp_path / "big.bin", "big.bin")
    assert r.error_code == FAIL_ERRNO and r.system_error == ENOSPC
    assert not (st / "big.bin").exists()  # the part that fitted went with the session
    assert put(mavftp(m), tmp_path / "small.bin", "small.bin").error_code == 0
    assert (st / "small.bin").read_bytes() == b"s" * 2500
    # 3500 of 4000 held: a write past the rest is refused; the file goes when its
    # session closes, the files already there stay.
    raw = Raw(m)
    assert raw.ask(CREATE, b"more.bin", session=9)["opcode"] == ACK
    assert raw.ask(WRITE, b"m" * 200, session=9, offset=0)["opcode"] == ACK
    r = raw.ask(WRITE, b"m" * 200, session=9, offset=400)
    assert nak(r) == FAIL_ERRNO and r["data"][1] == ENOSPC
    assert (st / "more.bin").read_bytes() == b"m" * 200
    assert raw.ask(TERMINATE, session=9)["opcode"] == ACK
    assert not (st / "more.bin").exists() and (st / "old.bin").exists()


def test_unknown_opcodes_are_nakked(vehicle, tmp_path):
    v = vehicle(storage=storage_with(tmp_path, {"a.txt": b"a"}))
    raw = Raw(v.gcs())
    for opcode in (0, 9, 10, 11, 12, 13, 16, 17, 100, ACK, NAK, 255):
        seq = raw.request(opcode, b"a.txt", session=1)
        r = raw.reply(seq)
        assert nak(r) == UNKNOWN_COMMAND and r["req_opcode"] == opcode and r["size"] == 1, opcode
    # Sessions that are not open, reads past the end.
    assert nak(raw.ask(READ, session=42, size=10)) == INVALID_SESSION
    assert nak(raw.ask(WRITE, b"x", session=42)) == INVALID_SESSION
    assert nak(raw.ask(TERMINATE, session=42)) == INVALID_SESSION
    assert raw.ask(OPEN_RO, b"a.txt", session=1)["opcode"] == ACK
    assert nak(raw.ask(READ, session=1, offset=1, size=10)) == EOF
    assert nak(raw.ask(READ, session=1, offset=0x7FFFFFFF, size=10)) == EOF
    assert raw.ask(RESET)["opcode"] == ACK
    assert nak(raw.ask(READ, session=1, size=10)) == INVALID_SESSION  # reset closed it


def test_resent_requests_get_the_same_answer(vehicle, tmp_path):
    st = storage_with(tmp_path, {"gone.txt": b"bye", "keep.txt": b"k"})
    v = vehicle(storage=st)
    raw = Raw(v.gcs())
    # A RemoveFile whose ACK was lost, sent again: the same ACK, not FileNotFound.
    seq = raw.request(REMOVE, b"gone.txt")
    first = raw.reply(seq)
    assert first["opcode"] == ACK and not (st / "gone.txt").exists()
    raw.request(REMOVE, b"gone.txt", seq=seq)
    assert raw.reply(seq) == first
    assert nak(raw.ask(REMOVE, b"gone.txt")) == FILE_NOT_FOUND  # a new request (new seq) runs
    # A CreateFile sent again after its ACK: answered, the file not emptied a second time.
    seq = raw.request(CREATE, b"new.txt", session=5)
    assert raw.reply(seq)["opcode"] == ACK
    w = raw.request(WRITE, b"written", session=5)
    assert raw.reply(w)["opcode"] == ACK
    raw.request(WRITE, b"written", session=5, seq=w)  # the write again: same ACK
    assert raw.reply(w)["opcode"] == ACK
    assert raw.ask(TERMINATE, session=5)["opcode"] == ACK
    assert (st / "new.txt").read_bytes() == b"written"
    # Replies count on from the request: seq + 1, wrapping at 2^16.
    seq = raw.request(LIST, b"/", seq=0xFFFF)
    r = recv(raw.m, "FILE_TRANSFER_PROTOCOL", 5)
    assert r.payload[0] == 0 and r.payload[1] == 0


def test_transfers_on_a_heap_locked_vehicle(vehicle, tmp_path):
    # The heap locked once the vehicle is built (without the simulator, which allocates):
    # reads, bursts and writes run locked, opening and listing open it for their moment.
    st = storage_with(tmp_path, {"a.bin": os.urandom(5000)})
    v = vehicle(storage=st, args=["--set", "heap_lock=1", "--set", "application=0"])
    m = v.gcs()
    ftp = mavftp(m)
    assert {e.name for e in ftp.cmd_list(["/"]).directory_listing} == {"a.bin"}
    assert get(ftp, "a.bin", tmp_path / "a.bin").error_code == 0
    assert (tmp_path / "a.bin").read_bytes() == (st / "a.bin").read_bytes()
    (tmp_path / "up.bin").write_bytes(os.urandom(7000))
    assert put(ftp, tmp_path / "up.bin", "up.bin").error_code == 0
    assert (st / "up.bin").read_bytes() == (tmp_path / "up.bin").read_bytes()
    raw = Raw(m)
    assert raw.ask(CRC32, b"up.bin")["data"] == struct.pack("<I", ardupilot_crc32((st / "up.bin").read_bytes()))
    assert nak(raw.ask(OPEN_RO, b"../x")) == FAIL and nak(raw.ask(9, b"d")) == UNKNOWN_COMMAND
    assert ftp.cmd_rm(["up.bin"]).error_code == 0
    v.check_alive()
    v.stop()
    assert "MemoryError" not in v.output()
