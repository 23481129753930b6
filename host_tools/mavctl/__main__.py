"""`python -m mavctl ...` (host_tools on the path): the same as the installed `mavctl`."""
import sys

from mavctl.cli import main

if __name__ == "__main__":
    sys.exit(main())
