"""``python -m lsys3d``: the command-line interface."""

from .cli import run

run()
