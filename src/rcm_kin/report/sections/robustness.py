"""Robustness of the controllers to what the model does not know: a small Monte Carlo over the
parameter uncertainty (:mod:`rcm_kin.robustness`) on the sinusoid (in the report's own process
pool; ``rcm-kin robustness`` runs more samples on Dask)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from rcm_kin.errors import output_folder
from rcm_kin.report.render import Table, relative

CONTROLLERS = ("p", "scheduled", "scheduled-friction", "thesis")
SAMPLES = 8                 # small, so the report stays quick; `rcm-kin robustness` for more
SEED = 0
SETTLED_FROM = 0.5          # s: the sinusoid starts at full speed


@dataclass(frozen=True)
class RobustnessSection:
    template: ClassVar[str] = "robustness.html.j2"
    table: Table
    uncertainty: Table
    figure: str
    samples: int
    seed: int
    settled_from_s: float
    controllers: tuple[str, ...]


def _f(value: float, digits: int = 2) -> str:
    return "n/a" if value != value else f"{value:.{digits}f}"


def robustness_section(out: Path, samples: int = SAMPLES, duration: float | None = None,
                       controllers=CONTROLLERS, client=None) -> RobustnessSection:
    """``samples`` draws of the default parameter uncertainty, each controller of ``controllers``
    on the sinusoid (``duration`` s, default the experiment's) with the gain schedule of the
    nominal set; a table of the distributions and their empirical CDFs in ``out/robustness``.
    ``client``: a ``distributed.Client`` to run on (default: none, the samples run in this process,
    which is one of the report's pool workers; the result is the same either way)."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.robustness.execution import run_in_process, run_robustness
    from rcm_kin.robustness.figures import robustness_figure
    from rcm_kin.robustness.sampling import SPREAD, uncertain_parameters
    from rcm_kin.robustness.task import Study

    params = load_drive_parameters()
    study = Study(params, uncertain_parameters(params), tuple(controllers), "sine", duration, SETTLED_FROM)
    result = (run_in_process(study, samples, SEED) if client is None
              else run_robustness(study, samples, SEED, client, progress=False))
    folder = output_folder(out / "robustness")
    figure = robustness_figure(result, folder / "robustness_sine.png")
    rows = []
    for name, c in result.controllers.items():
        for axis, a in c.axes.items():
            m = a.max_error_deg
            rows.append([name, axis, " / ".join(_f(v) for v in (m.p5, m.median, m.p95, m.worst)),
                         _f(a.mean_error_deg.median), f"{a.saturated_fraction:.0%}", f"{c.unstable_fraction:.0%}",
                         (f"{_f(c.firmware_spectral_radius.median, 4)} / {_f(c.firmware_spectral_radius.worst, 4)}"
                          if c.has_margin else "n/a"),
                         f"{c.firmware_unstable_fraction:.0%}" if c.has_margin else "n/a"])
    header = ["controller", "axis", "max error p5 / median / p95 / worst (deg)", "mean error median (deg)",
              "saturated", "unstable", "400 Hz radius median / worst", "400 Hz linearly unstable"]
    uncertainty = Table.of([[u.name, f"{u.nominal:.4g}"] + ([f"{u.sigma:.3g}", f"{u.sigma / abs(u.nominal):.0%}"]
                            if u.kind == SPREAD else [f"[{u.low:.4g}, {u.high:.4g}]", "n/a"])
                            + [u.distribution, u.source] for u in result.uncertain],
                           ["parameter", "nominal", "sigma", "relative", "distribution", "spread from"])
    return RobustnessSection(Table.of(rows, header), uncertainty, relative(figure, out), result.samples, SEED,
                             SETTLED_FROM, tuple(controllers))
