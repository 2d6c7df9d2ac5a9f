"""``python -m holoview`` is the ``holoview`` command."""

import sys

from holoview.cli import main

sys.exit(main())
