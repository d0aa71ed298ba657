"""Which terms of the drive-train model earn their place: leave-one-log-out over the roll steps
with each term switched on and off, beside the two baselines of the identification issue.

    python analysis/drive_train_terms.py ../shared/data [--out drive_train_terms.csv]
        [--variants presliding+two_mass,viscous+presliding:2]   (terms joined by +, :N elements)

Per variant: the in-sample fit (NRMSE %) on all steps, and per left-out log the cross-validated
fit and the final-travel error (the means over the six roll-step logs; every shared roll log is
fitted), every fit (and fold) under the roll's P-sinusoid speed bound as ``rcm-kin identify``
fits it (:mod:`rcm_kin.identification.speed_bounds`), the folds on two processes. The choice:
the best mean left-out fit, a variant within 1 point of it with fewer free parameters preferred.
Baseline on the same logs and windows: the nearest-pose log's own 2nd-order transfer function
applied to the left-out log.
"""

from __future__ import annotations

import argparse
import csv
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.identification.cross_validation import fit_with_cv  # noqa: E402
from rcm_kin.identification.drive_train import check_log, predict_log, search_for  # noqa: E402
from rcm_kin.identification.identify import GENERATIONS, base_model, joint_records  # noqa: E402
from rcm_kin.identification.log_catalog import catalog  # noqa: E402
from rcm_kin.identification.speed_bounds import speed_bounds  # noqa: E402
from rcm_kin.identification.transfer_function import fit_transfer_function, simulate_transfer_function  # noqa: E402

VARIANTS = [("viscous",), (), ("viscous", "presliding"), ("presliding",), ("viscous", "presliding", "stiction"),
            ("presliding", "stiction"), ("viscous", "presliding", "two_mass"), ("presliding", "two_mass")]
TIE = 1.0     # points of mean left-out fit within which the variant with fewer free parameters is chosen


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
    parser.add_argument("--variants", help="comma-separated variants, terms joined by +, ':N' for N Maxwell-slip "
                                           "elements (default: every variant of VARIANTS, 1 element)")
    args = parser.parse_args()
    variants = [(tuple(t for t in v.split(":")[0].split("+") if t), float(v.split(":")[1]) if ":" in v else 1.0)
                for v in args.variants.split(",")] if args.variants else [(t, 1.0) for t in VARIANTS]
    params = load_drive_parameters()
    model = base_model(params)
    logs, plants = joint_records(catalog([args.data], ("roll",)), model, "roll")
    bounds = speed_bounds(model, params, "roll")
    rows = [{"variant": "baseline (b): nearest-pose TF", "in_sample_mean": "", "cv_mean": "", "free": "",
             **{c.name: (c.fit_percent, c.travel_error) for c in nearest_pose_baseline(logs)}}]
    for terms, elements in variants:
        search = search_for(terms, elements)
        result = fit_with_cv(search, plants, logs, generations=GENERATIONS, speed_bounds=bounds, cv=True)
        in_sample = [check_log(g.name, g.measured, predict_log(result.friction, p, g), g.period).fit_percent
                     for g, p in zip(logs, plants)]
        cv = [c for c in result.checks if c.name.startswith("roll_step_response")] or list(result.checks)
        rows.append({"variant": ("+".join(terms) or "coulomb (flat)") + (f":{elements:g}" if elements != 1 else ""),
                     "in_sample_mean": float(np.mean(in_sample)),
                     "cv_mean": float(np.mean([c.fit_percent for c in cv])), "free": len(search.free),
                     **{c.name: (c.fit_percent, c.travel_error) for c in result.checks}})
        print(rows[-1]["variant"], f"free {len(search.free)}", f"in-sample {np.mean(in_sample):.1f}",
              f"CV mean {rows[-1]['cv_mean']:.1f}", f"worst travel error {100 * max(c.travel_error for c in cv):.0f} %",
              f"bound {bounds[0].value(result.friction):.3g} / {bounds[0].max_force:.3g} N m", flush=True)
    best = max(r["cv_mean"] for r in rows[1:])
    chosen = min((r for r in rows[1:] if r["cv_mean"] >= best - TIE), key=lambda r: (r["free"], -r["cv_mean"]))
    print(f"chosen: {chosen['variant']} (mean left-out fit {chosen['cv_mean']:.1f} %, best {best:.1f} %)")
    names = [g.name for g in logs]
    with open(args.out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["variant", "free", "in_sample_mean_fit", "cv_mean_fit"] + [f"{n} cv_fit" for n in names]
                   + [f"{n} travel_err" for n in names])
        for r in rows:
            w.writerow([r["variant"], r["free"], r["in_sample_mean"], r["cv_mean"]] + [f"{r[n][0]:.1f}" for n in names]
                       + [f"{100 * r[n][1]:.0f}%" for n in names])


if __name__ == "__main__":
    main()
