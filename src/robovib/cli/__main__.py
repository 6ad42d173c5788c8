"""``python -m robovib.cli``."""

from . import main

main()
