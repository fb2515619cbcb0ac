"""``python -m cli``: the ``wncs`` command line."""

import sys

from cli.main import main

sys.exit(main())
