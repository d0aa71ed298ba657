"""``python -m rcm_kin.cli``: the ``rcm-kin`` command."""

from rcm_kin.cli import run

run()
