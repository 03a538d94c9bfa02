"""``python -m realistic``: the command-line interface."""

import sys

try:
    from realistic.cli import main
except KeyboardInterrupt:  # interrupted while starting up: nothing was begun
    print("realistic: interrupted while starting: nothing written", file=sys.stderr)
    raise SystemExit(130) from None

raise SystemExit(main())
