"""The parameter table as one bytes block (params/block.py): the committed boards' blocks
are current (host_tools/paramgen.py), a block reads as its rows do, a bad one is refused,
and on MicroPython a table read from a block holds less heap than one made of rows."""
import os
import sys

import pytest

from conftest import ROOT, run_mpy

from mavstack.services import params as P
from mavstack.services.params import block
from mavstack.services.params.table import ParamTable

sys.path.insert(0, os.path.join(ROOT, "host_tools"))
sys.path.insert(0, os.path.join(ROOT, "boards"))
import paramgen  # noqa: E402
import qemu_params  # noqa: E402
import qemu_params_block  # noqa: E402

MIXED = (
    ("U8", P.UINT8, 7, 0, 200),
    ("I8", P.INT8, -3, -100, 100),
    ("U16", P.UINT16, 1000),
    ("I16", P.INT16, -1000),
    ("U32", P.UINT32, 12345),
    ("I32", P.INT32, -5),
    ("F", P.REAL32, 1.5, -10.0, 10.0),
    ("RO", P.UINT8, 1, 0, 255, P.READ_ONLY),
)


@pytest.mark.parametrize("name", sorted(paramgen.BLOCKS))
def test_committed_block_is_current(name):
    with open(paramgen.path(name), encoding="utf-8") as f:
        assert f.read() == paramgen.render(paramgen.BLOCKS[name]), \
            "%s is stale: run `make dialects`" % name


def test_check_mode_agrees():
    assert paramgen.main(["--check"]) == 0


def test_the_qemu_block_is_its_readable_table():
    assert qemu_params_block.PARAMS == bytes(block.compile(qemu_params.PARAMS))


@pytest.mark.parametrize("rows", [MIXED, qemu_params.PARAMS], ids=["mixed", "qemu"])
def test_a_block_reads_as_its_rows(rows):
    a, b = ParamTable(rows), ParamTable(bytes(block.compile(rows)))
    assert a.count == b.count == len(rows)
    for i, row in enumerate(rows):
        for t in (a, b):
            assert t.index(row[0]) == i
            assert t.name(i) == row[0] and t.type(i) == row[1]
            assert t.flags(i) == (row[5] if len(row) > 5 else 0)
        assert a.value(i) == b.value(i)
    assert b.find(b"NOPE", 0, 4) == -1
    assert a.pack() == b.pack()


def test_colliding_hashes_chain():
    rows = tuple(("P%d" % i, P.INT32, i) for i in range(300))  # 512 buckets: some share
    t = ParamTable(bytes(block.compile(rows)))
    assert [t.index("P%d" % i) for i in range(300)] == list(range(300))


@pytest.mark.parametrize("cut", ["magic", "version", "length"])
def test_a_bad_block_is_refused(cut):
    b = bytearray(block.compile(MIXED))
    if cut == "magic":
        b[0] ^= 1
    elif cut == "version":
        b[4] += 1
    else:
        b = b[:-1]
    with pytest.raises(ValueError):
        ParamTable(bytes(b))


def test_a_block_holds_less_heap_on_micropython():
    r = run_mpy(
        "import gc\n"
        "from mavstack.services.params.table import ParamTable\n"
        "from mavstack.services.params import block\n"
        "import qemu_params\n"
        "rows = qemu_params.PARAMS\n"
        "blk = bytes(block.compile(rows))\n"
        "def held(table):\n"
        "    gc.collect(); a = gc.mem_alloc(); t = ParamTable(table); gc.collect()\n"
        "    return gc.mem_alloc() - a\n"
        "print('held', held(rows), held(blk))\n", path=[os.path.join(ROOT, "boards")])
    assert r.returncode == 0, r.stderr
    rows, blk = (int(x) for x in r.stdout.split("held")[1].split())
    assert blk < rows - 2500, (rows, blk)
