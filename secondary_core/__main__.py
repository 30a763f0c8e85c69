"""``python -m secondary_core``: the same as the ``atemr-secondary`` console script."""

import sys

from secondary_core.cli import main

sys.exit(main())
