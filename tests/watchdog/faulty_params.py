"""The faulty M3's parameters, readable: the emulated boards' (boards/qemu_params.py) and
APP_FAULT (faults.py). host_tools/paramgen.py compiles them into faulty_params_block.py
(`make dialects`), the block board.py freezes and reads in place, as the boards do."""
from qemu_params import PARAMS as _QEMU
from faults import FAULT_PARAM

PARAMS = _QEMU + (FAULT_PARAM,)
