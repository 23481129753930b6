"""The emulated M3 with faults on demand (faults.py), frozen as `board` into the
firmware of tests/test_mcu_watchdog.py (faults_manifest.py), so that the vehicle its
watchdog restarts has them too. Its clean minute is 5 s, for the test."""
from qemu_m3 import *  # noqa: F401,F403
from qemu_m3 import application as _application
from qemu_params import PARAMS as _PARAMS  # the rows the profile freezes as a block
from faults import FAULT_PARAM, faulty

NAME = "qemu_m3"  # (mavctl and the tests know the board by it)
PARAMS = _PARAMS + (FAULT_PARAM,)
CLEAN_RUN_MS = 5000
application = faulty(_application)
