"""Byte kernels: viper (MicroPython) and portable (MicroPython with MAVSTACK_PORTABLE=1,
and CPython) agree with each other and with an independent CRC (and, for the frame
scanner, an independent model of it), and the whole parser gives the same frames and
statistics with either set."""
import os
import random
import sys

import fastcrc
import pytest

from conftest import ROOT
from mavstack.kernels.bytes_portable import BUF_LEN, FIELDS, SLOTS
from wire_oracle import OURS, RUNTIME_IDS, RUNTIMES, corrupt, random_frames, parse_files, run_tool, x25

sys.path.insert(0, os.path.join(ROOT, "host_tools"))
import mavgen  # noqa: E402  (the dialects' block, as the generator writes it)


def kernel_cases(rnd, n):
    """Lines for wire_tool kernels, and the result each must give."""
    lines, expect = [], []
    for _ in range(n):
        size = rnd.choice([0, 1, 2, 17, 280, rnd.randint(0, 600)])
        data = rnd.randbytes(size)
        hx = data.hex() or "-"
        start = rnd.randint(0, size)
        end = rnd.randint(start, size)
        op = rnd.randrange(7)
        if op == 0:
            crc = rnd.choice([0xFFFF, 0, rnd.getrandbits(16)])
            lines.append("crc %s %d %d %d" % (hx, start, end, crc))
            expect.append(str(fastcrc.crc16.mcrf4xx(data[start:end], crc)))
        elif op == 1:
            # Start markers dense enough to be found, sparse enough to be skipped over.
            marked = bytearray(data)
            for i in range(len(marked)):
                if rnd.random() < 0.02:
                    marked[i] = rnd.choice([0xFD, 0xFE])
                elif marked[i] in (0xFD, 0xFE) and rnd.random() < 0.5:
                    marked[i] = 0
            found = next((i for i in range(start, end) if marked[i] in (0xFD, 0xFE)), end)
            lines.append("stx %s %d %d" % (marked.hex() or "-", start, end))
            expect.append(str(found))
        elif op == 2:
            dst = bytearray(rnd.randbytes(rnd.choice([280, 1023, rnd.randint(1, 300)])))
            # Source offsets up to a 4 KiB chunk and beyond: s is packed above bit 10.
            src = rnd.randbytes(rnd.randint(0, 5000) if rnd.random() < 0.15 else rnd.randint(0, 300))
            d = rnd.randrange(len(dst))
            s = rnd.randint(0, len(src))
            k = rnd.randint(0, min(len(dst) - d, len(src) - s))
            lines.append("copy %s %s %d %d %d" % (dst.hex(), src.hex() or "-", d, s, k))
            dst[d:d + k] = src[s:s + k]
            expect.append(dst.hex())
        elif op == 5:  # place: any destination offset (RAM storage's region)
            dst = bytearray(rnd.randbytes(rnd.randint(1, 70000) if rnd.random() < 0.1 else rnd.randint(1, 300)))
            src = rnd.randbytes(rnd.randint(1, 64))
            k = rnd.randint(0, min(len(src), len(dst)))
            d = rnd.randint(0, len(dst) - k)
            lines.append("place %s %s %d %d" % (dst.hex(), src.hex(), d, k))
            dst[d:d + k] = src[:k]
            expect.append(dst.hex())
        elif op == 4:  # a MAVLink 2 frame around a payload with trailing zeros, or none
            plen = rnd.randint(1, 255)
            payload = bytearray(rnd.randbytes(plen))
            cut = rnd.randint(0, plen)
            payload[cut:] = bytes(plen - cut)
            buf = bytearray(rnd.randbytes(10)) + payload + rnd.randbytes(2 + 13)
            extra = rnd.getrandbits(8)
            info = plen << 16 | rnd.getrandbits(8) << 8 | extra
            seq, sysid, compid, flags = (rnd.getrandbits(8) for _ in range(4))
            flags &= 1
            ids = seq | sysid << 8 | compid << 16 | flags << 24
            msgid = rnd.getrandbits(24)
            lines.append("seal %s %d %d %d" % (buf.hex(), info, ids, msgid))
            kept = len(payload.rstrip(b"\0")) or 1
            head = bytes([kept, flags, 0, seq, sysid, compid, msgid & 0xFF, msgid >> 8 & 0xFF, msgid >> 16])
            crc = fastcrc.crc16.mcrf4xx(head + payload[:kept] + bytes([extra]), 0xFFFF)
            expect.append((b"\xfd" + head + payload[:kept] + bytes([crc & 0xFF, crc >> 8])).hex())
        elif op == 6:  # id_info: a dialect's block (dialects/table.py), ids it has and not
            infos = {i: rnd.getrandbits(16) | rnd.randint(1, 255) << 16
                     for i in rnd.sample(range(1 << 24) if rnd.random() < 0.5 else range(600), rnd.randint(0, 300))}
            asked = rnd.choice([-1, 0, 255, 256, (1 << 24) - 1, 1 << 24, rnd.randrange(1 << 24),
                                rnd.choice(sorted(infos) or [7])])
            lines.append("info %s %d" % (mavgen.info_block(infos).hex(), asked))
            expect.append(str(infos.get(asked, 0)))
        else:
            if not size:
                data, hx, start, end = b"\x01", "01", 0, 1
            lines.append("zero %s %d %d" % (hx, start, end))
            z = bytearray(data)
            z[start:end] = bytes(end - start)
            expect.append(z.hex() or "-")
    return lines, expect


