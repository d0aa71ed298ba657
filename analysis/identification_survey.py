"""Transfer functions identified per pose from the measured logs, beside the physics model's
linearisation at the same pose, and the thesis's (0, 0) roll model reproduced.

    python analysis/identification_survey.py --data ../shared/data --out analysis/output
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.identification.pose_models import identify_folder, identify_log, pose_table_rows, write_pose_table
from rcm_kin.model import load_robot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="the shared data folder (psm-sysid/...)")
    parser.add_argument("--out", default="analysis/output", help="output folder")
    args = parser.parse_args()
    data, out = Path(args.data) / "psm-sysid", Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model = driven_dynamics(load_robot("psm"), coulomb=False)

    thesis = identify_log(data / "single-axis" / "roll_step.csv", "roll").fit
    print("thesis roll model (0,0): (4.0426 s - 8.3312)/(s^2 + 6.1202 s + 16.288), DC -0.5115 deg/PWM")
    print(f"  from roll_step.csv: num {thesis.num.round(4).tolist()}, den {thesis.den.round(4).tolist()}, "
          f"DC {thesis.dc_gain:.4f}, fit {thesis.fit_percent:.1f} %")
    for folder, joint, orders in (("roll-step", "roll", (2,)), ("pitch-prbs", "pitch", (3, 4))):
        for order in orders:
            models = identify_folder(data / folder, joint, model, order=order)
            path = write_pose_table(models, out / f"{joint}_order{order}_pose_models.csv")
            print(f"\n{joint}, {order} poles ({path}):")
            for r in pose_table_rows(models):
                print(f"  {r['file']:44} fit {r['fit_percent']:6.1f} %  DC {r['dc_gain']:+.3f} (physics "
                      f"{r['physics_dc_gain']:+.3f}) deg/PWM  poles {r['poles']}  (physics {r['physics_poles']})")


if __name__ == "__main__":
    main()
