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
the first moments) is normal. Sample ``i`` of a run with seed ``s`` draws from
``numpy.random.SeedSequence(s).spawn(N)[i]`` alone, so a sample is the same whichever batch or
worker computes it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rcm_kin.dynamics.axis_friction import DISCRETE
from rcm_kin.dynamics.drive import DriveParameters, with_joint
from rcm_kin.dynamics.stick_slip import TERM_PARAMETERS, TERMS
from rcm_kin.errors import RcmKinError
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


@dataclass(frozen=True)
class Uncertain:
    """One uncertain parameter: its name (where it lives), nominal value and 1-sigma spread in its
    own units, whether it is drawn log-normal (positive) or normal (signed), and where the spread
    came from."""

    name: str
    nominal: float
    sigma: float
    positive: bool
    source: str            # "jackknife", "gauss-newton" or "default <kind> <fraction>"

    def as_dict(self) -> dict:
        return {"nominal": self.nominal, "sigma": self.sigma,
                "distribution": "log-normal" if self.positive else "normal", "source": self.source}


def read_standard_errors(path: str | Path) -> dict[str, tuple[float, str]]:
    """Standard errors from ``rcm-kin identify --json`` output: ``{"drive_train.<joint>.<name>":
    (sigma, "jackknife" | "gauss-newton")}``, the jackknife (leave-one-out) figure where there is a
    finite one."""
    try:
        raw = json.loads(Path(path).read_text())
    except OSError as exc:
        raise RcmKinError(f"cannot read the standard errors {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
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


def uncertain_parameters(params: DriveParameters,
                         standard_errors: dict[str, tuple[float, str]] | None = None) -> tuple[Uncertain, ...]:
    """The uncertain parameters of ``params`` (see the module's notes) with their spreads:
    ``standard_errors`` (:func:`read_standard_errors`) where they name the parameter, else the
    default relative spread of its kind."""
    known = standard_errors or {}

    def entry(name: str, nominal: float, kind: str, positive: bool = True) -> Uncertain:
        if name in known:
            sigma, source = known[name]
        else:
            fraction = DEFAULT_RELATIVE_SPREAD[kind]
            sigma, source = fraction * abs(nominal), f"default {kind} {fraction:g}"
        return Uncertain(name, float(nominal), float(sigma), positive, source)

    out = []
    for joint, friction in params.drive_train.items():
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
    return tuple(u for u in out if u.sigma > 0)


def draw(uncertain: tuple[Uncertain, ...], seed: np.random.SeedSequence) -> np.ndarray:
    """One value per uncertain parameter, from the generator of ``seed`` alone."""
    z = np.random.default_rng(seed).standard_normal(len(uncertain))
    nominal = np.array([u.nominal for u in uncertain])
    sigma = np.array([u.sigma for u in uncertain])
    positive = np.array([u.positive for u in uncertain], dtype=bool)
    out = nominal + sigma * z
    log_sd = sigma[positive] / nominal[positive]
    out[positive] = nominal[positive] * np.exp(log_sd * z[positive])
    return out


def sample_seeds(seed: int, samples: int) -> list[np.random.SeedSequence]:
    """The seed of each of ``samples`` samples: ``SeedSequence(seed).spawn(samples)``."""
    if samples < 1:
        raise RcmKinError(f"the number of samples must be at least 1, got {samples}")
    if seed < 0:
        raise RcmKinError(f"the seed is a non-negative integer, got {seed}")
    return np.random.SeedSequence(seed).spawn(samples)


def with_values(params: DriveParameters, uncertain: tuple[Uncertain, ...], values) -> DriveParameters:
    """``params`` with each uncertain parameter set to its value in ``values`` (same order); the
    smooth constants of a joint whose drive train is drawn derived from it as ``identify`` does."""
    frictions = {}
    offsets = {link: np.array(m, dtype=float) for link, m in params.gravity_offsets.items()}
    for u, value in zip(uncertain, values):
        head, _, rest = u.name.partition(".")
        if head == "drive_train":
            joint, name = rest.split(".")
            frictions[joint] = replace(frictions.get(joint, params.drive_train[joint]), **{name: float(value)})
        elif head == "gravity_offsets":
            link, k = rest[:-1].split("[")
            offsets[link][int(k)] = value
        else:
            params = with_joint(params, head, **{rest: float(value)})
    return with_drive_trains(replace(params, gravity_offsets=offsets), frictions)
