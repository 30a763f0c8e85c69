"""``python -m atemr`` is the ``atemr`` command."""

import sys

from atemr.cli.main import main

sys.exit(main())
