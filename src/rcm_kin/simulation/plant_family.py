"""The PSM plant for many parameter sets from one compiled library: no compiler run per set.

:func:`psm_plant` builds a plant's CasADi functions with the set's numbers in them, so its kernel
form compiles C for every set. A :class:`PlantFamily` builds the plant's functions once as
parametric ones (:mod:`rcm_kin.dynamics.parametric`: the drive's constants and first-moment
offsets as a last input ``p``) and compiles them once; ``plant(params)`` is then the plant of any
set of the same structure, its kernel form passing the set's ``p``
(:attr:`~rcm_kin.simulation.compiled_plant.CompiledPlant.parameters`). The parametric model is
:func:`~rcm_kin.dynamics.parametric.shared_model`'s: a robustness sample's plant and its margins'
model are one model, built once per process. The plant is the one
:func:`~rcm_kin.simulation.experiments.psm_plant` builds, bit for bit: the identified drive trains
when the set has them, else the smooth model's period map (tests/simulation/test_plant_family.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from rcm_kin.dynamics.axis_friction import substep_count
from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.parametric import ParametricDynamics, shared_model, structure_key
from rcm_kin.errors import RcmKinError, as_number
from rcm_kin.model import load_robot
from rcm_kin.simulation.compiled_plant import CFunction, CompiledPlant, c_function
from rcm_kin.simulation.kernel import DRIVE_TRAIN, SMOOTH
from rcm_kin.simulation.plant import (
    DriveTrainPlant,
    Plant,
    SmoothPlant,
    drive_train_friction,
    period_map,
    rigid_body_drive,
)

MAX_PERIOD = 1.0     # s: a controller period longer than this is a mistake (the firmware's is 2.5 ms)


@dataclass(frozen=True, eq=False)
class PlantFamily:
    """The PSM plants of every parameter set shaped like the one it was built from (same drive-train
    joints, offsets on the same links): ``plant(params)``."""

    model: ParametricDynamics                  # rigid body + drive (drive trains: without Coulomb)
    period: float                              # s
    drive_trains: bool                         # the identified drive trains, else the smooth model
    functions: tuple[CFunction, ...] | None    # compiled: (mass matrix, bias) or (period map,); None: none
    smooth_map: object = None                  # the smooth model's parametric period map (x, u, p) -> x(T)

    def plant(self, params: DriveParameters, fast: bool = True) -> Plant:
        """The plant of ``params``; ``fast``: its kernel form where the family's functions compiled."""
        if not isinstance(params, DriveParameters) or bool(params.drive_train) != self.drive_trains:
            kind = "identified drive trains" if self.drive_trains else "no drive trains (the smooth model)"
            raise RcmKinError(f"`params` must be drive parameters with {kind}, as the family's", parameter="params")
        if self.drive_trains:
            rigid = rigid_body_drive(params)
            readable = DriveTrainPlant(self.model.bind(rigid), drive_train_friction(params), self.period)
            if not fast or self.functions is None:
                return readable
            return CompiledPlant(DRIVE_TRAIN, self.functions, self.period, readable, substep_count(self.period),
                                 parameters=self.model.values(rigid))
        p = self.model.values(params)
        if fast and self.functions is not None:
            return CompiledPlant(SMOOTH, self.functions, self.period, parameters=p)
        return SmoothPlant(lambda x, u: self.smooth_map(x, u, p), self.period)


def plant_family(params: DriveParameters, period: float, substeps: int = 4) -> PlantFamily:
    """The family of the PSM's plants shaped like ``params``, its functions compiled once (cached on
    disk; none without a C compiler: then ``plant`` is the readable plant); ``substeps`` RK4 steps
    per ``period`` s in the smooth model's period map."""
    psm = load_robot("psm")
    structure_key(psm, params)                          # drive parameters, or a one-line error
    period = as_number(period, "period", "s", 0.0, MAX_PERIOD, low_open=True)
    if params.drive_train:
        model = shared_model(psm, rigid_body_drive(params), coulomb=False)
        mass_matrix, bias = c_function(model.mass_matrix), c_function(model.bias)
        functions = None if mass_matrix is None or bias is None else (mass_matrix, bias)
        return PlantFamily(model, period, True, functions)
    model = shared_model(psm, params)
    smooth_map = period_map(model.forward, period, substeps)
    fn = c_function(smooth_map)
    return PlantFamily(model, period, False, None if fn is None else (fn,), smooth_map)



_FAMILIES: dict[tuple, PlantFamily] = {}     # (structure, drive trains, period, substeps) -> family


def family_of(params: DriveParameters, period: float, substeps: int = 4) -> PlantFamily:
    """:func:`plant_family` of ``params``' structure (the parametric model's
    :func:`~rcm_kin.dynamics.parametric.structure_key` and which joints have drive trains), built
    once per process: the plant of a drawn set is ``family_of(drawn, period).plant(drawn)``."""
    key = (structure_key(load_robot("psm"), params), tuple(sorted(params.drive_train)),
           as_number(period, "period", "s", 0.0, MAX_PERIOD, low_open=True), int(substeps))
    if key not in _FAMILIES:
        _FAMILIES[key] = plant_family(params, period, substeps)
    return _FAMILIES[key]
