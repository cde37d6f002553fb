"""``python -m sim4endor`` runs the command line."""

import sys

from sim4endor.cli import main

sys.exit(main())
