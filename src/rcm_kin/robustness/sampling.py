"""The parameters the model is unsure of, their spreads, and parameter sets drawn from them.

Uncertain parameters of a drive parameter set (:class:`~rcm_kin.dynamics.drive.DriveParameters`),
each named by where it lives in the file:

- ``drive_train.<joint>.<name>``: every non-zero parameter of the terms an identified stick-slip
  drive train has on (:class:`~rcm_kin.dynamics.stick_slip.AxisFriction`,
  :func:`~rcm_kin.identification.drive_train.terms_of`), but for the model choices (the
  presliding spring's element count, :data:`~rcm_kin.dynamics.axis_friction.DISCRETE`), which
  stay as identified. The smooth model's constants of
  that joint (what the linearisation and the gain schedule use) follow the drawn drive train as
  ``identify`` derives them (:func:`rcm_kin.identification.identify.with_drive_trains`);
- ``<joint>.<name>``: the smooth model's non-zero ``extra_inertia``, ``viscous`` and ``coulomb``
  of a roll or pitch without a drive train, and the ``volts_per_pwm`` of the roll and pitch
  drivers. The insertion keeps its nominal constants (every controller holds it with the same
  firmware P loop);
- ``gravity_offsets.<link>[k]``: the non-zero components of the calibrated first moments.

Spreads (one standard deviation, the parameter's units): the identification's standard errors
where given (``rcm-kin identify --json``'s leave-one-out ``jackknife_standard_errors`` first, the
local Gauss-Newton ``standard_errors`` where there is no jackknife figure), else the default
relative spread :data:`DEFAULT_RELATIVE_SPREAD` of the parameter's kind. A parameter that is 0
stays 0 (there is no scale to take a relative spread of; give it a standard error to vary it).

Distributions: a positive parameter is log-normal with its nominal value as the median and
``sigma / nominal`` as the standard deviation of its logarithm (about ``sigma`` for spreads of a
few tens of per cent, and never of the wrong sign); a signed one (the presliding spring's slope,
the first moments) is normal.

A joint whose file carries leave-one-log-out fold sets (``[uncertainty.folds.<joint>]``, the sets
the prediction bands use, :mod:`rcm_kin.identification.file_bands`) draws its drive train as a
whole instead: ``drive_train.<joint>`` picks one of the fold sets or the file's own set, each as
likely (the value is the set's index: the folds in the file's order, then the own set), and each
parameter the logs do not determine (``[uncertainty.ranges.<joint>]``) is then drawn uniformly
over its range in that set (log-uniformly where the range spans a decade,
:data:`rcm_kin.identification.bands.DECADE`), named ``drive_train.<joint>.<name>``. The
per-parameter spreads of that joint's drive train (standard errors or default) are then NOT also
applied: the fold sets are that spread, measured. A fold set is drawn jackknife-inflated
(:func:`inflated`): each parameter's deviation from the folds' mean scaled by ``sqrt(n - 1)`` and
put on the own set's value (on the logarithm for a positive parameter), so the draws spread as the
jackknife standard errors (the folds, each fitted on all but one of ``n`` logs, spread
``sqrt(n - 1)`` times less than the estimate's error). Without fold sets the ranges are not used and the
draws are what they were before fold sets existed. The other parameters (``volts_per_pwm``, the
first moments, a joint without fold sets) keep their spreads.

Sample ``i`` of a run with seed ``s`` draws from ``numpy.random.SeedSequence(s).spawn(N)[i]``
alone (the spreads' standard normal deviates first, then one uniform deviate per set choice or
range), so a sample is the same whichever batch or worker computes it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rcm_kin.dynamics.axis_friction import DISCRETE
from rcm_kin.dynamics.drive import DriveParameters, with_joint
from rcm_kin.dynamics.stick_slip import TERM_PARAMETERS, TERMS
from rcm_kin.errors import RcmKinError, read_text, warn
from rcm_kin.identification.bands import DECADE
from rcm_kin.identification.drive_train import terms_of
from rcm_kin.identification.identify import with_drive_trains

# Default relative spread (1 sigma) per kind of parameter, where the identification gives none.
# Of the order the shipped parameter file's notes report for its own sets (the leave-one-log-out
# spread of the roll drive train, the calibration's error of volts_per_pwm and of the first
# moments), rounded up: robustness should be judged on a spread no smaller than the one measured.
DEFAULT_RELATIVE_SPREAD = {
    "drive_train": 0.25,       # identified stick-slip parameters
    "friction": 0.30,          # smooth friction/inertia of a joint not identified on logs (pitch)
    "volts_per_pwm": 0.15,     # effective driver gain from the holding calibration
    "gravity_offsets": 0.20,   # calibrated first moments
}
SMOOTH_FIELDS = ("extra_inertia", "viscous", "coulomb")
SIGNED = ("presliding_slope",)   # drive-train parameters that may take either sign
DRIVEN_AXES = ("roll", "pitch")
SPREAD, UNIFORM, LOG_UNIFORM, CHOICE = "spread", "uniform", "log-uniform", "one of the sets"   # Uncertain.kind


@dataclass(frozen=True)
class Uncertain:
    """One uncertain parameter: its name (where it lives), nominal value and 1-sigma spread in its
    own units, whether it is drawn log-normal (positive) or normal (signed), and where the spread
    came from. A parameter drawn uniformly (``kind`` :data:`UNIFORM` or :data:`LOG_UNIFORM`) has
    its range ``[low, high]`` instead of a spread (``sigma`` NaN); a choice of drive-train set
    (:data:`CHOICE`) is an index over ``[low, high]`` (0 to the number of sets less one), its
    nominal the file's own set."""

    name: str
    nominal: float
    sigma: float
    positive: bool
    source: str            # "jackknife", "gauss-newton", "default <kind> <fraction>", or the fold sets / range
    low: float = np.nan
    high: float = np.nan
    kind: str = SPREAD

    @property
    def distribution(self) -> str:
        """``log-normal`` or ``normal`` (a spread), ``uniform``, ``log-uniform`` or ``one of the sets``."""
        return ("log-normal" if self.positive else "normal") if self.kind == SPREAD else self.kind

    def from_unit(self, x: float) -> float:
        """The value of a uniformly drawn parameter at ``x`` in [0, 1) (a choice: the set's index)."""
        if self.kind == CHOICE:
            return float(min(int(x * (self.high + 1)), self.high))
        if self.kind == LOG_UNIFORM:
            return float(self.low * (self.high / self.low) ** x)
        return float(self.low + x * (self.high - self.low))

    def as_dict(self) -> dict:
        out = {"nominal": self.nominal, "sigma": None if np.isnan(self.sigma) else self.sigma,
               "distribution": self.distribution, "source": self.source}
        return out if self.kind == SPREAD else {**out, "range": [self.low, self.high]}


