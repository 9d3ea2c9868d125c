"""``python -m wfbench.cli``: the ``wfbench`` command line."""

import sys

from wfbench.cli import main

sys.exit(main())
