"""Cost of ``rcm-kin predict --band`` beside the plain point prediction, per shared roll-step log, and
what the band scores there.

    python benchmarks/bench_prediction_band.py --params FOLDS.toml [--data DIR] [--level 0.9] [--repeats N]

``FOLDS.toml``: a drive file with ``[uncertainty.folds.roll]`` (``rcm-kin identify --cv`` writes them).
Per log: in-process best-of-N seconds of ``predict_file`` (one simulation) and ``predict_band`` (the
whole ensemble: sets x undetermined values x preloads, on threads), and the wall time of the two
commands as a user runs them (a fresh process: imports and numba's cache load included). Target
(issue): ``predict --band`` on a step log under ~2 s. The scores: coverage of the measured angle
from the sample before the step, the final angle inside, the band's width at the end over the
measured travel, and the median's fit, on the whole log (what ``predict`` simulates) and on the
identification's window (2.5 s from the sample before the step, where its left-out fits are taken).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from common import best_of  # noqa: E402

from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.stick_slip import axis_plant  # noqa: E402
from rcm_kin.identification.drive_train import axis_log, fit_percent, predict_log  # noqa: E402
from rcm_kin.identification.file_bands import drive_file_band, predict_band  # noqa: E402
from rcm_kin.identification.identify import base_model, predict_file  # noqa: E402
from rcm_kin.identification.log_catalog import catalog  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"     # ../shared/data, as the tests


def wall(argv: list[str]) -> float:
    """Seconds of one ``rcm-kin`` run in a fresh process."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rcm_kin.cli", *argv], check=True, capture_output=True)
    return time.perf_counter() - start


def scores(band) -> str:
    ratio = band.end_width_over_travel
    return (f"{band.coverage:5.0%} {'yes' if band.final_inside else 'NO ':>3} {ratio if ratio else float('nan'):5.2f}"
            f" {band.median_fit:6.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--params", required=True, help="drive file with [uncertainty.folds.roll]")
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--level", type=float, default=0.9)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    params = load_drive_parameters(args.params)
    entries = [e for e in catalog([args.data], ("roll",)) if e.kind == "step"]
    if not entries:
        print(f"no roll-step logs under {args.data}: nothing to time")
        return
    model = base_model(params)
    predict_band(params, entries[0].path, "roll", args.level)      # numba cache load, once
    print(f"{args.level:.0%} band, {params.source}: coverage / final inside / end width over travel / median fit %")
    print(f"{'log':44} {'whole log (predict)':>25}   {'2.5 s window':>25}  {'point fit':>9}  "
          f"{'predict':>8} {'--band':>8}  {'CLI':>6} {'--band':>6}")
    for entry in entries:
        path = entry.path
        log, predicted, check, band = predict_band(params, path, "roll", args.level)
        window = axis_log(path, "roll")
        plant = axis_plant(model, "roll", window.pose)
        step_band = drive_file_band(params, window, plant, args.level)
        point = fit_percent(window.measured, predict_log(params.drive_train["roll"], plant, window))
        plain = best_of(lambda: predict_file(params, path, "roll"), args.repeats)
        banded = best_of(lambda: predict_band(params, path, "roll", args.level), args.repeats)
        base = ["predict", "psm", str(path), "--joint", "roll", "--params", str(args.params)]
        cli, cli_band = wall(base), wall(base + ["--band", str(args.level)])
        print(f"{path.name:44} {scores(band):>25}   {scores(step_band):>25}  {point:9.1f}  {plain:7.2f}s {banded:7.2f}s"
              f"  {cli:5.2f}s {cli_band:5.2f}s" + ("  extrapolated" if band.extrapolated else ""))
    print(f"members per band: {band.members} ({', '.join(f'{n} {k}' for n, k in band.sources.items())}); "
          f"{os.cpu_count()} cores")


if __name__ == "__main__":
    main()