@pytest.mark.parametrize("runtime,portable", RUNTIMES, ids=RUNTIME_IDS)
def test_kernels_agree_on_random_inputs(tmp_path, runtime, portable):
    lines, expect = kernel_cases(random.Random(2024), 3000)
    src, out = tmp_path / "cases.txt", tmp_path / "out.txt"
    src.write_text("\n".join(lines) + "\n")
    impl = run_tool(["kernels", src, out], portable, runtime).strip()
    assert impl == ("portable" if portable else "viper")
    got = out.read_text().split("\n")[:-1]
    assert len(got) == len(expect)
    for line, g, e in zip(lines, got, expect):
        assert g == e, line[:80]


def test_parser_same_output_with_both_kernel_sets(tmp_path):
    """A mixed stream (MAVLink 1, 2, signed, garbage, damaged frames) gives byte-identical
    frame records and statistics on every runtime and kernel set, whatever the chunking."""
    rnd = random.Random(77)
    stream, _ = corrupt(rnd, random_frames(rnd, 1500), rate=0.2, garbage_rate=0.2)
    path = tmp_path / "stream.bin"
    path.write_bytes(stream)
    outputs = {}
    for (runtime, portable), name in zip(RUNTIMES, RUNTIME_IDS):
        for chunks in ("r5", "4096"):
            out = tmp_path / ("%s-%s.txt" % (name, chunks))
            results, impl = parse_files("common", [path], chunks, out, runtime, portable)
            assert impl == ("portable" if portable else "viper")
            outputs[name, chunks] = out.read_text().split("\n", 1)[1]
            assert results[0][1]["frames"] > 1000
    reference = outputs["cpython", "r5"]
    for key, text in outputs.items():
        assert text == reference, key


# --- the frame scanner ------------------------------------------------------------------


INFOS = OURS["common"].CRC_LEN  # the dialect wire_tool's scan reads


