"""The cost of owned, atomic outputs and of the compiled cache's verification, beside plain writes.

Each command runs in this process through ``rcm_kin.cli.main``, alternately as shipped and with the
safeguards switched off by patching (what the code did before them): files written in place (no
temporary, no fsync, no rename), no claim on the output folder (no lock, no manifest), and cached
libraries loaded without their SHA-256 check. Best of ``--repeats`` for each, same run.

- ``torque-map psm`` at 1001 x 1001 poses, CSV, no figures (the 1,002,002-line table of the issue);
- the warm ``report`` (its caches filled by a first run that is not timed).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_atomic.py [--repeats 3] [--no-report]``.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path
from unittest import mock

sys.path.insert(0, str(Path(__file__).parent))
import common  # noqa: E402,F401  (OPENBLAS_NUM_THREADS=1)

import rcm_kin.atomic as atomic  # noqa: E402
import rcm_kin.cli.outputs as cli_outputs  # noqa: E402
import rcm_kin.symbolic.compiled as compiled  # noqa: E402
from rcm_kin.cli import main  # noqa: E402


@contextlib.contextmanager
def plain_writes():
    """Writes in place, no claim, no checksum check: the code before the safeguards."""
    with mock.patch.object(atomic, "_reserve", lambda final: final), \
            mock.patch.object(atomic, "_sync", lambda temporary: None), \
            mock.patch.object(atomic, "_commit", lambda temporary, final: None), \
            mock.patch.object(cli_outputs, "_own", lambda path, folder, force: None), \
            mock.patch.object(compiled, "library_mismatch", lambda library, key: None):
        yield


def timed(argv: list[str]) -> float:
    start = time.perf_counter()
    status = main(argv)
    seconds = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"rcm-kin {' '.join(argv)} failed with status {status}")
    return seconds


def compare(name: str, argv: list[str], repeats: int) -> None:
    timed(argv)                                      # warm: caches filled, imports done
    shipped, plain = [], []
    for _ in range(repeats):                         # alternated: drifts in the machine's load hit both
        shipped.append(timed(argv))
        with plain_writes():
            plain.append(timed(argv))
    a, b = min(shipped), min(plain)
    print(f"{name:34s} shipped {a:7.3f} s   plain writes {b:7.3f} s   cost {100 * (a / b - 1):+6.1f} %")


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-report", action="store_true", help="skip the warm report (about a minute)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        maps = Path(tmp) / "maps"
        compare("torque-map psm 1001 x 1001 (CSV)", ["torque-map", "psm", "--roll=-30:30:1001", "--pitch=-30:30:1001",
                                                     "--out", str(maps), "--no-figures", "--force"], args.repeats)
        if not args.no_report:
            compare("report (warm)", ["report", "--out", str(Path(tmp) / "report"), "--force"], args.repeats)


if __name__ == "__main__":
    main_bench()
