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


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_committed_dialect_is_current(name):
    xml, path = DIALECTS[name]
    messages, enums = mavgen.load(xml)
    text = mavgen.render(messages, enums, name, os.path.basename(xml))
    with open(path, encoding="utf-8") as f:
        current = f.read() == text
    assert current, "%s is stale: run `make dialects`" % os.path.relpath(path, ROOT)


def test_check_mode_agrees():
    assert mavgen.main(["--all", "--check"]) == 0


def test_seed_dialect_is_the_2012_message_set():
    messages, _ = mavgen.load(DIALECTS["seed2012"][0])
    assert len(messages) == 84
    mod = import_file("seed2012", DIALECTS["seed2012"][1])
    assert len(mod.LAYOUT) == len(mod.CRC_LEN) == 84


@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_messages_match_pymavlink(name, tmp_path_factory):
    ref, parsed = reference(name, tmp_path_factory)
    ours = import_file("ours_" + name, DIALECTS[name][1])
    assert set(ours.LAYOUT) == set(ours.CRC_LEN) == set(ref.mavlink_map) == set(parsed)
    for mid, cls in ref.mavlink_map.items():
        mname, fmt, fields = ours.LAYOUT[mid]
        crc_len = ours.CRC_LEN[mid]
        p = parsed[mid]
        where = "%s %d" % (mname, mid)
        assert mname == cls.msgname, where
        assert getattr(ours, "MSG_" + mname) == mid, where
        assert crc_len & 0xFF == cls.crc_extra == p.crc_extra, where
        assert crc_len >> 8 & 0xFF == p.wire_min_length, where
        assert crc_len >> 16 == cls.unpacker.size == p.wire_length == struct.calcsize(fmt), where
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
    ours = import_file("ours_" + name, DIALECTS[name][1])
    _, enums = mavgen.load(DIALECTS[name][0])
    assert set(enums) == set(ref.enums)
    for enum, entries in enums.items():
        for entry, value in entries:
            assert getattr(ours, entry) == getattr(ref, entry) == value, "%s.%s" % (enum, entry)


def test_micropython_imports_dialects():
    r = run_mpy(
        "import struct\n"
        "from mavstack.dialects import common, seed2012\n"
        "for mod in (common, seed2012):\n"
        "    for mid, (name, fmt, fields) in mod.LAYOUT.items():\n"
        "        n = mod.CRC_LEN[mid] >> 16\n"
        "        assert struct.calcsize(fmt) == n, name\n"
        "        assert len(struct.unpack(fmt, bytes(n))) >= len(fields), name\n"
        "assert common.MSG_HEARTBEAT == 0 and seed2012.MAV_STATE_ACTIVE == 4\n"
        "print('OK', len(common.LAYOUT), len(seed2012.LAYOUT))\n"
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["OK", "210", "84"]


def test_restricted_dialect(tmp_path):
    out = tmp_path / "tiny.py"
    subprocess.run([sys.executable, MAVGEN, DIALECTS["common"][0], str(out),
                    "--messages", "HEARTBEAT,PARAM_VALUE"], check=True)
    r = run_mpy(
        "import struct, tiny\n"
        "print(sorted(tiny.LAYOUT), sorted(tiny.CRC_LEN), hasattr(tiny, 'MSG_SYS_STATUS'))\n"
        "print(tiny.MSG_PARAM_VALUE, tiny.MAV_TYPE_QUADROTOR)\n",
        path=[str(tmp_path)],
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == ["[0, 22] [0, 22] False", "22 2"]


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


@pytest.mark.parametrize("messages", [
    '<message id="1" name="A"/><message id="1" name="B"/>',
    '<message id="16777216" name="A"/>',
    '<message id="1" name="A"><field type="float[64]" name="x"/></message>',
    '<message id="1" name="A"><field type="bool" name="x"/></message>',
])
def test_bad_definitions_rejected(tmp_path, messages):
    with pytest.raises(mavgen.MavgenError):
        mavgen.load(write(tmp_path / "bad.xml", "<messages>%s</messages>" % messages))
