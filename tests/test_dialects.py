"""The generated dialects: current, in agreement with pymavlink, importable on MicroPython."""
import importlib.util
import os
import struct
import subprocess
import sys

import pytest
from pymavlink.generator import mavgen as pymavgen
from pymavlink.generator import mavparse

from conftest import ROOT, run_mpy

sys.path.insert(0, os.path.join(ROOT, "host_tools"))
import mavgen  # noqa: E402
from mavstack.dialects import layout  # noqa: E402

MAVGEN = os.path.join(ROOT, "host_tools", "mavgen.py")
DIALECTS = {name: (xml, path) for name, xml, path in mavgen.committed()}


def import_file(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


_refs = {}


def reference(name, tmp_path_factory):
    """pymavlink's own generated module for a dialect, and its parsed XML files."""
    if name not in _refs:
        xml = DIALECTS[name][0]
        if name == "common":
            from pymavlink.dialects.v20 import common as mod
        else:
            out = str(tmp_path_factory.mktemp("pymavgen") / ("ref_%s.py" % name))
            opts = pymavgen.Opts(out, wire_protocol="2.0", language="Python3", validate=False)
            assert pymavgen.mavgen(opts, [xml])
            mod = import_file("ref_" + name, out)
        # mavparse per file gives what the Python module lacks: len1 and offsets.
        parsed, todo = {}, [os.path.abspath(xml)]
        while todo:
            path = todo.pop()
            x = mavparse.MAVXML(path, mavparse.PROTOCOL_2_0)
            for m in x.message:
                parsed[m.id] = m
            todo += [os.path.join(os.path.dirname(path), i) for i in x.include]
        _refs[name] = mod, parsed
    return _refs[name]


def meta_file(name):
    return mavgen.meta_path(DIALECTS[name][1])


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_committed_dialect_is_current(name):
    xml, path = DIALECTS[name]
    messages, enums = mavgen.load(xml)
    texts = mavgen.render(messages, enums, name, os.path.basename(xml))
    for p, text in zip((path, meta_file(name)), texts):
        with open(p, encoding="utf-8") as f:
            current = f.read() == text
        assert current, "%s is stale: run `make dialects`" % os.path.relpath(p, ROOT)


def test_check_mode_agrees():
    assert mavgen.main(["--all", "--check"]) == 0


def test_check_mode_notices_a_stale_meta_module(tmp_path):
    xml = DIALECTS["seed2012"][0]
    out = str(tmp_path / "d.py")
    assert mavgen.main([xml, out]) == 0
    assert mavgen.main([xml, out, "--check"]) == 0
    with open(mavgen.meta_path(out), "a") as f:
        f.write("# edited\n")
    assert mavgen.main([xml, out, "--check"]) == 1


def test_seed_dialect_is_the_2012_message_set():
    messages, _ = mavgen.load(DIALECTS["seed2012"][0])
    assert len(messages) == 84
    mod = import_file("seed2012", DIALECTS["seed2012"][1])
    meta = import_file("seed2012_meta", meta_file("seed2012"))
    assert len(mod.FMT) == len(mod.CRC_LEN) == len(meta.MESSAGES) == 84


def test_runtime_module_holds_only_the_tables():
    for name in DIALECTS:
        mod = import_file("rt_" + name, DIALECTS[name][1])
        assert sorted(k for k in vars(mod) if not k.startswith("__")) == [
            "CRC_LEN", "FMT", "IdTable", "InfoTable", "TARGETS", "TARGETS_HIGH"]
        # Constants (flash when frozen) read like dicts: FMT two tuples, CRC_LEN a block.
        assert not isinstance(mod.FMT, dict) and isinstance(mod.CRC_LEN.block, bytes)
        assert sorted(mod.FMT) == sorted(mod.CRC_LEN) == [k for k, _ in mod.FMT.items()]
        assert all(mod.FMT[k] == mod.FMT.get(k) and k in mod.FMT for k in mod.CRC_LEN)
        for table in (mod.FMT, mod.CRC_LEN):
            assert len(table) == len(mod.FMT) and dict(table.items())
            for absent in (-1, 3, 255 if 255 not in mod.FMT else 0x7FFF, 0x1000000):
                assert absent not in table and table.get(absent, "none") == "none"
                with pytest.raises(KeyError):
                    table[absent]


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_routing_targets_match_pymavlink(name, tmp_path_factory):
    """TARGETS / TARGETS_HIGH (mavstack/router.py) say where target_system and
    target_component sit, as MAVLink's C library's message entries do."""
    _, parsed = reference(name, tmp_path_factory)
    ours = import_file("ours_" + name, DIALECTS[name][1])
    high = {}
    for i in range(0, len(ours.TARGETS_HIGH), 5):
        r = ours.TARGETS_HIGH[i:i + 5]
        high[r[0] | r[1] << 8 | r[2] << 16] = (r[3], r[4])
    for mid, p in parsed.items():
        want = (p.target_system_ofs + 1 if p.message_flags & mavparse.FLAG_HAVE_TARGET_SYSTEM else 0,
                p.target_component_ofs + 1 if p.message_flags & mavparse.FLAG_HAVE_TARGET_COMPONENT else 0)
        got = tuple(ours.TARGETS[2 * mid:2 * mid + 2]) if mid < 256 else high.get(mid, (0, 0))
        assert got == want, "%s %d" % (p.name, mid)
    assert set(high) <= set(parsed)


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_messages_match_pymavlink(name, tmp_path_factory):
    ref, parsed = reference(name, tmp_path_factory)
    ours = import_file("ours_" + name, DIALECTS[name][1])
    meta = import_file("ours_%s_meta" % name, meta_file(name))
    assert set(ours.FMT) == set(ours.CRC_LEN) == set(meta.MESSAGES) == set(ref.mavlink_map) == set(parsed)
    for mid, cls in ref.mavlink_map.items():
        mname, crc_extra, len1, len2, fmt, fields = layout.message(ours, meta, mid)
        p = parsed[mid]
        where = "%s %d" % (mname, mid)
        assert mname == cls.msgname, where
        assert getattr(meta, "MSG_" + mname) == mid, where
        assert crc_extra == cls.crc_extra == p.crc_extra, where
        assert len1 == p.wire_min_length, where
        assert len2 == cls.unpacker.size == p.wire_length == struct.calcsize(fmt), where
        # Wire order, types, array lengths, offsets.
        assert [f[0] for f in fields] == cls.ordered_fieldnames, where
        types = dict(zip(cls.fieldnames, cls.fieldtypes))
        assert [f[1] for f in fields] == [types[f[0]] for f in fields], where
        assert [f[2] for f in fields] == cls.array_lengths, where
        assert [f[3] for f in fields] == [p.field_offsets[f[0]] for f in fields], where
        # Same struct layout; a scalar char is '1s' here, 'c' there.
        assert fmt == cls.unpacker.format.replace("c", "1s"), where


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_enums_match_pymavlink(name, tmp_path_factory):
    ref, _ = reference(name, tmp_path_factory)
    meta = import_file("ours_%s_meta" % name, meta_file(name))
    _, enums = mavgen.load(DIALECTS[name][0])
    assert set(enums) == set(ref.enums)
    for enum, entries in enums.items():
        for entry, value in entries:
            assert getattr(meta, entry) == getattr(ref, entry) == value, "%s.%s" % (enum, entry)


def test_layout_fields():
    assert layout.fields("<Q3hB", "t acc id") == [
        ("t", "uint64_t", 0, 0), ("acc", "int16_t", 3, 8), ("id", "uint8_t", 0, 14)]
    # '1s' is a scalar char, 'Ns' a char array, '1B' an array of one.
    assert layout.fields("<16s1s1B", "name c one") == [
        ("name", "char", 16, 0), ("c", "char", 0, 16), ("one", "uint8_t", 1, 17)]
    for fmt, names in [("<BB", "a"), ("<B", "a b"), ("<Bx", "a"), ("<B3", "a"), ("<<B", "a"), ("B", "a")]:
        with pytest.raises(ValueError):
            layout.fields(fmt, names)


def test_micropython_imports_runtime_dialects():
    r = run_mpy(
        "import struct\n"
        "from mavstack.dialects import common, seed2012\n"
        "for mod in (common, seed2012):\n"
        "    assert sorted(mod.FMT) == sorted(mod.CRC_LEN)\n"
        "    for mid, fmt in mod.FMT.items():\n"
        "        assert struct.calcsize(fmt) == mod.CRC_LEN[mid] >> 16, mid\n"
        "print('OK', len(common.FMT), len(seed2012.FMT))\n"
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["OK", "210", "84"]


def test_micropython_imports_meta_and_layout():
    r = run_mpy(
        "import struct\n"
        "from mavstack.dialects import common, common_meta, seed2012, seed2012_meta, layout\n"
        "n = 0\n"
        "for rt, meta in ((common, common_meta), (seed2012, seed2012_meta)):\n"
        "    for mid in rt.FMT:\n"
        "        name, crc, len1, len2, fmt, fields = layout.message(rt, meta, mid)\n"
        "        last = fields[-1]\n"
        "        assert last[3] + struct.calcsize('<' + fmt[-1]) * (last[2] or 1) == len2, name\n"
        "        assert getattr(meta, 'MSG_' + name) == mid\n"
        "        n += 1\n"
        "print(n, common_meta.MSG_HEARTBEAT, seed2012_meta.MAV_STATE_ACTIVE)\n"
        "print(layout.fields(common.FMT[0], common_meta.MESSAGES[0][1])[-1])\n"
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == ["294 0 4", "('mavlink_version', 'uint8_t', 0, 8)"]


# Heap the runtime module of `common` may take on the unix port (64-bit), compiled from
# source, past the byte kernels (the parser's, imported first on a board): the
# single-module tables took 328,000 bytes. A board imports it at start-up, so this bound
# guards the RAM budget; on a board, frozen, the tables stay in flash (bench_mcu_heap.py).
COMMON_RUNTIME_HEAP_BOUND = 18 * 1024


def test_runtime_dialect_heap_cost():
    r = run_mpy(
        "import gc\n"
        "import mavstack.dialects, mavstack.kernels\n"
        "gc.collect()\n"
        "before = gc.mem_alloc()\n"
        "from mavstack.dialects import common\n"
        "gc.collect()\n"
        "print(gc.mem_alloc() - before)\n"
    )
    assert r.returncode == 0, r.stderr
    used = int(r.stdout)
    assert used < COMMON_RUNTIME_HEAP_BOUND, "importing common takes %d bytes of heap" % used


def test_restricted_dialect(tmp_path):
    out = tmp_path / "tiny.py"
    subprocess.run([sys.executable, MAVGEN, DIALECTS["common"][0], str(out),
                    "--messages", "HEARTBEAT,PARAM_VALUE"], check=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.py", "tiny_meta.py"]
    r = run_mpy(
        "import tiny, tiny_meta\n"
        "print(sorted(tiny.FMT), sorted(tiny.CRC_LEN), sorted(tiny_meta.MESSAGES))\n"
        "print(hasattr(tiny_meta, 'MSG_SYS_STATUS'), tiny_meta.MSG_PARAM_VALUE, tiny_meta.MAV_TYPE_QUADROTOR)\n",
        path=[str(tmp_path)],
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == ["[0, 22] [0, 22] [0, 22]", "False 22 2"]
    # A few messages: FMT stays a dict (less heap than IdTable's code would take).
    assert "FMT = {" in out.read_text() and "IdTable" not in out.read_text()


def test_select_by_id_or_name():
    messages, _ = mavgen.load(DIALECTS["seed2012"][0])
    assert [m.name for m in mavgen.select(messages, ["22", "heartbeat"])] == ["HEARTBEAT", "PARAM_VALUE"]
    with pytest.raises(mavgen.MavgenError):
        mavgen.select(messages, ["NO_SUCH_MESSAGE"])


def write(path, body):
    path.write_text('<?xml version="1.0"?>\n<mavlink>%s</mavlink>\n' % body)
    return str(path)


def test_includes_and_enum_merging(tmp_path):
    write(tmp_path / "base.xml",
          '<enums><enum name="E"><entry value="0x10" name="E_A"/><entry name="E_B"/></enum></enums>'
          '<messages><message id="1" name="ONE"><field type="char" name="c"/></message></messages>')
    write(tmp_path / "mid.xml", "<include>base.xml</include>")
    top = write(tmp_path / "top.xml",
                "<include>base.xml</include><include>mid.xml</include>"
                '<enums><enum name="E"><entry value="2**6" name="E_C"/><entry name="E_D"/></enum>'
                '<enum name="F"><entry name="F_A"/></enum></enums>'
                '<messages><message id="2" name="TWO"><field type="uint8_t" name="a"/>'
                '<field type="uint16_t[2]" name="b"/><extensions/><field type="uint32_t" name="x"/>'
                "</message></messages>")
    messages, enums = mavgen.load(top)
    assert [m.name for m in messages] == ["ONE", "TWO"]
    assert enums == {"E": [("E_A", 16), ("E_B", 17), ("E_C", 64), ("E_D", 65)], "F": [("F_A", 1)]}
    two = messages[1]
    assert [f.name for f in two.wire_fields()] == ["b", "a", "x"]
    assert (two.len1, two.len2, two.fmt) == (5, 9, "<2HBI")
    assert messages[0].fmt == "<1s"


def test_char_array_of_one_rejected(tmp_path):
    # FMT spells a scalar char '1s'; char[1] would read back as a scalar.
    xml = write(tmp_path / "c1.xml", '<messages><message id="1" name="A">'
                '<field type="char[1]" name="c"/></message></messages>')
    with pytest.raises(mavgen.MavgenError):
        mavgen.load(xml)


@pytest.mark.parametrize("messages", [
    '<message id="1" name="A"/><message id="1" name="B"/>',
    '<message id="16777216" name="A"/>',
    '<message id="1" name="A"><field type="float[64]" name="x"/></message>',
    '<message id="1" name="A"><field type="bool" name="x"/></message>',
])
def test_bad_definitions_rejected(tmp_path, messages):
    with pytest.raises(mavgen.MavgenError):
        mavgen.load(write(tmp_path / "bad.xml", "<messages>%s</messages>" % messages))