def read_standard_errors(path: str | Path) -> dict[str, tuple[float, str]]:
    """Standard errors from ``rcm-kin identify --json`` output: ``{"drive_train.<joint>.<name>":
    (sigma, "jackknife" | "gauss-newton")}``, the jackknife (leave-one-out) figure where there is a
    finite one."""
    try:
        raw = json.loads(read_text(Path(path), "standard errors file"))
    except OSError as exc:
        raise RcmKinError(f"cannot read the standard errors {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RcmKinError(f"{path} is not JSON (rcm-kin identify ... --json output): {exc.msg}") from None
    if not isinstance(raw, dict) or "standard_errors" not in raw:
        raise RcmKinError(f"{path} has no \"standard_errors\": give rcm-kin identify ... --json output")
    out: dict[str, tuple[float, str]] = {}
    for key, source in (("standard_errors", "gauss-newton"), ("jackknife_standard_errors", "jackknife")):
        tables = raw.get(key) or {}
        if not (isinstance(tables, dict) and all(isinstance(t, dict) for t in tables.values())):
            raise RcmKinError(f"{path}: \"{key}\" must map each joint to {{parameter: standard error}}")
        for joint, errors in tables.items():
            for name, sigma in errors.items():
                if isinstance(sigma, (int, float)) and np.isfinite(sigma) and sigma >= 0:
                    out[f"drive_train.{joint}.{name}"] = (float(sigma), source)
    return out


def fold_draws(params: DriveParameters, joint: str) -> list[Uncertain]:
    """How ``joint``'s drive train is drawn from the file's fold sets (see the module's notes): the
    set choice ``drive_train.<joint>``, then each parameter of ``[uncertainty.ranges.<joint>]``
    uniform (log-uniform over a decade or more) in its range, by name."""
    count = len(params.uncertainty.folds[joint])
    own = params.drive_train[joint]
    out = [Uncertain(f"drive_train.{joint}", float(count), np.nan, False,
                     f"fold sets ({count}, jackknife-inflated) and the own set", 0.0, float(count), CHOICE)]
    for name, (lo, hi) in sorted(params.uncertainty.ranges.get(joint, {}).items()):
        kind = LOG_UNIFORM if lo > 0 and hi / lo >= DECADE else UNIFORM
        out.append(Uncertain(f"drive_train.{joint}.{name}", float(getattr(own, name)), np.nan, lo > 0,
                             f"[uncertainty.ranges.{joint}]", float(lo), float(hi), kind))
    return out


def uncertain_parameters(params: DriveParameters,
                         standard_errors: dict[str, tuple[float, str]] | None = None) -> tuple[Uncertain, ...]:
    """The uncertain parameters of ``params`` (see the module's notes) with their spreads:
    ``standard_errors`` (:func:`read_standard_errors`) where they name the parameter, else the
    default relative spread of its kind; a joint with fold sets drawn from them (:func:`fold_draws`),
    any standard errors of its drive train left unused (with a warning)."""
    known = standard_errors or {}
    folded = [j for j in params.drive_train if params.uncertainty.folds.get(j)]
    if stray := [j for j in params.uncertainty.folds if params.uncertainty.folds[j] and j not in params.drive_train]:
        raise RcmKinError(f"{params.source or 'the drive parameters'} has fold sets of the {stray[0]} but no "
                          f"[drive_train.{stray[0]}]: the fold sets are drawn in place of a drive train",
                          parameter="params")
    if unused := sorted(n for n in known if n.partition(".")[2].partition(".")[0] in folded):
        warn(f"the standard errors of {', '.join(unused)} are not used: the drive trains of "
             f"{', '.join(folded)} are drawn from the file's fold sets")

    def entry(name: str, nominal: float, kind: str, positive: bool = True) -> Uncertain:
        if name in known:
            sigma, source = known[name]
        else:
            fraction = DEFAULT_RELATIVE_SPREAD[kind]
            sigma, source = fraction * abs(nominal), f"default {kind} {fraction:g}"
        return Uncertain(name, float(nominal), float(sigma), positive, source)

    out = []
    for joint, friction in params.drive_train.items():
        if joint in folded:
            out += fold_draws(params, joint)
            continue
        on = terms_of(friction)
        off = {name for term in TERMS if term not in on for name in TERM_PARAMETERS[term]} | set(DISCRETE)
        out += [entry(f"drive_train.{joint}.{name}", value, "drive_train", name not in SIGNED)
                for name, value in friction.as_dict().items() if value != 0 and name not in off]
    for joint in DRIVEN_AXES:
        if joint not in params.drive_train:
            out += [entry(f"{joint}.{name}", getattr(params[joint], name), "friction")
                    for name in SMOOTH_FIELDS if getattr(params[joint], name) != 0]
        out.append(entry(f"{joint}.volts_per_pwm", params[joint].volts_per_pwm, "volts_per_pwm"))
    for link, moment in params.gravity_offsets.items():
        out += [entry(f"gravity_offsets.{link}[{k}]", value, "gravity_offsets", positive=False)
                for k, value in enumerate(moment) if value != 0]
    return tuple(u for u in out if u.kind != SPREAD or u.sigma > 0)


def draw(uncertain: tuple[Uncertain, ...], seed: np.random.SeedSequence) -> np.ndarray:
    """One value per uncertain parameter, from the generator of ``seed`` alone: a standard normal
    deviate per spread (all of them first, as when there were only spreads), then a uniform one per
    range or set choice, each in the order of ``uncertain``."""
    rng = np.random.default_rng(seed)
    spread = np.array([u.kind == SPREAD for u in uncertain], dtype=bool)
    z = rng.standard_normal(int(spread.sum()))
    nominal = np.array([u.nominal for u in uncertain if u.kind == SPREAD])
    sigma = np.array([u.sigma for u in uncertain if u.kind == SPREAD])
    positive = np.array([u.positive for u in uncertain if u.kind == SPREAD], dtype=bool)
    values = nominal + sigma * z
    log_sd = sigma[positive] / nominal[positive]
    values[positive] = nominal[positive] * np.exp(log_sd * z[positive])
    if spread.all():
        return values
    out = np.empty(len(uncertain))
    out[spread] = values
    uniform = [u for u in uncertain if u.kind != SPREAD]
    out[~spread] = [u.from_unit(x) for u, x in zip(uniform, rng.random(len(uniform)))]
    return out


def sample_seeds(seed: int, samples: int) -> list[np.random.SeedSequence]:
    """The seed of each of ``samples`` samples: ``SeedSequence(seed).spawn(samples)``."""
    if samples < 1:
        raise RcmKinError(f"the number of samples must be at least 1, got {samples}")
    if seed < 0:
        raise RcmKinError(f"the seed is a non-negative integer, got {seed}")
    return np.random.SeedSequence(seed).spawn(samples)


def chosen_set(params: DriveParameters, joint: str, index: float):
    """``joint``'s drive train number ``index`` (:data:`CHOICE`): a fold set in the file's order, or
    (the last index) the file's own set."""
    folds = params.uncertainty.folds.get(joint, ())
    k = int(index)
    if not (k == index and 0 <= k <= len(folds)):
        raise RcmKinError(f"drive_train.{joint}: set {index!r} is not one of the {len(folds)} fold sets and the own "
                          "set", parameter="values")
    return inflated(folds, params.drive_train[joint], k) if k < len(folds) else params.drive_train[joint]


def inflated(folds, own, k: int):
    """Fold set ``k`` of ``folds`` (:class:`FoldSet`) jackknife-inflated about ``own`` (the file's set):
    per parameter ``own + sqrt(n - 1) (p_k - mean p)``, on the logarithm when every value is
    positive; model choices (:data:`DISCRETE`) and parameters equal in every set kept."""
    n, values = len(folds), {}
    for name, mine in own.as_dict().items():
        p = np.array([getattr(f.friction, name) for f in folds], dtype=float)
        if name in DISCRETE or np.all(p == p[0]) and p[0] == mine:
            continue
        scale = np.sqrt(max(n - 1, 1))
        if mine > 0 and np.all(p > 0):
            values[name] = float(mine * np.exp(scale * (np.log(p[k]) - np.mean(np.log(p)))))
        else:
            values[name] = float(mine + scale * (p[k] - p.mean()))
    return replace(own, **values)


def with_values(params: DriveParameters, uncertain: tuple[Uncertain, ...], values) -> DriveParameters:
    """``params`` with each uncertain parameter set to its value in ``values`` (same order); a
    joint's drive train first the chosen set where it is drawn from sets (:func:`chosen_set`), its
    ranges' values put in it; the smooth constants of a joint whose drive train is drawn derived
    from it as ``identify`` does."""
    frictions = {u.name.partition(".")[2]: chosen_set(params, u.name.partition(".")[2], value)
                 for u, value in zip(uncertain, values) if u.kind == CHOICE}
    offsets = {link: np.array(m, dtype=float) for link, m in params.gravity_offsets.items()}
    for u, value in zip(uncertain, values):
        head, _, rest = u.name.partition(".")
        if u.kind == CHOICE:
            continue
        if head == "drive_train":
            joint, name = rest.split(".")
            frictions[joint] = replace(frictions.get(joint, params.drive_train[joint]), **{name: float(value)})
        elif head == "gravity_offsets":
            link, k = rest[:-1].split("[")
            offsets[link][int(k)] = value
        else:
            params = with_joint(params, head, **{rest: float(value)})
    return with_drive_trains(replace(params, gravity_offsets=offsets), frictions)


def drive_train_sources(uncertain: tuple[Uncertain, ...]) -> dict[str, str]:
    """Per joint with a drawn drive train, where its draws come from: ``fold sets (N) and the own
    set`` (and the ranges drawn in them) or ``spreads (<their sources>)``."""
    sets, ranges, spreads = {}, {}, {}
    for u in uncertain:
        head, _, rest = u.name.partition(".")
        joint, _, name = rest.partition(".")
        if head != "drive_train":
            continue
        if u.kind == CHOICE:
            sets[joint] = u.source
        elif u.kind == SPREAD:
            spreads.setdefault(joint, set()).add(u.source)
        else:
            ranges.setdefault(joint, []).append(name)
    out = {j: source + (f"; uniform over [uncertainty.ranges]: {', '.join(ranges[j])}" if j in ranges else "")
           for j, source in sets.items()}
    return {**out, **{j: f"spreads ({', '.join(sorted(s))})" for j, s in spreads.items()}}
