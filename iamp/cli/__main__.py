"""``python -m iamp.cli`` runs the command line."""

import sys

from iamp.cli.main import main

sys.exit(main())
