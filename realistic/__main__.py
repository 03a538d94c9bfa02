"""``python -m realistic``: the command-line interface."""

from realistic.cli import main

raise SystemExit(main())
