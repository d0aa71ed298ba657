"""The Python API holds the command line's contract (README, "Bad input: the contract"): every public
function, given hostile arguments (wrong sizes and types, NaN, infinities, huge numbers, strings,
None, nested lists), raises an :class:`rcm_kin.RcmKinError` (naming the argument) or returns finite
numbers; never a raw ``TypeError``/``ValueError``/``ZeroDivisionError`` or a CasADi error, never NaN.
A pose outside the joint limits is refused (:class:`JointLimitError`) unless
``allow_outside_limits=True`` asks for the model there, where it equals plain Pinocchio.

Deterministic in CI (``derandomize=True``); a longer run: ``RCM_KIN_FUZZ_EXAMPLES=500``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rcm_kin as rk

EXAMPLES = int(os.environ.get("RCM_KIN_FUZZ_EXAMPLES", "40"))

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30),
                    st.sampled_from([0.0, 0.05, -0.05, 0.1, 1e6, -1e300, 5.0]))
near = st.one_of(st.floats(-0.6, 0.6), st.floats(-40, 40),
                 st.sampled_from([math.nan, math.inf, 0.5236, -0.5236, 0.16, 30.0, -30.0, 31.0, 1e-300]))
hostile = st.one_of(
    st.lists(near, min_size=1, max_size=7),          # near the valid range: deeper paths
    st.lists(near, min_size=3, max_size=3),
    st.lists(numbers, max_size=9),
    st.text(max_size=6),
    st.none(),
    st.lists(st.lists(numbers, max_size=3), max_size=3),
    st.builds(lambda n, x: np.full((n, 3), x), st.integers(0, 3), numbers),
    st.dictionaries(st.text(max_size=3), numbers, max_size=2),
    numbers,
)


@pytest.fixture(scope="module")
def robots():
    psm = rk.load_robot("psm")
    return {"psm": psm, "mtm": rk.load_robot("mtm"), "driven": rk.driven_dynamics(psm),
            "design": rk.driven_dynamics(psm, coulomb=False), "run": rk.run_experiment("step", "p", duration=0.5)}


CALLS = {
    "gravity_torque": lambda r, x: rk.gravity_torque(r["psm"], x),
    "forward_kinematics": lambda r, x: rk.forward_kinematics(r["psm"], x),
    "holding_effort": lambda r, x: rk.holding_effort(r["psm"], x),
    "holding_pwm": lambda r, x: rk.holding_pwm(r["driven"], x),
    "linearize": lambda r, x: rk.linearize(r["driven"], x),
    "linearize_grid": lambda r, x: rk.linearize_grid(r["driven"], x, compile=False),
    "inverse_kinematics": lambda r, x: rk.inverse_kinematics(r["psm"], x),
    "inverse_kinematics q0": lambda r, x: rk.inverse_kinematics(r["psm"], [0.01, 0.02, -0.06], q0=x),
    "gravity_map": lambda r, x: rk.gravity_map(r["psm"], roll_deg=x, pitch_deg=[0.0]),
    "torque_map": lambda r, x: rk.torque_map(r["mtm"], {"j2": x, "j3": [0.0, 0.1]}),
    "schedule_gains": lambda r, x: rk.schedule_gains(r["design"], x, [0.0, 5.0]),
    "joint_table": lambda r, x: rk.joint_table(x),
    "robot argument": lambda r, x: rk.forward_kinematics(x, np.zeros(7)),
    "ik robot": lambda r, x: rk.inverse_kinematics(x, [0.01, 0.02, -0.06]),
    "ik rpy": lambda r, x: rk.inverse_kinematics(r["psm"], [-0.009, 0, -0.073], rpy=x),
    "ik frame": lambda r, x: rk.inverse_kinematics(r["psm"], [0.01, 0.02, -0.06], frame=x),
    "torque_map robot": lambda r, x: rk.torque_map(x, {"j2": [0.0, 0.1], "j3": [0.0, 0.1]}),
    "torque_map q": lambda r, x: rk.torque_map(r["mtm"], {"j2": [0.0, 0.1], "j3": [0.0, 0.1]}, q=x),
    "gravity_map robot": lambda r, x: rk.gravity_map(x, roll_deg=[0.0], pitch_deg=[0.0]),
    "gravity_map insertion": lambda r, x: rk.gravity_map(r["psm"], roll_deg=[0.0], pitch_deg=[0.0], insertion=x),
    "driven_dynamics robot": lambda r, x: rk.driven_dynamics(x),
    "place_counterweight mass": lambda r, x: rk.place_counterweight(r["mtm"], "counterweight",
                                                                    {"j2": [0, 0.1], "j3": [0, 0.1]}, mass=x),
    "place_counterweight max_distance": lambda r, x: rk.place_counterweight(
        r["mtm"], "counterweight", {"j2": [0, 0.1], "j3": [0, 0.1]}, max_distance=x),
    "place_counterweight joints": lambda r, x: rk.place_counterweight(r["mtm"], "counterweight",
                                                                      {"j2": [0, 0.1], "j3": [0, 0.1]}, joints=x),
    "schedule_gains insertion": lambda r, x: rk.schedule_gains(r["design"], [0.0, 5.0], [0.0, 5.0], insertion=x),
    "schedule_gains ramp": lambda r, x: rk.schedule_gains(r["design"], [0.0, 5.0], [0.0, 5.0],
                                                          friction_ramp_deg_s=x),
    "schedule_gains model": lambda r, x: rk.schedule_gains(x, [0.0, 5.0], [0.0, 5.0]),
    "run_experiment duration": lambda r, x: rk.run_experiment("step", "p", duration=x),
    "run_experiment seed": lambda r, x: rk.run_experiment("step", "p", duration=0.5, seed=x),
    "tracking_metrics": lambda r, x: rk.tracking_metrics(x),
    "tracking_metrics skip": lambda r, x: rk.tracking_metrics(r["run"], skip=x),
    "simulate": lambda r, x: rk.simulate(lambda state, u: state, x, x),
    "load_drive_parameters": lambda r, x: rk.load_drive_parameters(x) if not isinstance(x, str) else None,
    "write_report map_points": lambda r, x: rk.write_report(os.devnull, map_points=x) if not (
        isinstance(x, int) and not isinstance(x, bool) and 2 <= x <= 1001) else None,
}


def finite(value, seen=0) -> bool:
    """Whether every number in ``value`` (arrays, dataclasses, dicts, lists, SE3) is finite."""
    if seen > 6:
        return True
    if isinstance(value, pin.SE3):
        return bool(np.all(np.isfinite(value.homogeneous)))
    if isinstance(value, np.ndarray):
        return value.dtype.kind not in "fc" or bool(np.all(np.isfinite(value)))
    if isinstance(value, float):
        return math.isfinite(value)
    if dataclasses.is_dataclass(value):
        return all(finite(getattr(value, f.name), seen + 1) for f in dataclasses.fields(value))
    if isinstance(value, dict):
        return all(finite(v, seen + 1) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(finite(v, seen + 1) for v in value)
    return True


@pytest.mark.parametrize("name", CALLS)
def test_hostile_arguments_give_an_rcm_kin_error_or_finite_numbers(robots, name):
    @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(hostile)
    def case(x):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                result = CALLS[name](robots, x)
            except rk.RcmKinError as exc:
                assert str(exc) and "\n" not in str(exc).strip()
                return
        assert finite(result), f"{name}({x!r}) returned a non-finite number"

    case()


FAR = [5.0, 5.0, 5.0, 0, 0, 0, 0]


@pytest.mark.parametrize("call", [rk.gravity_torque, rk.forward_kinematics, rk.holding_effort])
def test_a_pose_outside_the_limits_is_refused_naming_the_argument(robots, call):
    with pytest.raises(rk.JointLimitError) as caught:
        call(robots["psm"], FAR)
    assert caught.value.parameter == "q" and caught.value.joints == ("roll", "pitch", "insertion")
    assert "roll 286.479 deg not in [-30 deg, 30 deg]" in str(caught.value)


def test_holding_pwm_refuses_a_pose_outside_the_limits_and_other_bad_poses(robots):
    model = robots["driven"]
    with pytest.raises(rk.JointLimitError) as caught:
        rk.holding_pwm(model, [5, 5, 5])                 # the case: numbers came back
    assert caught.value.parameter == "q" and caught.value.joints == ("roll", "pitch", "insertion")
    for bad in ([float("nan"), 0, 0], [0, 0], "a", None):
        with pytest.raises(rk.RcmKinError) as caught:
            rk.holding_pwm(model, bad)
        assert caught.value.parameter == "q"
    with pytest.raises(rk.RcmKinError, match="driven_dynamics") as caught:
        rk.holding_pwm(robots["psm"], [0, 0, 0.08])
    assert caught.value.parameter == "model"


def test_outside_the_limits_on_request_is_plain_pinocchio(robots):
    """``allow_outside_limits=True`` evaluates the model there: the same numbers as Pinocchio's own
    calls on the reduced model (the PSM's passive joints as mimic joints)."""
    psm = robots["psm"]
    q = np.array([0.7, -0.9, 0.2, 0.1, 0.0, 0.0, 0.0])          # roll 40 deg, pitch -52 deg, 0.2 m
    model, data = psm.reduced, psm.reduced.createData()
    q_red = np.zeros(model.nq)
    q_red[[model.joints[model.getJointId(j)].idx_q for j in psm.actuated]] = q
    pin.framesForwardKinematics(model, data, q_red)
    tip = data.oMf[model.getFrameId("shaft_tip")].homogeneous
    fk = rk.forward_kinematics(psm, q, allow_outside_limits=True)
    assert np.allclose(fk.frames["shaft_tip"].homogeneous, tip, atol=1e-12)
    g = pin.computeGeneralizedGravity(model, data, q_red)
    tau = rk.gravity_torque(psm, q, allow_outside_limits=True)
    assert np.allclose(tau, g[[model.joints[model.getJointId(j)].idx_v for j in psm.actuated]], atol=1e-9)
    pwm = rk.holding_pwm(robots["driven"], q[:3], allow_outside_limits=True)
    assert np.all(np.isfinite(pwm)) and pwm.shape == (3,)
