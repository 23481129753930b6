"""Generate docs/seed-coverage.md: what mavstack does with every message and MAV_CMD of
the seed (the 2012 common set, firmware/mavstack/dialects/seed2012*.py).

    python host_tools/seed_coverage.py            write docs/seed-coverage.md
    python host_tools/seed_coverage.py --check    exit 1 if the committed table is stale

Nothing in the table is written by hand: it is read from the seed dialect, the unix
vehicle built on CPython (the handlers its services register, its producers and
commands), the services' sources and the tests. Where each column comes from:
docs/mavctl.md.
"""
import ast
import glob
import io
import os
import re
import shutil
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
SERVICES_DIR = os.path.join(FIRMWARE, "mavstack", "services")
OUT = os.path.join(ROOT, "docs", "seed-coverage.md")
for p in (FIRMWARE, os.path.join(ROOT, "boards")):
    if p not in sys.path:
        sys.path.insert(0, p)


def seed_names():
    """({msgid: NAME}, {cmd id: NAME}) of the seed's set."""
    from mavstack.dialects import seed2012_meta as meta

    msgs, cmds = {}, {}
    for k, v in vars(meta).items():
        if k.startswith("MSG_"):
            msgs[v] = k[4:]
        elif k.startswith("MAV_CMD_") and not k.startswith("MAV_CMD_ACK"):
            cmds[v] = k[8:]
    return dict(sorted(msgs.items())), dict(sorted(cmds.items()))


def build(dialect, board="unix"):
    """The board's endpoint in CPython with its services and application -> endpoint,
    with `taken`: {msgid: [handler, ...]} its services registered with Endpoint.on."""
    import main
    from mavstack.endpoint import Endpoint

    storage = tempfile.mkdtemp(prefix="seedcov")
    opts = {"links": ["udpin:127.0.0.1:0"], "storage": storage, "sysid": None,
            "options": {"dialect": dialect}}
    if os.environ.get("SEED_COVERAGE_NO_APP"):  # (debugging the tool while the simulator is broken)
        opts["options"]["application"] = "0"
    taken = {}
    register = Endpoint.on

    def on(ep, msgid, handler, wake=True):  # Endpoint.on, noting what each service takes
        if not register(ep, msgid, handler, wake):
            return False
        taken.setdefault(msgid, []).append(handler)
        return True

    out = sys.stdout
    sys.stdout = io.StringIO()  # the build's own report
    Endpoint.on = on
    try:
        ep, app = main.build(main.load_board(board), opts)
    finally:
        Endpoint.on = register
        sys.stdout = out
        shutil.rmtree(storage, ignore_errors=True)
    ep.close()
    ep.app = app
    ep.taken = taken
    return ep


def slot_owner(ep, slot):
    """The service that made a telemetry slot (telemetry, or one holding it)."""
    for svc in ep.services.values():
        for v in vars(svc).values():
            if v is slot or (isinstance(v, dict) and slot in v.values()):
                return type(svc).__module__.replace("mavstack.services.", "")
            echo = getattr(v, "echo", None)
            if echo is not None and getattr(echo, "slot", None) is slot:
                return type(svc).__module__.replace("mavstack.services.", "")
        for v in getattr(svc, "records", ()):
            echo = getattr(v, "echo", None)
            if echo is not None and echo.slot is slot:
                return type(svc).__module__.replace("mavstack.services.", "")
    return "telemetry"


def producer_owner(ep, fn):
    obj = getattr(fn, "__self__", None)
    if type(obj).__name__ in ("Slot", "NamedSlot"):
        tm = getattr(ep, "telemetry", None)
        if tm is not None and obj in tm.slots.values():
            return "telemetry"
        return slot_owner(ep, obj)
    return owner(fn)


def handler_name(fn):
    return "%s.%s" % (owner(fn), getattr(fn, "__name__", "?"))


def owner(fn):
    """The module (services/NAME, services/PACKAGE.NAME, or sim.NAME) a handler belongs to."""
    obj = getattr(fn, "__self__", None)
    if obj is not None and hasattr(obj, "service") and not hasattr(obj, "NAME"):
        obj = obj.service  # a per-message delivery object (services/debug.py)
    mod = type(obj).__module__ if obj is not None else getattr(fn, "__module__", "?")
    return mod.replace("mavstack.services.", "")


