"""``python -m pipeline`` runs the ``microtube`` command line."""

import sys

from .cli import main

sys.exit(main())
