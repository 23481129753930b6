"""Byte kernels: viper (MicroPython) and portable (MicroPython with MAVSTACK_PORTABLE=1,
and CPython) agree with each other and with an independent CRC, and the whole parser
gives the same frames and statistics with either set."""
import random

import fastcrc
import pytest

from wire_oracle import RUNTIME_IDS, RUNTIMES, corrupt, random_frames, parse_files, run_tool


def kernel_cases(rnd, n):
    """Lines for wire_tool kernels, and the result each must give."""
    lines, expect = [], []
    for _ in range(n):
        size = rnd.choice([0, 1, 2, 17, 280, rnd.randint(0, 600)])
        data = rnd.randbytes(size)
        hx = data.hex() or "-"
        start = rnd.randint(0, size)
        end = rnd.randint(start, size)
        op = rnd.randrange(4)
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
