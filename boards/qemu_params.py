"""The emulated boards' parameters, readable: the unix vehicle's table (unix_params.py),
with a uint32 BRD_SERIAL_NUM that can hold values of 2^30 and more. Not on the boards:
host_tools/paramgen.py compiles it into qemu_params_block.py (`make dialects`), the
block the boards freeze and read in place."""
from mavstack.services.params import UINT32
from unix_params import PARAMS as _UNIX

PARAMS = tuple(p for p in _UNIX if p[0] != "BRD_SERIAL_NUM") + (("BRD_SERIAL_NUM", UINT32, 0),)
