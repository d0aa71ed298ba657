"""``python -m rcm_kin.cli``: the ``rcm-kin`` command."""

import sys

from rcm_kin.cli import main

sys.exit(main())
