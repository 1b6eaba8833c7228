"""``python -m lsys3d``: the command-line interface."""

from .cli import main

raise SystemExit(main())
