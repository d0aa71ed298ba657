"""Compiled CasADi functions: same numbers as the interpreted ones, cached, and a fallback."""

from __future__ import annotations

import importlib
import os
import shutil
import warnings

import casadi as ca
import numpy as np
import pytest

from rcm_kin.errors import CompilerFallbackWarning, RcmKinError, RcmKinWarning

comp = importlib.import_module("rcm_kin.symbolic.compiled")   # the module (the package's ``compiled`` is the function)


needs_compiler = pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None,
                                    reason="no C compiler (CC hidden): the fallback run")


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    """An empty cache folder for one test."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    comp._load.cache_clear()
    return tmp_path / "rcm-kin" / "casadi"


def random_states(model, n, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(model.lower, model.upper, (n, 3))
    v = rng.normal(0, 0.5, (n, 3))
    u = rng.uniform(-200, 200, (n, 3))
    return np.hstack([q, v]), u


@needs_compiler
def test_compiled_model_functions_equal_interpreted(cache, model):
    """forward, jacobians (sparse outputs) and gravity: the C build agrees to 1e-12."""
    X, U = random_states(model, 20, 0)
    for fn in (model.forward, model.jacobians):
        fast = comp.compiled(fn)
        assert fast.class_name() != fn.class_name()   # a loaded library, not the SX function
        for x, u in zip(X, U):
            for a, b in zip(fast.call([x, u]), fn.call([x, u]), strict=True):
                np.testing.assert_allclose(np.array(a), np.array(b), rtol=1e-12, atol=1e-12)
    g = comp.compiled(model.gravity)
    for x in X:
        np.testing.assert_allclose(np.array(g(x[:3])), np.array(model.gravity(x[:3])), rtol=1e-12, atol=1e-12)
    # mapped: the loop over poses stays in C
    A, B = comp.compiled(model.jacobians).map(len(X))(X.T, U.T)
    for k, (x, u) in enumerate(zip(X, U)):
        a, b = model.jacobians(x, u)
        np.testing.assert_allclose(np.array(A)[:, 6 * k:6 * k + 6], np.array(a), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.array(B)[:, 3 * k:3 * k + 3], np.array(b), rtol=1e-12, atol=1e-12)


@needs_compiler
def test_built_once_then_loaded_from_the_cache(cache, model):
    comp.compiled(model.gravity)
    libraries = list(cache.glob("*.so"))
    assert len(libraries) == 1 and libraries[0].name.startswith("gravity_")
    inode = libraries[0].stat().st_ino                       # a rebuild would replace the file
    comp._load.cache_clear()
    comp.compiled(model.gravity)
    assert list(cache.glob("*.so")) == libraries and libraries[0].stat().st_ino == inode
    assert [p for p in cache.iterdir() if p.is_dir()] == []   # no build folder left behind


def test_key_follows_the_function_the_compiler_and_the_machine(model, monkeypatch):
    command = ["cc"]
    key = comp.function_key(model.gravity, command)
    assert key == comp.function_key(model.gravity, command)
    assert key != comp.function_key(model.bias, command)
    assert key != comp.function_key(model.gravity, ["gcc"])
    monkeypatch.setattr(comp.platform, "machine", lambda: "some-other-cpu")
    assert key != comp.function_key(model.gravity, command)
    monkeypatch.undo()
    monkeypatch.setattr(comp.platform, "system", lambda: "SomeOtherOS")
    assert key != comp.function_key(model.gravity, command)


@needs_compiler
def test_the_cache_keeps_the_most_recently_used_libraries(cache, monkeypatch):
    """Beyond the limit the least recently used library goes; using one (a cache hit) makes it
    recent again, and the one just built is never deleted."""
    monkeypatch.setattr(comp, "CACHE_LIBRARIES", 2)
    command = comp.compiler_command()
    def build(k: int):
        return comp.build_library(f"f{k}", f"{k:032d}", f"double f{k}(void) {{ return {k}; }}\n", command)
    first, second = build(1), build(2)
    os.utime(first, (1, 1))                                  # make the first the oldest, then use it
    os.utime(second, (2, 2))
    assert build(1) == first and first.stat().st_mtime > 2   # a hit touches it
    third = build(3)
    assert sorted(p.name for p in cache.glob("*.so")) == sorted([first.name, third.name])


@needs_compiler
def test_a_truncated_cached_library_is_built_anew(cache, model):
    """A cached library cut short after its ELF header (a full disk, a killed copy) fails its
    checksum: deleted and rebuilt on the next call, with one warning naming it, which then gives
    the interpreted function's values (1e-12)."""
    library = comp.compiled_library(model.gravity)        # built, not loaded in this process
    library.write_bytes(library.read_bytes()[:64])       # the ELF header only
    with pytest.warns(RcmKinWarning) as caught:
        g = comp.compiled(model.gravity)
    assert len(caught) == 1
    assert str(caught[0].message) == (f"the cached library {library} does not match its SHA-256 "
                                      "(truncated or overwritten): deleted and built anew")
    assert g.class_name() != model.gravity.class_name()  # the library, not the interpreted fallback
    assert library.stat().st_size > 64 and list(cache.glob("*.so")) == [library]
    for q in np.random.default_rng(3).uniform(model.lower, model.upper, (10, 3)):
        np.testing.assert_allclose(np.array(g(q)), np.array(model.gravity(q)), rtol=1e-12, atol=1e-12)


