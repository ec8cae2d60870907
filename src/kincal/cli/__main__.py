"""``python -m kincal.cli``."""
import sys

from . import main

sys.exit(main())