def sent_by_sources():
    """{(id, constant name): [service, ...]} for messages a service sends as an answer."""
    sent = {}
    stack = os.path.join(FIRMWARE, "mavstack")
    for path in sorted(glob.glob(os.path.join(stack, "**", "*.py"), recursive=True)):
        top = SERVICES_DIR if path.startswith(SERVICES_DIR) else stack  # the core's statustext too
        rel = os.path.relpath(path, top)[:-3].replace(os.sep, ".")
        module = rel[: -len(".__init__")] if rel.endswith(".__init__") else rel  # as owner() names it
        with open(path, encoding="utf-8") as f:
            text = f.read()
        consts = dict(re.findall(r"^(_MSG_\w+) = const\((\d+)\)", text, re.M))
        for name in set(re.findall(r"send(?:_payload)?\((_MSG_\w+)", text)):
            if name in consts:
                # by name: the constant names the message its service means (ids are shared
                # between the dialects' different messages)
                sent.setdefault((int(consts[name]), name[5:]), []).append(module)
    return sent


def mission_commands():
    """MAV_CMD ids a mission may hold: the rules of services/missions/items.py, read from
    its source (_MISSION_RULES: 3 bytes a command, its id little-endian first)."""
    path = os.path.join(SERVICES_DIR, "missions", "items.py")
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    rules = next(ast.literal_eval(node.value) for node in tree.body if isinstance(node, ast.Assign)
                 and [getattr(t, "id", None) for t in node.targets] == ["_MISSION_RULES"])
    return {rules[i] | rules[i + 1] << 8 for i in range(0, len(rules), 3)}


def test_index():
    """[(test id, text of the function, markers)] of tests/test_*.py."""
    tests = []
    tdir = os.path.join(ROOT, "tests")
    for fname in sorted(os.listdir(tdir)):
        if not (fname.startswith("test_") and fname.endswith(".py")):
            continue
        path = os.path.join(tdir, fname)
        with open(path, encoding="utf-8") as f:
            src = f.read()
        lines = src.splitlines()
        try:
            tree = ast.parse(src)
        except SyntaxError:
            continue
        file_tests, helpers = [], []
        for node in tree.body:
            if not isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                continue
            text = "\n".join(lines[node.lineno - 1:node.end_lineno])
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_"):
                marks = set()
                for m in re.findall(r"#\s*seed:\s*([A-Z0-9_, ]+)", text):
                    marks.update(x.strip() for x in m.split(",") if x.strip())
                file_tests.append(("tests/%s::%s" % (fname, node.name), text, marks))
            else:
                helpers.append((node.name, text))
        tests += file_tests
        # A helper (a station class, a fixture) serves its file's tests: its text counts
        # for the first test that names it, else the file's first test.
        for name, text in helpers:
            if file_tests:
                users = [t for t in file_tests if re.search(r"\b%s\b" % name, t[1])]
                tests.append(((users or file_tests)[0][0], text, set()))
    return tests


def proving_test(name, tests, cmd=False, cid=None):
    for tid, _, marks in tests:
        if name in marks:
            return tid
    low = name.lower()
    pats = [r"MAV_CMD_%s\b" % name] + ([r"\bItem\(\s*\d+,\s*%d\b" % cid, r"\b(run|command)\(\w+,\s*%d\b" % cid]
                                        if cid is not None else []) if cmd else [r'"%s"' % name, r"\b%s_(send|encode)\(" % low,
                                                  r"MAVLink_%s_message\b" % low, r'"%s"' % low,
                                                  r"\.frame\(%d\b" % cid]
    pats.append(r"#.*\b%s\b" % name)
    pats.append(r"\b%s\b" % name)
    for pat in pats:
        for tid, text, _ in tests:
            if re.search(pat, text):
                return tid
    return ""


def same_meaning(msgid):
    from mavstack.dialects import common, seed2012

    a, b = seed2012.CRC_LEN.get(msgid), common.CRC_LEN.get(msgid)
    return b is not None and (a & 0xFF) == (b & 0xFF)


