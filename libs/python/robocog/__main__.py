"""`python -m robocog run MODULE[:CLASS] [FLAGS...]`: run a Python component, as the launcher does
for a manifest entry `python = "MODULE[:CLASS]"`. Without CLASS, the module's one
`robocog.component.Component` subclass."""

import sys

from .component import run_named

if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[1] != "run":
        print(__doc__.strip(), file=sys.stderr)
        sys.exit(64)
    sys.exit(run_named(sys.argv[2], sys.argv[3:]))
