"""The unix vehicle with faults on demand (faults.py): tests/test_watchdog.py runs it
under host_tools/watchdog.py."""
from unix import *  # noqa: F401,F403
from unix import PARAMS as _PARAMS, application as _application
from faults import FAULT_PARAM, faulty

NAME = "faulty_unix"
PARAMS = _PARAMS + (FAULT_PARAM,)
application = faulty(_application)