def scan_model(src, pos, end, buf):
    """kernels.scan as its contract (bytes_portable.py) says, written plainly, with the
    common dialect -> (answer, buf after)."""
    buf = bytearray(buf)
    fast = end >= 0
    end = abs(end)
    k = next((i for i in range(pos, end) if src[i] in (0xFD, 0xFE)), end)
    if k > pos:
        return -1 - (k << 2), buf
    more = -1 - (pos << 2 | 1), buf
    v1 = src[pos] == 0xFE
    hdr = 6 if v1 else 10
    if end - pos < hdr:
        return more
    plen = src[pos + 1]
    if v1:
        msgid, signed = src[pos + 5], 0
    else:
        if src[pos + 2] > 1 or src[pos + 8] or src[pos + 9]:
            return more
        msgid, signed = src[pos + 7], src[pos + 2]
    info = INFOS.get(msgid, 0)
    extra, least, full = info & 0xFF, info >> 8 & 0xFF, info >> 16
    if full == 0 or plen > full or (plen < least if v1 else plen == 0):
        return more
    n = hdr + plen + 2 + 13 * signed
    c = pos + hdr + plen
    if end - pos < n or x25(src[pos + 1:c], extra) != src[c] | src[c + 1] << 8:
        return more
    buf[0:n] = src[pos:pos + n]
    e = pos + n
    if not fast or signed:
        return -1 - (e << 2 | 2), buf
    buf[hdr + plen:hdr + full] = bytes(full - plen)
    s = 2 if v1 else 4  # seq, sysid, compid
    slots = [i for i in range(SLOTS, FIELDS, 4) if buf[i] and buf[i + 1:i + 3] == buf[s + 1:s + 3]]
    if not slots or (buf[s] - buf[slots[0] + 3] - 1) & 0xFF:
        return -1 - (e << 2 | 2), buf
    buf[slots[0] + 3] = buf[s]
    v = 1 if v1 else 2
    changed = buf[FIELDS] != v
    buf[FIELDS] = v
    return e << 2 | (2 if v1 else 0) | changed, buf


def scan_cases(rnd, n):
    """Frames (MAVLink 1, 2, signed, ids over 255, damaged, cut short) after garbage or
    not, scanned fast or careful from their start or earlier, with senders known or not,
    in sequence or not -> (lines, expected answers and buffers)."""
    frames = random_frames(rnd, n, v1_share=0.4, signed_share=0.15)
    lines, expect = [], []
    for f in frames:
        f = bytearray(f)
        how = rnd.random()
        if how < 0.1:
            f[rnd.randrange(1, len(f))] ^= 1 << rnd.randrange(8)  # damaged anywhere
        elif how < 0.15:
            f = f[:rnd.randrange(1, len(f))]  # cut short
        lead = bytes(rnd.randrange(0xFD) for _ in range(rnd.choice([0, 0, 0, 3])))
        src = lead + f + bytes(rnd.randrange(256) for _ in range(rnd.randint(0, 20)))
        buf = bytearray(BUF_LEN)
        buf[0:280] = rnd.randbytes(280)
        hdr = 6 if f[0] == 0xFE else 10
        if len(f) >= hdr and rnd.random() < 0.8:  # the sender in a slot
            s = 2 if hdr == 6 else 4
            i = SLOTS + 4 * rnd.randrange(8)
            last = (f[s] - 1) & 0xFF if rnd.random() < 0.8 else rnd.randrange(256)
            buf[i:i + 4] = bytes([1, f[s + 1], f[s + 2], last])
        buf[FIELDS] = rnd.choice([0, 1, 2])
        pos = rnd.choice([0, len(lead)]) if lead else 0
        end = len(src) if rnd.random() < 0.9 else rnd.randint(pos + 1, len(src))
        if rnd.random() < 0.2:
            end = -end
        lines.append("scan %s %d %d %s" % (src.hex(), pos, end, buf.hex()))
        expect.append(scan_model(src, pos, end, buf))
    return lines, expect


@pytest.mark.parametrize("runtime,portable", RUNTIMES, ids=RUNTIME_IDS)
def test_scan_agrees_with_its_model(tmp_path, runtime, portable):
    lines, expect = scan_cases(random.Random(4321), 1500)
    answers = [e[0] for e in expect]
    assert sum(a >= 0 for a in answers) > 300  # the fast answer
    for code in (0, 1, 2):
        assert sum(a < 0 and (-1 - a) & 3 == code for a in answers) > 30
    src, out = tmp_path / "cases.txt", tmp_path / "out.txt"
    src.write_text("\n".join(lines) + "\n")
    run_tool(["kernels", src, out], portable, runtime)
    got = out.read_text().split("\n")[:-1]
    assert len(got) == len(expect)
    for line, g, (answer, buf) in zip(lines, got, expect):
        r, hx = g.split()
        assert int(r) == answer, line[:120]
        after = bytes.fromhex(hx)
        # The frame area is the scanner's scratch when it delivers nothing.
        keep = 280 if answer < 0 and (-1 - answer) & 3 != 2 else 0
        assert after[keep:] == buf[keep:], line[:120]