def scaled(factor: float) -> ca.Function:
    """``f(x) = factor * x``: functions of one name that differ only in a constant (as one model's
    gravity under two parameter sets)."""
    x = ca.SX.sym("x", 2)
    return ca.Function("f", [x], [factor * x])


@needs_compiler
@pytest.mark.parametrize("with_checksum", [False, True])
def test_a_library_copied_over_another_name_is_built_anew(cache, with_checksum):
    """The library of ``3 x`` copied over the cached name of ``2 x`` (alone: its bytes do not hash
    as recorded; with its checksum file: the key recorded is another's) is detected, rebuilt with
    one warning, and the numbers are those of ``2 x``."""
    two, three = comp.compiled_library(scaled(2.0)), comp.compiled_library(scaled(3.0))
    assert two != three
    shutil.copyfile(three, two)
    if with_checksum:
        shutil.copyfile(comp.checksum_file(three), comp.checksum_file(two))
    with pytest.warns(RcmKinWarning) as caught:
        f = comp.compiled(scaled(2.0))
    reason = "has a checksum file for another key" if with_checksum else "does not match its SHA-256"
    assert len(caught) == 1 and str(caught[0].message).startswith(f"the cached library {two} {reason}")
    assert f.class_name() != "SXFunction"
    np.testing.assert_array_equal(np.array(f([1.5, -4.0])).ravel(), [3.0, -8.0])
    np.testing.assert_array_equal(np.array(comp.compiled(scaled(3.0))([1.0, 2.0])).ravel(), [3.0, 6.0])


@needs_compiler
def test_a_library_without_its_checksum_file_is_built_anew(cache, model, monkeypatch):
    """A library from before checksum files (or copied in by hand) is rebuilt (the compiler runs
    once), with one warning, and gets its checksum file."""
    library = comp.compiled_library(model.gravity)
    comp.checksum_file(library).unlink()
    runs, run = [], comp.subprocess.run
    monkeypatch.setattr(comp.subprocess, "run", lambda *a, **k: runs.append(a) or run(*a, **k))
    with pytest.warns(RcmKinWarning, match="has no checksum file") as caught:
        g = comp.compiled(model.gravity)
    assert len(caught) == 1 and len(runs) == 1 and comp.checksum_file(library).is_file()
    for q in np.random.default_rng(4).uniform(model.lower, model.upper, (5, 3)):
        np.testing.assert_allclose(np.array(g(q)), np.array(model.gravity(q)), rtol=1e-12, atol=1e-12)


@needs_compiler
def test_a_valid_cached_library_is_used_without_building(cache, model, monkeypatch):
    """A library that passes its checks is loaded as it is: no compiler run, no warning."""
    library = comp.compiled_library(model.gravity)
    assert comp.checksum_file(library).read_text().split()[1] == comp.function_key(
        model.gravity, comp.compiler_command())

    def no_build(*args, **kwargs):
        raise AssertionError("the compiler ran on a valid cached library")
    monkeypatch.setattr(comp.subprocess, "run", no_build)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = comp.compiled(model.gravity)
    assert g.class_name() != model.gravity.class_name()
    q = np.array([0.1, -0.2, 0.15])
    np.testing.assert_allclose(np.array(g(q)), np.array(model.gravity(q)), rtol=1e-12, atol=1e-12)


