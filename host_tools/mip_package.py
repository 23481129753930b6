"""package.json at the top of the checkout: mavstack as a package MicroPython's `mip` installs.

    python host_tools/mip_package.py            write package.json
    python host_tools/mip_package.py --check    exit 1 if the committed one is stale

It lists main.py and the stack as a board runs it (firmware/mavstack without the host-side
name tables: *_meta.py and dialects/layout.py, which flash leaves out too), each under the
path it takes on the board, with the source relative to package.json. Installed with
`mpremote mip install --target /flash package.json` (docs/boards.md), beside a board profile
copied as board.py; `mavctl flash` and the freezing manifest are the other two ways.
"""
import ast
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
OUT = os.path.join(ROOT, "package.json")


def version():
    """mavstack.VERSION as "major.minor.patch", read from its source."""
    with open(os.path.join(FIRMWARE, "mavstack", "__init__.py"), encoding="utf-8") as f:
        for node in ast.parse(f.read()).body:
            if isinstance(node, ast.Assign) and node.targets[0].id == "VERSION":
                return ".".join(str(n) for n in ast.literal_eval(node.value))
    raise SystemExit("mip_package: no VERSION in firmware/mavstack/__init__.py")


def files():
    """[(path on the board, source relative to the checkout)], sorted."""
    out = [("main.py", "firmware/main.py")]
    stack = os.path.join(FIRMWARE, "mavstack")
    for dirpath, dirnames, filenames in os.walk(stack):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
        for name in sorted(filenames):
            if not name.endswith(".py") or name.endswith("_meta.py") or name == "layout.py":
                continue
            src = os.path.relpath(os.path.join(dirpath, name), ROOT).replace(os.sep, "/")
            out.append((os.path.relpath(os.path.join(dirpath, name), FIRMWARE).replace(os.sep, "/"), src))
    return sorted(out)


def render():
    """The JSON, one file a line (diffs stay readable)."""
    urls = ",\n".join("  " + json.dumps(list(f)) for f in files())
    return '{\n "urls": [\n%s\n ],\n "version": %s\n}\n' % (urls, json.dumps(version()))


def main(argv):
    text = render()
    if "--check" in argv:
        with open(OUT, encoding="utf-8") as f:
            stale = f.read() != text
        if stale:
            print("package.json is stale: run make dialects (host_tools/mip_package.py)")
        return 1 if stale else 0
    with open(OUT, "w", encoding="utf-8") as f:
        f.write(text)
    print("wrote package.json (%d files)" % len(files()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