def message_rows(msgs, eps, sent, tests):
    rows = []
    for msgid, name in msgs.items():
        ep = eps["seed2012"]
        common_too = same_meaning(msgid)
        ins = sorted({owner(h) for h in ep.taken.get(msgid, ())})
        outs = []
        if msgid in ep.producers:
            outs.append(producer_owner(ep, ep.producers[msgid]))
        for (i, short), services in sent.items():
            # the constant's name ends the message's (_MSG_ITEM_REACHED: MISSION_ITEM_REACHED)
            if i == msgid and name.endswith(short):
                outs += [s for s in services if s not in outs]
        what = []
        if ins:
            what.append("taken")
        if msgid in ep.producers:
            what.append("sent on request and by streams")
        elif outs:
            what.append("sent as an answer")
        direction = "/".join(d for d, on in (("in", ins), ("out", outs)) if on) or "-"
        services = ", ".join(sorted(set(ins + outs)))
        if not what:
            what = ["NOT HANDLED"]
        dialects = "both" if common_too else "seed2012 (today's common: another message or none)"
        rows.append((msgid, name, direction, "; ".join(what), services, dialects,
                     proving_test(name, tests, cid=msgid)))
    return rows


def command_rows(cmds, eps, tests, in_missions, reasons):
    rows = []
    for cid, name in cmds.items():
        fns = [eps[d].commands[cid] for d in eps if cid in eps[d].commands]
        handlers = sorted({owner(f) for f in fns})
        what = []
        if cid in reasons:
            what.append("UNSUPPORTED: " + reasons[cid])
        elif handlers:
            what.append("command: " + ", ".join(sorted({"`%s`" % handler_name(f) for f in fns})))
        if cid in in_missions:
            what.append("mission item: accepted, carried out as the runner makes it current")
        if not what:
            what = ["NOT HANDLED"]
        rows.append((cid, name, "in", "; ".join(what), ", ".join(handlers) or "missions (missions/items.py)",
                     proving_test(name, tests, cmd=True, cid=cid)))
    return rows


def render():
    from mavstack.services import seed_commands

    msgs, cmds = seed_names()
    eps = {d: build(d) for d in ("seed2012", "common")}
    tests = test_index()
    mrows = message_rows(msgs, eps, sent_by_sources(), tests)
    crows = command_rows(cmds, eps, tests, mission_commands(), seed_commands.REASONS)
    bad = [r[1] for r in mrows + crows if "NOT HANDLED" in r[3]]
    if bad:
        raise SystemExit("seed_coverage: not handled and no reason given: " + ", ".join(bad))
    out = ["# Seed coverage", "",
           "Generated by `host_tools/seed_coverage.py` (`make seed-coverage`) from the seed",
           "dialect, the unix vehicle's handler and command tables (both dialects) and the",
           "tests; do not edit. %d messages, %d MAV_CMDs." % (len(mrows), len(crows)), "",
           "## Messages", "",
           "| id | message | direction | what mavstack does | service | dialects | test |",
           "|---|---|---|---|---|---|---|"]
    for r in mrows:
        out.append("| %d | %s | %s | %s | %s | %s | %s |" % (r[0], r[1], r[2], r[3], r[4], r[5], _t(r[6])))
    out += ["", "## Commands (MAV_CMD)", "",
            "| id | command | direction | what mavstack does | service | test |",
            "|---|---|---|---|---|---|"]
    for r in crows:
        out.append("| %d | %s | %s | %s | %s | %s |" % (r[0], r[1], r[2], r[3], r[4], _t(r[5])))
    missing = sum(1 for r in mrows if not r[6]) + sum(1 for r in crows if not r[5])
    out += ["", "Rows without a test: %d." % missing, ""]
    return "\n".join(out)


def _t(tid):
    return "`%s`" % tid if tid else "-"


def main(argv):
    text = render()
    if "--check" in argv:
        try:
            with open(OUT, encoding="utf-8") as f:
                current = f.read()
        except OSError:
            current = None
        if current != text:
            print("docs/seed-coverage.md is stale: run `make seed-coverage`")
            return 1
        return 0
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w", encoding="utf-8") as f:
        f.write(text)
    print("wrote", os.path.relpath(OUT, ROOT))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