def test_a_library_that_never_loads_is_an_error(cache, model, monkeypatch, tmp_path):
    """A compiler whose output never loads (here: writes a text file): rebuilt once, then one clear error."""
    fake = tmp_path / "fake-cc"
    fake.write_text('#!/bin/sh\nwhile [ "$1" != "-o" ]; do shift; done\necho not a library > "$2"\n')
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    with pytest.raises(RcmKinError, match=r"the compiled gravity does not load, even built anew: .*\.so"):
        comp.compiled(model.gravity)


def test_cache_folder_respects_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert comp.cache_folder() == tmp_path / "rcm-kin" / "casadi"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert str(comp.cache_folder()).endswith(".cache/rcm-kin/casadi")


def test_no_compiler_falls_back_with_one_warning(cache, model, capsys, tmp_path, monkeypatch):
    """With the compiler hidden the interpreted function comes back and one warning says so
    (through ``warnings``: nothing printed)."""
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.warns(CompilerFallbackWarning) as caught:
        f1, f2 = comp.compiled(model.gravity), comp.compiled(model.forward)
    assert f1 is model.gravity and f2 is model.forward
    assert len(caught) == 1
    message = str(caught[0].message)
    assert message.startswith("no C compiler") and "interpreted" in message
    assert caught[0].filename == __file__                    # located at the caller's line
    assert capsys.readouterr() == ("", "")
    assert not cache.exists()


@needs_compiler
def test_unwritable_cache_falls_back_with_one_warning(model, monkeypatch, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))           # the cache would have to live in a file
    with pytest.warns(CompilerFallbackWarning) as caught:
        assert comp.compiled(model.gravity) is model.gravity
    assert len(caught) == 1 and str(caught[0].message).startswith("cannot write the compiled-function cache")
    assert capsys.readouterr() == ("", "")


def test_compiler_failure_is_an_error(cache, model, monkeypatch):
    monkeypatch.setenv("CC", "false")
    with pytest.raises(RcmKinError, match="compiling gravity with false failed"):
        comp.compiled(model.gravity)


@pytest.mark.parametrize("build", [False, True])
def test_single_call_matches_a_plain_call(cache, model, build):
    fn = comp.compiled(model.jacobians) if build else model.jacobians
    call = comp.single_call(fn)
    X, U = random_states(model, 5, 1)
    for x, u in zip(X, U):
        A, B = call(x, u)
        a, b = model.jacobians(x, u)
        assert A.shape == (6, 6) and B.shape == (6, 3)
        np.testing.assert_allclose(A, np.array(a), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(B, np.array(b), rtol=1e-12, atol=1e-12)
    (xdot,) = comp.single_call(model.forward)(X[0], U[0])
    np.testing.assert_array_equal(xdot, np.array(model.forward(X[0], U[0])).ravel())


def test_single_call_dense_matrix_layout():
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [ca.vertcat(ca.horzcat(x[0], 2 * x[1], 3.0), ca.horzcat(x[1], x[0] * x[1], 5.0))])
    (out,) = comp.single_call(f)(np.array([2.0, 7.0]))
    np.testing.assert_array_equal(out, [[2.0, 14.0, 3.0], [7.0, 14.0, 5.0]])


@pytest.mark.parametrize("build", [False, True])
def test_map_points_matches_point_calls(cache, model, build):
    """Chunks of 7 over 20 points (a remainder chunk), sparse (A, B) filled densely."""
    X, U = random_states(model, 20, 2)
    fn = comp.compiled(model.jacobians) if build else model.jacobians
    A, B = comp.map_points(fn, X, U, chunk=7)
    assert A.shape == (20, 6, 6) and B.shape == (20, 6, 3)
    (g,) = comp.map_points(comp.compiled(model.gravity) if build else model.gravity, X[:, :3], chunk=7)
    assert g.shape == (20, 3)
    for k, (x, u) in enumerate(zip(X, U)):
        a, b = model.jacobians(x, u)
        np.testing.assert_allclose(A[k], np.array(a), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(B[k], np.array(b), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(g[k], np.array(model.gravity(x[:3])).ravel(), rtol=1e-12, atol=1e-12)
    with pytest.raises(RcmKinError, match="needs 6 dense values"):
        comp.map_points(fn, X[:, :3], U)


def test_map_points_matrix_and_scalar_outputs():
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [ca.horzcat(x, 2 * x), x[0] * x[1]])
    M, s = comp.map_points(f, np.array([[1.0, 2.0], [3.0, 4.0]]))
    np.testing.assert_array_equal(M, [[[1, 2], [2, 4]], [[3, 6], [4, 8]]])
    np.testing.assert_array_equal(s, [2.0, 12.0])
