"""The MTM, the second real robot: what the operator holds (or a gravity-compensation motor must
supply) over its shoulder and elbow, the design of its shoulder counterweight, and its linear model
per pose. No drive is described for the MTM: its CAD (URDF) inertias, torque in N m."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.atomic import write_text
from rcm_kin.model import load_robot
from rcm_kin.report.render import Table, relative

SHOULDER, ELBOW = "j1", "j3"        # the MTM sidecar's shoulder pitch and elbow pitch (robot-parameters.md)
POLE_POSES_DEG = (-45.0, 0.0, 45.0)  # shoulder and elbow values of the linear models' table


@dataclass(frozen=True)
class MtmSection:
    template: ClassVar[str] = "mtm.html.j2"
    model: str                      # which model: "CAD (URDF inertias)"
    map_points: int
    figure: str                     # the heat maps (PNG)
    data: dict[str, str]            # file name -> path
    peak: Table                     # per joint: largest |torque| over the map, with and without the counterweight
    counterweight: Table
    counterweight_link: str
    mount: str
    linear: Table
    linear_data: str                # JSON of the linear models


def _poles(A: np.ndarray, tiny: float = 1e-6) -> str:
    """The eigenvalues of ``A`` (1/s), parts below ``tiny`` shown as 0 (an undamped model's rounding)."""
    poles = [complex(0.0 if abs(p.real) < tiny else p.real, 0.0 if abs(p.imag) < tiny else p.imag)
             for p in np.linalg.eigvals(A)]
    return " ".join(f"{p.real:+.3g}{p.imag:+.3g}j" if p.imag else f"{p.real:+.3g}"
                    for p in sorted(poles, key=lambda p: (p.real, p.imag)))


def mtm_section(out: Path, map_points: int = 61) -> MtmSection:
    """The MTM's shoulder x elbow torque map (``map_points`` per axis over the joints' limits) with and
    without its counterweight, the counterweight placed by least squares, and linear models."""
    from rcm_kin.control.linearization import linearize
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.statics.counterweights import place_counterweight
    from rcm_kin.statics.holding import torque_map, write_torque_map

    mtm = load_robot("mtm")
    k = [mtm.actuated.index(j) for j in (SHOULDER, ELBOW)]
    grid = {j: np.linspace(mtm.lower[i], mtm.upper[i], map_points) for j, i in zip((SHOULDER, ELBOW), k)}
    folder = out / "mtm"
    folder.mkdir(exist_ok=True)
    tmap = torque_map(mtm, grid)
    files = write_torque_map(tmap, folder)
    bare = torque_map(mtm, grid, counterweights=False)
    peak = Table.of([[j, f"{np.abs(tmap.tau[..., i]).max():.4f}", f"{np.abs(bare.tau[..., i]).max():.4f}"]
                     for j, i in zip((SHOULDER, ELBOW), k)],
                    ["joint", "peak |torque| as built (N m)", "without the counterweight (N m)"])
    link = mtm.description.counterweights[0]
    design = place_counterweight(mtm, link, {j: v[::max(1, map_points // 13)] for j, v in grid.items()})
    rows = [[j, f"{design.rms_without[n]:.4f}", f"{design.rms_as_built[n]:.4f}", f"{design.rms[n]:.4f}"]
            for n, j in enumerate(design.joints) if j in (SHOULDER, ELBOW)]
    counterweight = Table.of(rows, ["joint", "RMS without (N m)", "as built", "designed"])
    model = driven_dynamics(mtm, joints=(SHOULDER, ELBOW))
    models, linear_rows = [], []
    for a in POLE_POSES_DEG:
        for b in POLE_POSES_DEG:
            lin = linearize(model, np.radians([a, b]))
            models.append({f"{SHOULDER}_deg": a, f"{ELBOW}_deg": b, "A": lin.A.tolist(), "B": lin.B.tolist(),
                           "u_hold_N_m": lin.u0.tolist()})
            linear_rows.append([f"{a:g}", f"{b:g}", f"{lin.u0[0]:+.4f}", f"{lin.u0[1]:+.4f}", _poles(lin.A)])
    write_text(folder / "linear_models.json", json.dumps(models, indent=1))
    paths = {f.name: relative(f, out) for f in files}
    return MtmSection(
        model=tmap.model, map_points=map_points, figure=paths["torque_map.png"],
        data={name: p for name, p in paths.items() if not name.endswith(".png")}, peak=peak,
        counterweight=counterweight, counterweight_link=f"{link}, {design.mass:.3f} kg", mount=design.mount,
        linear=Table.of(linear_rows, [f"{SHOULDER} (deg)", f"{ELBOW} (deg)", f"holding {SHOULDER} (N m)",
                                      f"holding {ELBOW} (N m)", "poles of A (1/s)"]),
        linear_data=relative(folder / "linear_models.json", out))
