"""``python -m scratch_iridescence.mitsuba_bridge``: the command line (:mod:`.cli`)."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
