"""Prediction bands of a drive parameter file on a log: ``rcm-kin predict --band``.

The file's own ``[drive_train.<joint>]`` and its ``[uncertainty]`` (fold sets, undetermined ranges,
preload span, hull) make the ensemble of :mod:`rcm_kin.identification.bands`.
"""

from __future__ import annotations

import numpy as np

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.stick_slip import AxisPlant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.bands import LEVEL, PRELOADS, PredictionBand, prediction_band, widened
from rcm_kin.identification.drive_train import AxisLog, LogCheck
from rcm_kin.identification.identify import file_record, predict_record
from rcm_kin.statics.holding_band import check_level

__all__ = ["drive_file_band", "predict_band"]


def drive_file_band(params: DriveParameters, log: AxisLog, plant: AxisPlant, level: float = LEVEL,
                    preloads: int = PRELOADS) -> PredictionBand:
    """The band of the drive file ``params`` over ``log`` (its ``joint``) on ``plant``: its own
    ``[drive_train.<joint>]`` and its ``[uncertainty]`` folds, ranges, logs' preloads (a step log;
    without them, and on a closed-loop record, preloads evenly over [-1, 1]) and hull, widened by
    its logs' widening scores (``[uncertainty.discrepancy]``, :func:`widened`) where it has them
    (a step log inside the calibrated poses). A file without fold
    sets is a clear error."""
    joint = log.joint
    level = check_level(level)
    folds = params.uncertainty.folds.get(joint, ())
    if not folds:
        raise RcmKinError(f"no leave-one-log-out parameter sets in {params.source}: run rcm-kin identify --cv")
    sets = [s.friction for s in folds] + [params.drive_train[joint]]
    values = params.uncertainty.preloads.get(joint) if log.law is None else None
    band = prediction_band(sets, plant, log, level, params.uncertainty.ranges.get(joint), preloads,
                           params.uncertainty.hull, folds=len(folds), preload_values=values)
    scores = params.uncertainty.discrepancy.get(joint)
    return widened(band, scores) if scores and log.law is None and not band.extrapolated else band


def predict_band(params: DriveParameters, path, joint: str, level: float = LEVEL,
                 preloads: int = PRELOADS) -> tuple[AxisLog, np.ndarray, LogCheck, PredictionBand]:
    """``rcm-kin predict --band``: the log at ``path`` as :func:`predict_file` reads it, the file's
    point prediction (rad) and its check, and the file's band (:func:`drive_file_band`)."""
    level = check_level(level)
    if not params.uncertainty.folds.get(joint):
        raise RcmKinError(f"no leave-one-log-out parameter sets in {params.source}: run rcm-kin identify --cv")
    log, plant = file_record(params, path, joint)
    predicted, check = predict_record(params, log, plant)
    return log, predicted, check, drive_file_band(params, log, plant, level, preloads)
