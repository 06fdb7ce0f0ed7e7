"""``python -m geosyn``: the geosyn command line."""

import sys

from geosyn.experiments.cli import main

if __name__ == "__main__":
    sys.exit(main())
