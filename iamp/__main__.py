"""``python -m iamp`` runs the command line."""

import sys

from iamp.cli.main import main

sys.exit(main())
