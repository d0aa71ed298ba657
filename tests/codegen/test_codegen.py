"""Plain C99 model code: compiles under strict flags, agrees with the Python model at random poses."""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import subprocess

import casadi as ca
import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.codegen.c99 import c_function
from rcm_kin.codegen.psm_model import export_c
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.dynamics.state_space import holding_pwm
from rcm_kin.errors import RcmKinError
from rcm_kin.statics.maps import holding_effort

STRICT = ["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror"]
COMPILER = shutil.which(os.environ.get("CC") or "cc")
needs_compiler = pytest.mark.skipif(COMPILER is None, reason="no C compiler (CC hidden): the fallback run")


def build(sources, folder, name="model.so"):
    """Compile ``sources`` with the strict flags into a shared library and load it."""
    library = folder / name
    run = subprocess.run([COMPILER, *STRICT, "-O2", "-fPIC", "-shared", *map(str, sources), "-o", str(library),
                          "-lm"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return ctypes.CDLL(str(library))


def c_call(function, q):
    """pwm (3,), dpwm_dq (3, 3) from the C function through ctypes."""
    q = np.ascontiguousarray(q, dtype=float)
    pwm, grad = np.zeros(3), np.zeros(9)
    pointer = ctypes.POINTER(ctypes.c_double)
    function(*(a.ctypes.data_as(pointer) for a in (q, pwm, grad)))
    return pwm, grad.reshape(3, 3)


@pytest.fixture(scope="module")
def exported(tmp_path_factory, model):
    folder = tmp_path_factory.mktemp("c_model")
    result = export_c(model, folder)
    if COMPILER is None:
        return result, None
    function = build([f for f in result.files if f.suffix == ".c"], folder).rcm_psm_holding_pwm
    function.restype = None
    return result, function


def random_poses(model, n, seed=0):
    return np.random.default_rng(seed).uniform(model.lower, model.upper, (n, 3))


@needs_compiler
def test_c_holding_pwm_equals_the_casadi_model(exported, model):
    """Same expression graph: PWM and gradient to 1e-12 (relative to the largest entry)."""
    _, function = exported
    q = ca.SX.sym("q", 3)
    pwm = model.gravity(q) / ca.DM(model.drive.input_gain)
    gradient = ca.Function("grad", [q], [ca.jacobian(pwm, q)])   # without the export's CSE
    for pose in random_poses(model, 50):
        c_pwm, c_grad = c_call(function, pose)
        expect = holding_pwm(model, pose)
        np.testing.assert_allclose(c_pwm, expect, rtol=0, atol=1e-12 * max(1.0, np.abs(expect).max()))
        g = np.array(gradient(pose))
        np.testing.assert_allclose(c_grad, g, rtol=0, atol=1e-12 * max(1.0, np.abs(g).max()))


@needs_compiler
def test_c_holding_pwm_against_the_numpy_gravity_path(exported, model, psm, params):
    """Independent: Pinocchio-constant NumPy gravity (gravity_batch) through the drive model, and
    central differences of it for the gradient."""
    _, function = exported

    def numpy_pwm(pose):
        q = np.zeros(psm.nq)
        q[:3] = pose
        return holding_effort(psm, q).drive.pwm

    h = 1e-6
    for pose in random_poses(model, 10, seed=1):
        c_pwm, c_grad = c_call(function, pose)
        np.testing.assert_allclose(c_pwm, numpy_pwm(pose), rtol=1e-10, atol=1e-9)
        fd = np.column_stack([(numpy_pwm(pose + h * e) - numpy_pwm(pose - h * e)) / (2 * h) for e in np.eye(3)])
        np.testing.assert_allclose(c_grad, fd, rtol=1e-6, atol=1e-5)


def test_export_files_and_operation_count(exported):
    result, _ = exported
    assert [f.name for f in result.files] == ["rcm_psm_model.h", "rcm_psm_model.c"]
    assert result.functions == ["rcm_psm_holding_pwm"]
    assert result.operations == sum(result.operation_counts.values()) > 100
    text = result.files[1].read_text()
    assert "casadi" not in text.lower().replace("the casadi expression graph", "")
    assert "#include <math.h>" in text and "malloc" not in text
    assert f"{result.operations} floating-point operations" in result.files[0].read_text()


@needs_compiler
def test_c99_writer_on_a_small_function(tmp_path):
    """Powers, quotients, a constant output and a structural zero, against CasADi's evaluation."""
    x = ca.SX.sym("x", 2)
    out = ca.vertcat(ca.horzcat(x[0] ** 3 / x[1], ca.atan2(x[0], x[1]), 2.5),
                     ca.horzcat(ca.SX(0), ca.tanh(x[0]) * ca.sqrt(x[1]), ca.fmax(x[0], x[1])))
    fn = ca.Function("small", [x], [out, ca.exp(x)])
    code = c_function(fn, "small", ["x"], ["m", "e"])
    assert code.prototype == "void small(const double x[2], double m[6], double e[2])"
    source = tmp_path / "small.c"
    source.write_text("#include <math.h>\n" + code.body + "\n")
    lib = build([source], tmp_path, "small.so")
    pointer = ctypes.POINTER(ctypes.c_double)
    for value in ([0.3, 1.7], [-2.0, 0.5]):
        xv, m, e = np.array(value), np.full(6, np.nan), np.full(2, np.nan)
        lib.small(*(a.ctypes.data_as(pointer) for a in (xv, m, e)))
        expect_m, expect_e = (np.array(r) for r in fn.call([xv]))
        np.testing.assert_allclose(m.reshape(2, 3), expect_m, rtol=1e-15, atol=0)
        np.testing.assert_allclose(e, expect_e.ravel(), rtol=1e-15, atol=0)


def test_c99_writer_refuses_what_it_cannot_write():
    x = ca.SX.sym("x", 2)
    with pytest.raises(RcmKinError, match="no C99 translation"):
        c_function(ca.Function("f", [x], [ca.erf(x)]), "f", ["x"], ["y"])
    with pytest.raises(RcmKinError, match="only SX"):
        X = ca.MX.sym("x", 2)
        c_function(ca.Function("f", [X], [2 * X]), "f", ["x"], ["y"])


def test_export_cli(capsys, tmp_path):
    code = main(["export", "psm", "--c", str(tmp_path / "fw"), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    payload = json.loads(out)
    assert payload["files"] == [str(tmp_path / "fw" / "rcm_psm_model.h"), str(tmp_path / "fw" / "rcm_psm_model.c")]
    assert isinstance(payload["operations"], int) and payload["functions"] == ["rcm_psm_holding_pwm"]
    for argv, message in ((["export", "mtm", "--c", str(tmp_path)], "PSM's holding PWM"),
                          (["export", "psm"], "--c DIR")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error:") and message in err[0]


def test_export_follows_the_parameter_file(tmp_path, psm, params):
    """A different drive gain scales the exported constants: the C is built from the given TOML."""
    from rcm_kin.dynamics.drive import with_joint, write_parameters
    changed = write_parameters(with_joint(params, "roll", resistance=2 * params["roll"].resistance),
                               tmp_path / "p.toml")
    assert load_drive_parameters(changed)["roll"].resistance == 2 * params["roll"].resistance
    main(["export", "psm", "--c", str(tmp_path / "a")])
    main(["export", "psm", "--c", str(tmp_path / "b"), "--params", str(changed)])
    a, b = ((tmp_path / d / "rcm_psm_model.c").read_text() for d in "ab")
    assert a != b and "p.toml" in (tmp_path / "b" / "rcm_psm_model.h").read_text()
