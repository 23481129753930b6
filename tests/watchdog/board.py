"""The emulated M3 with faults on demand (faults.py), frozen as `board` into the
firmware of tests/test_mcu_watchdog.py (faults_manifest.py), so that the vehicle its
watchdog restarts has them too. Its clean minute is 5 s, for the test."""
from qemu_m3 import *  # noqa: F401,F403
from qemu_m3 import application as _application
from faulty_params_block import PARAMS  # noqa: F811 (the profile's and APP_FAULT, a block)
from faults import faulty

NAME = "qemu_m3"  # (mavctl and the tests know the board by it)
CLEAN_RUN_MS = 5000
application = faulty(_application)
