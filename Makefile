# mavstack: the on-vehicle MAVLink endpoint. `make run` flies the simulated vehicle,
# `make test` runs the whole suite; both set themselves up on first use.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
MICROPYTHON := $(VENV)/bin/micropython
STAMP := $(VENV)/.installed
ARGS ?=

# The MCU stage's Debian packages (mcu/firmware.py builds MicroPython's qemu port with
# them; tests/test_mcu*.py run it): pinned to the versions it was proven with.
MCU_DEBS := gcc-arm-none-eabi=15:12.2.rel1-1 libnewlib-arm-none-eabi=3.3.0-1.3+deb12u1 \
	qemu-system-arm=1:7.2+dfsg-7+deb12u18+b3
MCU_TOOLS_OK = command -v qemu-system-arm >/dev/null && command -v arm-none-eabi-gcc >/dev/null \
	&& test -d /usr/lib/arm-none-eabi/newlib

.PHONY: setup test run bench dialects clean mcu-deps mcu-tools mcu-test mcu-firmware fuzz soak seed-coverage

setup: $(STAMP)

# The last step installs host_tools as an editable package: the `mavctl` command in .venv/bin.
$(STAMP): requirements.txt requirements-nodeps.txt host_tools/pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps -r requirements-nodeps.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e host_tools
	touch $(STAMP)

# Two workers, each taking whole files (a file's vehicles and emulated boards stay
# together): most of a test's time is spent waiting on a vehicle, not computing.
test: setup mcu-tools
	$(PY) -m pytest -q -n 2 --dist loadfile tests

# Install the MCU stage's tools where that can be done (root, apt-get); elsewhere say
# loudly that the stage will be skipped (under CI=true its tests fail instead).
mcu-tools:
	@if $(MCU_TOOLS_OK); then exit 0; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then $(MAKE) --no-print-directory mcu-deps; \
	else echo "*** MCU stage SKIPPED: qemu-system-arm / gcc-arm-none-eabi missing and no root apt-get to install them (make mcu-deps) ***"; fi

mcu-deps:
	apt-get update -q >/dev/null
	apt-get install -y -q --no-install-recommends $(MCU_DEBS) >/dev/null \
	  || { echo "mcu-deps: pinned versions unavailable, installing the suite's current ones"; \
	       apt-get install -y -q --no-install-recommends $(foreach d,$(MCU_DEBS),$(firstword $(subst =, ,$(d)))) >/dev/null; }

mcu-firmware: setup mcu-tools
	$(PY) mcu/firmware.py build

mcu-test: setup mcu-tools
	$(PY) -m pytest -q tests/test_mcu.py tests/test_mcu_vehicle.py tests/test_mcu_peripheral.py tests/test_e2e_links.py tests/test_flash_mcu.py

# The fuzzer for SECONDS: the unix port's vehicles (both dialects) over UDP, growing the
# corpus in tests/fuzz/corpus/ (tests/fuzz/engine.py); a one-minute run is part of `make test`.
SECONDS ?= 600
fuzz: setup
	$(PY) tests/fuzz/engine.py --seconds $(SECONDS)

# The unix vehicle with two ground stations at full link rate and a flood, heap locked,
# for MINUTES; a two-minute soak is part of `make test`.
MINUTES ?= 10
soak: setup
	SOAK_MINUTES=$(MINUTES) $(PY) -m pytest -q -s tests/test_soak.py

run: setup
	$(MICROPYTHON) firmware/main.py --board unix $(ARGS)

bench: setup
	$(PY) bench/run.py

# Everything generated and committed (a test fails when one is stale): the dialect modules,
# the boards' parameter blocks, docs/seed-coverage.md and package.json (what `mpremote mip
# install` takes).
dialects: setup
	$(PY) host_tools/mavgen.py --all
	$(PY) host_tools/paramgen.py
	$(PY) host_tools/seed_coverage.py
	$(PY) host_tools/mip_package.py

seed-coverage: setup
	$(PY) host_tools/seed_coverage.py

clean:
	rm -rf $(VENV) storage build bench/latest.json
