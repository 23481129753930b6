"""docs/seed-coverage.md: generated (host_tools/seed_coverage.py), current, complete."""
import os
import sys

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "host_tools"))
import seed_coverage  # noqa: E402


def test_committed_table_is_current():
    text = seed_coverage.render()  # fails itself on a row "not handled" without a reason
    with open(seed_coverage.OUT, encoding="utf-8") as f:
        assert f.read() == text, "docs/seed-coverage.md is stale: run `make seed-coverage`"


def test_one_row_per_seed_message_and_command():
    msgs, cmds = seed_coverage.seed_names()
    assert (len(msgs), len(cmds)) == (84, 33)
    with open(seed_coverage.OUT, encoding="utf-8") as f:
        rows = [line for line in f if line.startswith("| ") and not line.startswith("| id")]
    assert len(rows) == 84 + 33
    assert not any("NOT HANDLED" in r for r in rows)
