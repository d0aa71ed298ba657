"""What a robustness run or a design sweep would cost, checked before any cluster starts.

A run's references are built here, in the calling process, so a duration the simulator refuses
(:data:`rcm_kin.simulation.references.MAX_SAMPLES` controller periods per run) is refused before
the cluster starts, with the simulator's own message; and the total work is bounded:

- robustness: samples x controllers x controller periods of the experiment <= :data:`MAX_PERIODS`;
- weights sweep: error budgets x PWM budgets x controller periods of the sinusoid <= :data:`MAX_PERIODS`;
- counterweights sweep: main masses x DPM masses x points^2 workspace poses <= :data:`MAX_POSES`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rcm_kin.errors import RcmKinError, WorkLimitError
from rcm_kin.simulation.experiments import experiment_reference
from rcm_kin.simulation.firmware import FirmwareSettings

if TYPE_CHECKING:
    from rcm_kin.robustness.task import Study

# controller periods simulated in all: a sample's run goes at about 1.5e4 periods per second per
# core (measured, sine, P controller), so this is about a core-day
MAX_PERIODS = 1_000_000_000
MAX_POSES = 10_000_000          # counterweight-sweep poses in all (each a holding-PWM evaluation)


def controller_periods(experiment: str, duration: float | None) -> int:
    """Controller periods of one run of ``experiment`` (``duration`` s, None: its default) at the
    firmware rate; refuses what the simulator refuses."""
    return experiment_reference(experiment, FirmwareSettings().period, duration).time.size


def check_periods(total: int, what: str, fewer: str, parameter: str | tuple[str, ...] | None = None) -> None:
    """Refuse ``total`` controller periods above :data:`MAX_PERIODS` (``fewer`` says what to ask
    for instead, naming ``parameter``)."""
    if total > MAX_PERIODS:
        raise WorkLimitError(f"{what} is {total:,} controller periods to simulate; the limit is {MAX_PERIODS:,}: "
                             f"{fewer}", requested=total, limit=MAX_PERIODS, parameter=parameter)


def check_robustness(study: Study, samples: int) -> None:
    """Refuse a robustness run over the simulator's per-run limit or :data:`MAX_PERIODS` in all,
    or whose statistics would start (``study.skip``) after its run ends."""
    reference = experiment_reference(study.experiment, FirmwareSettings().period, study.duration)
    if study.skip >= reference.time[-1]:
        raise RcmKinError(f"the statistics start within the run: 0 <= skip < duration, got skip {study.skip} s and "
                          f"duration {reference.time[-1]:g} s")
    periods, controllers = reference.time.size, len(study.controllers)
    check_periods(samples * controllers * periods, f"{samples:,} samples x {controllers} controllers x {periods:,} "
                  "periods", "fewer samples or controllers, or a shorter `duration`", "duration")


def check_weights_sweep(error_budgets: int, pwm_budgets: int, duration: float | None) -> None:
    """Refuse a weights sweep over the simulator's per-run limit or :data:`MAX_PERIODS` in all."""
    periods = controller_periods("sine", duration)
    check_periods(error_budgets * pwm_budgets * periods, f"{error_budgets} x {pwm_budgets} budgets x {periods:,} "
                  "periods", "fewer budgets or a shorter `duration`", "duration")


def check_counterweight_sweep(main_masses: int, dpm_masses: int, points: int) -> None:
    """Refuse a counterweight sweep of more than :data:`MAX_POSES` poses in all."""
    poses = main_masses * dpm_masses * points**2
    if poses > MAX_POSES:
        raise WorkLimitError(f"{main_masses} x {dpm_masses} masses x {points}^2 points is {poses:,} poses; the limit "
                             f"is {MAX_POSES:,}: fewer masses or `points`", requested=poses, limit=MAX_POSES,
                             parameter="points")
