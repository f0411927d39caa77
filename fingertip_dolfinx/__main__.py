"""`python -m fingertip_dolfinx ...`: the `fingertip` command."""

import sys

from .cli import main

sys.exit(main())
