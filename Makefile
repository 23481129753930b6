# mavstack: the on-vehicle MAVLink endpoint. `make run` flies the simulated vehicle,
# `make test` runs the whole suite; both set themselves up on first use.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
MICROPYTHON := $(VENV)/bin/micropython
STAMP := $(VENV)/.installed
ARGS ?=

.PHONY: setup test run bench dialects clean

setup: $(STAMP)

$(STAMP): requirements.txt requirements-nodeps.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps -r requirements-nodeps.txt
	touch $(STAMP)

test: setup
	$(PY) -m pytest -q tests

run: setup
	$(MICROPYTHON) firmware/main.py --board unix $(ARGS)

bench: setup
	$(PY) bench/run.py

dialects: setup
	$(PY) host_tools/mavgen.py --all

clean:
	rm -rf $(VENV) storage build bench/latest.json
