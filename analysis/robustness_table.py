r"""The robustness table of the note: ``rcm-kin robustness --json`` output as a Markdown table.

    rcm-kin identify psm ../shared/data --out /tmp/identified.toml --cv --json > identify.json
    rcm-kin robustness psm --controller p --controller pid --controller lqr-fixed --controller scheduled \\
        --controller scheduled-friction --controller thesis --experiment sine --samples 100 --skip 0.5 \\
        --uncertainty identify.json --json > robustness.json
    python analysis/robustness_table.py robustness.json

Per controller and axis: the largest and the mean error over each run (deg, p5 / median / p95 /
worst over the samples), the fraction of samples whose command saturated, that diverged, and
the 400 Hz linear loop's spectral radius and least damping ratio (median / worst) with the
fraction of samples where it is unstable.
"""

from __future__ import annotations

import json
import sys


def spread(s: dict, digits: int = 2) -> str:
    return " / ".join("n/a" if s[k] is None else f"{s[k]:.{digits}f}" for k in ("p5", "median", "p95", "worst"))


def table(result: dict) -> str:
    lines = [f"{result['experiment']}, {result['samples']} samples (seed {result['seed']})", "",
             "| controller | axis | max error (deg) | mean error (deg) | saturated | diverged "
             "| 400 Hz radius median / worst"
             " | least damping median / worst | 400 Hz linearly unstable |", "|---|---|---|---|---|---|---|---|---|"]
    for name, c in result["controllers"].items():
        s = c["stability"]
        linear = (f"{s['firmware_spectral_radius']['median']:.4f} / {s['firmware_spectral_radius']['worst']:.4f} | "
                  f"{s['firmware_min_damping']['median']:.3f} / {s['firmware_min_damping']['worst']:.3f} | "
                  f"{s['firmware_unstable_fraction']:.0%}") if s else "n/a | n/a | n/a"
        for axis in ("roll", "pitch"):
            a = c[axis]
            lines.append(f"| {name} | {axis} | {spread(a['max_error_deg'])} | {spread(a['mean_error_deg'])} | "
                         f"{a['saturated_fraction']:.0%} | {c['unstable_fraction']:.0%} | {linear} |")
    return "\n".join(lines)


if __name__ == "__main__":
    with open(sys.argv[1]) as f:
        print(table(json.load(f)))
