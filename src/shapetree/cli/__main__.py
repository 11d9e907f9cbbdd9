"""``python -m shapetree.cli``."""

import sys

from shapetree.cli import main

if __name__ == "__main__":
    sys.exit(main())
