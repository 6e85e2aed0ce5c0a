"""``python -m camvlp``: the command line."""

from .cli import main

main()
