"""Which terms of the drive-train model earn their place: leave-one-log-out over the roll steps
with each term switched on and off, beside the two baselines of the identification issue.

    python analysis/drive_train_terms.py ../shared/data [--out drive_train_terms.csv]

Per variant: the in-sample fit (NRMSE %) on all steps, and per left-out log the cross-validated
fit and the final-travel error. Baselines on the same logs and windows: (a) the smooth model
with the parameters shipped before the identification, (b) the nearest-pose log's own 2nd-order
transfer function applied to the left-out log.
"""

from __future__ import annotations

import argparse
import csv
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.identification.drive_train import check_log, fit_friction, leave_one_out, predict_log, search_for  # noqa: E402
from rcm_kin.identification.identify import base_model, joint_records  # noqa: E402
from rcm_kin.identification.log_catalog import catalog  # noqa: E402
from rcm_kin.identification.transfer_function import fit_transfer_function, simulate_transfer_function  # noqa: E402

VARIANTS = [(), ("stiction",), ("presliding",), ("two_mass",), ("presliding", "stiction"),
            ("presliding", "two_mass")]


def nearest_pose_baseline(logs) -> list:
    """Baseline (b): each log predicted by the 2nd-order TF fitted on the nearest-pose other log."""
    fits = [fit_transfer_function(g.pwm - g.pwm[0], np.degrees(g.measured - g.measured[0]), g.period, 2)
            for g in logs]
    out = []
    for i, log in enumerate(logs):
        distance = [np.hypot(*np.subtract(o.operating_point, log.operating_point)) if j != i else np.inf
                    for j, o in enumerate(logs)]
        tf = fits[int(np.argmin(distance))]
        y = simulate_transfer_function(tf.num, tf.den, log.pwm - log.pwm[0], log.period)
        out.append(check_log(log.name, log.measured, log.measured[0] + np.radians(y), log.period))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data")
    parser.add_argument("--out", default="drive_train_terms.csv")
    args = parser.parse_args()
    model = base_model(load_drive_parameters())
    logs, plants = joint_records(catalog([args.data], ("roll",)), model, "roll")
    rows = [{"variant": "baseline (b): nearest-pose TF", "in_sample_mean": "",
             **{c.name: (c.fit_percent, c.travel_error) for c in nearest_pose_baseline(logs)}}]
    for terms in VARIANTS:
        search = search_for(terms)
        friction, _ = fit_friction(search, plants, logs, generations=100)
        in_sample = [check_log(g.name, g.measured, predict_log(friction, p, g), g.period).fit_percent
                     for g, p in zip(logs, plants)]
        cv, _ = leave_one_out(search, plants, logs)
        rows.append({"variant": "+".join(terms) or "viscous+coulomb", "in_sample_mean": float(np.mean(in_sample)),
                     **{c.name: (c.fit_percent, c.travel_error) for c in cv}})
        print(rows[-1]["variant"], f"in-sample {np.mean(in_sample):.1f}",
              f"CV mean {np.mean([c.fit_percent for c in cv]):.1f}",
              f"worst travel error {100 * max(c.travel_error for c in cv):.0f} %", flush=True)
    names = [g.name for g in logs]
    with open(args.out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["variant", "in_sample_mean_fit"] + [f"{n} cv_fit" for n in names]
                   + [f"{n} travel_err" for n in names])
        for r in rows:
            w.writerow([r["variant"], r["in_sample_mean"]] + [f"{r[n][0]:.1f}" for n in names]
                       + [f"{100 * r[n][1]:.0f}%" for n in names])


if __name__ == "__main__":
    main()
