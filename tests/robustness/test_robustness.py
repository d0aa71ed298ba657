"""Robustness runs: draws, statistics, and the same answer on any Dask cluster (embedded, external,
with a worker killed mid-run). The runs are tiny (4-6 samples of a 0.25 s sinusoid) so the
clusters' start-up dominates."""

from __future__ import annotations

import json
import os
import signal
import socketserver
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import rcm_kin
from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.cli.common import check_finite
from rcm_kin.dynamics.drive import DRIVEN, load_drive_parameters
from rcm_kin.parallel import batches_of
from rcm_kin.robustness.execution import run_in_process, run_robustness
from rcm_kin.robustness.sampling import (
    DEFAULT_RELATIVE_SPREAD,
    draw,
    read_standard_errors,
    sample_seeds,
    uncertain_parameters,
    with_values,
)
from rcm_kin.robustness.statistics import spread, summarise
from rcm_kin.robustness.task import SampleOutcome, Study, run_batch

CONTROLLERS = ("p", "scheduled")
DURATION = 0.25                 # s of the sinusoid: the statistics do not need more
SAMPLES = 4
SEED = 7
ARGS = ["robustness", "psm", "--controller", "p", "--controller", "scheduled", "--experiment", "sine",
        "--samples", str(SAMPLES), "--seed", str(SEED), "--duration", str(DURATION), "--batch-size", "1", "--json"]


@pytest.fixture(scope="module")
def params():
    """The shipped set without its fold sets: every uncertain parameter drawn from its spread (the
    fold-set draws: tests/robustness/test_fold_sampling.py)."""
    shipped = load_drive_parameters()
    return replace(shipped, uncertainty=replace(shipped.uncertainty, folds={}))


@pytest.fixture(scope="module")
def study():
    """The study the CLI runs by default: the shipped file, its roll drawn from its fold sets."""
    shipped = load_drive_parameters()
    return Study(shipped, uncertain_parameters(shipped), CONTROLLERS, "sine", DURATION)


@pytest.fixture(scope="module")
def serial(study):
    """The reference: every sample computed in this process, no Dask."""
    return run_in_process(study, SAMPLES, SEED)


# --- draws -------------------------------------------------------------------------------------

def test_sample_seeds_are_spawned_children():
    with pytest.raises(RcmKinError, match="non-negative"):
        sample_seeds(-1, 5)
    children = sample_seeds(3, 5)
    for i, child in enumerate(children):
        again = np.random.SeedSequence(3, spawn_key=(i,))
        assert np.array_equal(child.generate_state(4), again.generate_state(4))


def test_draws_follow_the_stated_distributions(params):
    uncertain = uncertain_parameters(params)
    values = np.array([draw(uncertain, s) for s in sample_seeds(0, 4000)])
    z = np.empty_like(values)
    for k, u in enumerate(uncertain):
        z[:, k] = (np.log(values[:, k] / u.nominal) / (u.sigma / u.nominal) if u.positive
                   else (values[:, k] - u.nominal) / u.sigma)
    # standard normal: mean within 4 standard errors of 0, standard deviation within 4 of 1
    n = len(values)
    assert np.all(np.abs(z.mean(axis=0)) < 4 / np.sqrt(n))
    assert np.all(np.abs(z.std(axis=0) - 1) < 4 / np.sqrt(2 * n))
    assert np.all(values[:, [u.positive for u in uncertain]] > 0)


def test_uncertain_parameters_of_the_shipped_set(params):
    uncertain = {u.name: u for u in uncertain_parameters(params)}
    roll = params.drive_train["roll"]
    assert uncertain["drive_train.roll.motor_viscous"].sigma == pytest.approx(
        DEFAULT_RELATIVE_SPREAD["drive_train"] * roll.motor_viscous, rel=1e-12)
    assert not uncertain["drive_train.roll.presliding_slope"].positive
    assert "drive_train.roll.stribeck_velocity" not in uncertain      # stiction is off: its velocity does nothing
    assert "drive_train.roll.viscous" not in uncertain                # 0: no scale
    assert "roll.coulomb" not in uncertain                             # follows the drive train
    pitch = params["pitch"].coulomb
    assert uncertain["pitch.coulomb"].sigma == pytest.approx(DEFAULT_RELATIVE_SPREAD["friction"] * pitch, rel=1e-12)


def test_nominal_values_give_back_the_nominal_set(params):
    uncertain = uncertain_parameters(params)
    same = with_values(params, uncertain, [u.nominal for u in uncertain])
    for joint in DRIVEN:
        assert vars(same[joint]) == pytest.approx(vars(params[joint]), rel=1e-12, abs=0)
    assert same.drive_train == params.drive_train
    for link, moment in params.gravity_offsets.items():
        assert np.array_equal(same.gravity_offsets[link], moment)


def test_drawn_drive_train_moves_the_smooth_constants(params):
    uncertain = uncertain_parameters(params)
    values = [2 * u.nominal if u.name == "drive_train.roll.presliding_force" else u.nominal for u in uncertain]
    drawn = with_values(params, uncertain, values)
    roll = params.drive_train["roll"]
    assert drawn.drive_train["roll"].presliding_force == 2 * roll.presliding_force
    assert drawn["roll"].coulomb == pytest.approx(roll.coulomb + roll.motor_coulomb + 2 * roll.presliding_force,
                                                  rel=1e-12)


def test_standard_errors_from_identify_output(tmp_path, params):
    path = tmp_path / "identify.json"
    path.write_text(json.dumps({"standard_errors": {"roll": {"motor_viscous": 0.08, "presliding_force": None}},
                                "jackknife_standard_errors": {"roll": {"motor_viscous": 1.3,
                                                                       "presliding_force": 0.58}}}))
    errors = read_standard_errors(path)
    assert errors == {"drive_train.roll.motor_viscous": (1.3, "jackknife"),
                      "drive_train.roll.presliding_force": (0.58, "jackknife")}
    uncertain = {u.name: u for u in uncertain_parameters(params, errors)}
    assert (uncertain["drive_train.roll.motor_viscous"].sigma, uncertain["drive_train.roll.motor_viscous"].source) == \
        (1.3, "jackknife")
    assert uncertain["drive_train.roll.coulomb"].source.startswith("default")
    path.write_text(json.dumps({"standard_errors": {"roll": {"viscous": 0.08}}, "jackknife_standard_errors": {}}))
    assert read_standard_errors(path) == {"drive_train.roll.viscous": (0.08, "gauss-newton")}
    path.write_text(json.dumps({"standard_errors": {"roll": [0.08]}}))
    with pytest.raises(RcmKinError, match="must map each joint"):
        read_standard_errors(path)


# --- statistics ----------------------------------------------------------------------------------

def _percentile(values, q):
    """Linear interpolation between order statistics, by hand."""
    v = sorted(values)
    position = (len(v) - 1) * q / 100
    lo = int(np.floor(position))
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (position - lo) * (v[hi] - v[lo])


def test_statistics_against_a_hand_computation(study):
    rng = np.random.default_rng(1)
    n = 11
    max_error = rng.uniform(0.5, 3.0, (n, 2, 2))
    mean_error = max_error * rng.uniform(0.1, 0.5, (n, 2, 2))
    diverged = np.zeros((n, 2), dtype=bool)
    diverged[[2, 7], 1] = True
    max_error[diverged], mean_error[diverged] = np.nan, np.nan
    saturated = rng.uniform(size=(n, 2, 2)) < 0.4
    max_real = rng.uniform(-5, 0.5, (n, 2))
    radius = rng.uniform(0.95, 1.02, (n, 2))
    damping = rng.uniform(-0.1, 0.7, (n, 2))
    outcomes = [SampleOutcome(i, np.zeros(0), max_error[i], mean_error[i], saturated[i], diverged[i], max_real[i],
                              radius[i], damping[i]) for i in reversed(range(n))]            # any order in
    result = summarise(study, 0, outcomes)
    assert [o.index for o in result.outcomes] == list(range(n))
    for c, name in enumerate(study.controllers):
        r = result.controllers[name]
        ok = ~diverged[:, c]
        assert r.unstable_fraction == pytest.approx(diverged[:, c].sum() / n, abs=1e-15)
        for a, axis in enumerate(("roll", "pitch")):
            for got, table in ((r.axes[axis].max_error_deg, max_error), (r.axes[axis].mean_error_deg, mean_error)):
                kept = list(table[ok, c, a])
                assert [got.p5, got.median, got.p95, got.worst] == pytest.approx(
                    [_percentile(kept, 5), _percentile(kept, 50), _percentile(kept, 95), max(kept)], rel=1e-12)
            assert r.axes[axis].saturated_fraction == pytest.approx(saturated[:, c, a].sum() / n, abs=1e-15)
        assert r.firmware_spectral_radius.worst == radius[:, c].max()
        assert r.firmware_unstable_fraction == pytest.approx(np.count_nonzero(radius[:, c] >= 1) / n, abs=1e-15)
        assert r.continuous_unstable_fraction == pytest.approx(np.count_nonzero(max_real[:, c] >= 0) / n, abs=1e-15)
        assert r.continuous_max_real.median == pytest.approx(_percentile(list(max_real[:, c]), 50), rel=1e-12)
        d = r.firmware_min_damping                   # less is worse: its worst is the least
        assert [d.p5, d.worst] == pytest.approx([_percentile(list(damping[:, c]), 5), min(damping[:, c])], rel=1e-12)


def test_spread_of_nothing_is_nan_and_becomes_null_in_json():
    s = spread([np.nan, np.nan])
    assert all(np.isnan(v) for v in vars(s).values())
    assert s.as_dict() == dict.fromkeys(("p5", "median", "p95", "worst"))
    check_finite({"spread": s.as_dict()})                     # what emit refuses before printing
    assert json.loads(json.dumps(s.as_dict(), allow_nan=False)) == dict.fromkeys(("p5", "median", "p95", "worst"))


def test_batches_cover_the_samples_in_order():
    items = list(range(10))
    assert batches_of(items, 3) == [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9]]


# --- the simulation task ---------------------------------------------------------------------------

def test_a_sample_is_the_simulator_on_the_drawn_set(study, serial):
    """Sample 0 against the simulator run on the drawn parameters with the nominal schedule."""
    from rcm_kin.model import load_robot
    from rcm_kin.simulation.controllers import make_controller
    from rcm_kin.simulation.experiments import experiment_reference, psm_plant_and_schedule, start_hold
    from rcm_kin.simulation.loop import simulate, tracking_metrics
    from rcm_kin.simulation.plant import drive_train_plant

    seed = sample_seeds(SEED, SAMPLES)[0]
    drawn = with_values(study.params, study.uncertain, draw(study.uncertain, seed))
    plant = drive_train_plant(load_robot("psm"), drawn, 0.0025)
    _, schedule = psm_plant_and_schedule(study.params)
    reference = experiment_reference("sine", 0.0025, DURATION)
    run = simulate(plant.step, make_controller("scheduled", schedule), reference, initial=plant.initial,
                   hold=start_hold(reference, drawn))            # from the drawn robot's own steady hold
    metrics = tracking_metrics(run)
    outcome = serial.outcomes[0]
    assert outcome.max_error_deg[1] == pytest.approx([metrics["roll"].max_error_deg, metrics["pitch"].max_error_deg],
                                                     rel=1e-12)
    # the drawn plant differs from the nominal one: sample 0 is not the nominal run
    nominal_plant, _ = psm_plant_and_schedule(study.params)
    nominal = tracking_metrics(simulate(nominal_plant.step, make_controller("scheduled", schedule),
                                        experiment_reference("sine", 0.0025, DURATION), initial=nominal_plant.initial))
    assert nominal["roll"].max_error_deg != outcome.max_error_deg[1, 0]


def test_loop_margins_are_the_stability_survey_without_the_insertion_modes(params, monkeypatch):
    """The modes left out are the insertion's own loop (its 2 x 2 block, the coupling dropped, within
    1 %); with them back, the margins are ``stability_survey``'s (the project's survey, same grid)."""
    from rcm_kin.control.gain_schedule import closed_loop_matrix
    from rcm_kin.control.linearization import linearize_grid
    from rcm_kin.control.stability import firmware_loop_matrix, stability_survey
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.model import load_robot
    from rcm_kin.robustness import task
    from rcm_kin.simulation.experiments import psm_plant_and_schedule

    model = driven_dynamics(load_robot("psm"), params, coulomb=False)
    _, schedule = psm_plant_and_schedule(params)
    law = task.linear_law("scheduled", schedule)
    grid = linearize_grid(model, [[np.radians(20), np.radians(-15), schedule.insertion]])
    for matrix in (closed_loop_matrix, firmware_loop_matrix):
        full = matrix(grid.A[0], grid.B[0], *law(20.0, -15.0))
        kept = task.roll_pitch_modes(full)
        everything = np.linalg.eigvals(full)
        dropped = [w for w in everything if np.min(np.abs(kept - w)) > 1e-12]
        own = np.linalg.eigvals(full[np.ix_(task.INSERTION_STATES, task.INSERTION_STATES)])
        assert len(dropped) == 2 and len(kept) == len(everything) - 2
        assert np.sort_complex(np.array(dropped)) == pytest.approx(np.sort_complex(own), rel=1e-2)
    monkeypatch.setattr(task, "roll_pitch_modes", np.linalg.eigvals)     # every mode, as the survey takes them
    for name in ("scheduled", "thesis"):
        law = task.linear_law(name, schedule)
        survey = stability_survey(model, schedule, 3, gains=law)
        assert task.loop_margins(model, schedule, law, 3) == pytest.approx(
            (survey.max_real.max(), survey.spectral_radius.max(), survey.min_damping.min()), rel=1e-12)


def test_a_loop_without_integral_loses_only_the_integrator_mode(params):
    """P: the loops' eigenvalues are those of the reduced loops plus the integrator's 0 (s) and 1 (z)."""
    from rcm_kin.control.gain_schedule import closed_loop_matrix
    from rcm_kin.control.linearization import linearize_grid
    from rcm_kin.control.stability import firmware_loop_matrix
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.model import load_robot
    from rcm_kin.robustness.task import linear_law

    model = driven_dynamics(load_robot("psm"), params, coulomb=False)
    grid = linearize_grid(model, [[0.2, -0.1, 0.08]])
    k_roll, k_pitch = linear_law("p", None)(0.0, 0.0)
    for matrix, keep, mode in ((closed_loop_matrix, 6, 0.0), (firmware_loop_matrix, 9, 1.0)):
        full = matrix(grid.A[0], grid.B[0], k_roll, k_pitch)
        reduced = np.linalg.eigvals(full[:keep, :keep])
        assert np.all(full[:keep, keep] == 0)                  # nothing depends on the integral
        together = np.sort_complex(np.r_[reduced, mode])
        assert np.allclose(np.sort_complex(np.linalg.eigvals(full)), together, atol=1e-9)


# --- Dask: the same answer on any cluster ------------------------------------------------------------

def _environment() -> dict:
    """This process's environment with the rcm_kin under test first on the workers' path."""
    source = str(Path(rcm_kin.__file__).resolve().parents[1])
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([source] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    return env


class ExternalCluster:
    """``dask scheduler`` and two ``dask worker --no-nanny`` processes on 127.0.0.1."""

    def __init__(self, folder: Path, workers: int = 2):
        env = _environment()
        file = folder / "scheduler.json"
        dask = [sys.executable, "-m", "dask"]
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
        self.scheduler = subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                                  "--scheduler-file", str(file)], **quiet)
        deadline = time.monotonic() + 60
        while not file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.2)
        self.address = json.loads(file.read_text())["address"]
        self.workers = [subprocess.Popen(dask + ["worker", self.address, "--nthreads", "1", "--no-nanny",
                                                 "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{k}"], **quiet)
                        for k in range(workers)]

    def close(self):
        for p in self.workers + [self.scheduler]:
            if p.poll() is None:
                p.terminate()
        for p in self.workers + [self.scheduler]:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture
def cluster(tmp_path):
    """A cluster of the test's own (the kill test stops one of its workers)."""
    c = ExternalCluster(tmp_path)
    yield c
    c.close()


@pytest.fixture(scope="module")
def shared_cluster(tmp_path_factory):
    c = ExternalCluster(tmp_path_factory.mktemp("dask"))
    yield c
    c.close()


def _wait_for_workers(client, n: int):
    client.wait_for_workers(n, timeout=90)


def test_embedded_and_external_clusters_give_the_same_json(shared_cluster, serial, capsys, tmp_path):
    cluster = shared_cluster
    assert main(ARGS + ["--workers", "2"]) == 0
    embedded = capsys.readouterr().out
    from distributed import Client

    with Client(cluster.address) as client:
        _wait_for_workers(client, 2)
    assert main(ARGS + ["--scheduler", cluster.address]) == 0
    external = capsys.readouterr().out
    assert external == embedded
    payload = json.loads(embedded)
    assert payload["samples"] == SAMPLES
    assert set(payload["controllers"]) == set(CONTROLLERS)
    assert set(payload["controllers"]["p"]["roll"]["max_error_deg"]) == {"p5", "median", "p95", "worst"}
    # and both are the serial computation's
    expected = json.loads(json.dumps(serial.as_dict()))
    assert payload == expected
    # a sweep on the same external cluster
    assert main(["sweep", "psm", "counterweights", "--main-mass", "2", "3", "--dpm-mass", "1.65", "--points", "5",
                 "--scheduler", cluster.address, "--out", str(tmp_path), "--json"]) == 0
    sweep = json.loads(capsys.readouterr().out)
    assert [r["main_mass_kg"] for r in sweep["rows"]] == [2.0, 3.0]
    assert Path(sweep["table"]).is_file() and Path(sweep["figure"]).is_file()


def test_a_killed_worker_does_not_change_the_answer(cluster, study, serial):
    from distributed import Client

    samples = 6
    expected = summarise(study, SEED, run_batch(study, list(enumerate(sample_seeds(SEED, samples))))).as_dict()
    killed = []
    pids = {p.pid: p for p in cluster.workers}

    def kill_one(done: int):
        if killed:
            return
        busy = [w for w, tasks in client.processing().items() if tasks]
        if not busy:
            return
        pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
        assert pid in pids                                  # one of the processes this test started
        os.kill(pid, signal.SIGKILL)
        pids[pid].wait(timeout=20)
        killed.append(done)

    with Client(cluster.address) as client:
        _wait_for_workers(client, 2)
        result = run_robustness(study, samples, SEED, client, batch_size=1, progress=False, on_batch=kill_one)
        assert len(client.nthreads()) == 1
    assert killed and killed[0] < samples                   # killed while batches were left
    assert result.as_dict() == expected


def test_cli_errors_are_one_line(capsys):
    assert main(["robustness", "psm", "--controller", "p", "--experiment", "sine", "--samples", "0"]) == 2
    assert capsys.readouterr().err == "error: --samples: needs at least 1 and at most 1,000,000 samples, got '0'\n"
    assert main(["robustness", "mtm", "--controller", "p", "--experiment", "sine", "--samples", "2"]) == 2
    assert capsys.readouterr().err.startswith("error: ")
    assert main(ARGS + ["--seed", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --seed: needs at least 0") and err.count("\n") == 1
    assert main(ARGS + ["--skip", "1"]) == 2                 # the statistics would start after the run
    assert capsys.readouterr().err.startswith("error: the statistics start within the run")
    assert main(ARGS + ["--scheduler", "tcp://127.0.0.1:1", "--workers", "2"]) == 2
    assert capsys.readouterr().err.startswith("error: --workers sizes the embedded cluster")


class _Answers(socketserver.BaseRequestHandler):
    """A service that is not Dask's: reads what comes and answers with an HTTP error."""

    def handle(self):
        self.request.recv(4096)
        self.request.sendall(b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n")


class _Silent(socketserver.BaseRequestHandler):
    """A service that accepts and never answers (as `python -m http.server` does Dask's bytes)."""

    def handle(self):
        self.request.recv(4096)
        time.sleep(3)


@pytest.fixture
def tcp_server(request):
    """A throwaway TCP server on 127.0.0.1 (handler: the test's parameter); its tcp:// address."""
    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), request.param)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("tcp_server", [_Answers], indirect=True)
def test_a_service_that_is_not_a_scheduler_is_a_one_line_error(tcp_server, capsys):
    assert main(ARGS + ["--scheduler", tcp_server]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: cannot reach a Dask scheduler at {tcp_server}: ") and err.count("\n") == 1


@pytest.mark.parametrize("tcp_server", [_Silent], indirect=True)
def test_a_service_that_never_answers_is_refused_in_bounded_time(tcp_server):
    from rcm_kin.parallel import check_scheduler

    with pytest.raises(RcmKinError, match=r"cannot reach a Dask scheduler at .*: no Dask handshake within 0.5 s"):
        check_scheduler(tcp_server, seconds=0.5)


def test_work_is_checked_before_any_cluster_starts(monkeypatch, capsys, tmp_path):
    from rcm_kin.robustness import execution
    from rcm_kin.simulation.references import MAX_SAMPLES

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(execution, "dask_client", no_cluster)
    one = ["robustness", "psm", "--controller", "p", "--experiment", "sine"]
    # the simulator's own limit on one run: 10000 s at 400 Hz
    assert main(one + ["--samples", "1", "--duration", "10000"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: 10000 s at 400 Hz is 4,000,001 controller periods; the limit is "
                          f"{MAX_SAMPLES:,}") and err.count("\n") == 1
    # statistics that would start after the default sinusoid's 6 s
    assert main(one + ["--samples", "1", "--skip", "7"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: the statistics start within the run") and err.count("\n") == 1
    # the total: 10^6 samples x 1 controller x (6 s x 400 Hz + 1) periods of the default sinusoid
    assert main(one + ["--samples", "1000000"]) == 2
    assert capsys.readouterr().err.startswith("error: 1,000,000 samples x 1 controllers x 2,401 periods is "
                                              "2,401,000,000 controller periods to simulate")
    out = ["--out", str(tmp_path)]
    assert main(["sweep", "psm", "weights", "--duration", "600"] + out) == 2
    assert capsys.readouterr().err.startswith("error: 600 s at 400 Hz is 240,001 controller periods")
    masses = [str(m) for m in range(1, 31)]
    assert main(["sweep", "psm", "counterweights", "--main-mass", *masses, "--dpm-mass", *masses[:10],
                 "--points", "201"] + out) == 2
    assert capsys.readouterr().err.startswith("error: 30 x 10 masses x 201^2 points is 12,120,300 poses")


def test_an_error_on_a_worker_is_not_retried_and_leaves_stderr_quiet(capfd, tmp_path):
    from rcm_kin.parallel import dask_client, map_batches

    calls = tmp_path / "calls"

    def refuse(batch):          # pickled by value: a local function
        with open(calls, "a") as f:
            f.write("call\n")
        raise RcmKinError("refused on the worker")

    with dask_client(workers=1) as client:
        capfd.readouterr()
        with pytest.raises(RcmKinError, match="refused on the worker"):
            map_batches(client, refuse, [[1]], progress=False)
        err = capfd.readouterr().err
    assert calls.read_text() == "call\n"
    assert err == ""


def test_a_run_that_diverges_or_leaves_the_joint_range_is_unstable(params):
    from rcm_kin.errors import EngineFallbackWarning
    from rcm_kin.robustness.task import closed_loop_run
    from rcm_kin.simulation.controllers import make_controller
    from rcm_kin.simulation.experiments import SmoothPlant, experiment_reference, psm_plant_and_schedule
    from rcm_kin.simulation.firmware import FirmwareSettings

    settings = FirmwareSettings()
    _, schedule = psm_plant_and_schedule(params, settings.period)
    reference = experiment_reference("sine", settings.period, DURATION)
    def run(step):              # a plain step function has no compiled form: the readable loop, said once
        with pytest.warns(EngineFallbackWarning, match="SmoothPlant has no compiled form"):
            return closed_loop_run(SmoothPlant(step), make_controller("p", schedule), reference, settings)

    held = run(lambda x, u: x)                                              # stays at the first pose
    assert held is not None and np.array_equal(held.position[:, :2], np.degrees(np.tile(reference.position[0, :2],
                                                                                         (reference.time.size, 1))))
    assert run(lambda x, u: x + np.r_[0.01, 0, 0, 0, 0, 0]) is None          # finite, drifts out of the roll range
    assert run(lambda x, u: x * np.nan) is None                             # diverged


# --- design sweeps ----------------------------------------------------------------------------------

def test_counterweight_sweep_row_is_the_osmdv_design(params, tmp_path):
    from rcm_kin.hardware import DPM_COUNTERWEIGHT, MAIN_COUNTERWEIGHT
    from rcm_kin.robustness.sweeps import counterweight_batch, write_table
    from rcm_kin.statics.counterweights import osmdv_designs

    row, = counterweight_batch([(MAIN_COUNTERWEIGHT[0], DPM_COUNTERWEIGHT[0])], params, points=7)
    design = osmdv_designs(params, points=7).roll_and_pitch
    assert [row.main_distance_m, row.dpm_distance_m, row.rms_pwm_roll, row.rms_pwm_pitch] == pytest.approx(
        [design.main_distance, design.dpm_distance, *design.rms_pwm], rel=1e-12)
    table = write_table([row], tmp_path / "t.csv").read_text().splitlines()
    assert table[0].split(",")[:2] == ["main_mass_kg", "dpm_mass_kg"]
    assert float(table[1].split(",")[5]) == row.rms_pwm_roll


def test_report_section(shared_cluster, tmp_path):
    """The report's robustness section on the external cluster: a row per controller and axis, the
    figure linked relatively, the uncertainty table."""
    from distributed import Client

    from rcm_kin.report.render import render_section
    from rcm_kin.report.sections.robustness import robustness_section

    with Client(shared_cluster.address) as client:
        _wait_for_workers(client, 2)
        s = robustness_section(tmp_path, samples=2, duration=0.75, controllers=CONTROLLERS, client=client)
    assert [row[:2] for row in s.table.rows] == [(c, a) for c in CONTROLLERS for a in ("roll", "pitch")]
    assert any(row[0] == "drive_train.roll" for row in s.uncertainty.rows)    # the shipped file's fold sets
    html = render_section(s)
    assert f'src="{s.figure}"' in html and s.figure == "robustness/robustness_sine.png"
    assert (tmp_path / s.figure).stat().st_size > 0 and str(tmp_path) not in html


def test_weights_sweep_at_the_default_budgets_is_the_shipped_schedule(params):
    """Budgets 2 deg / the full PWM limit are the default weights: the row is `simulate`'s scheduled run."""
    from rcm_kin.control.weights import Weights
    from rcm_kin.robustness.sweeps import budget_weights, weights_batch
    from rcm_kin.simulation.experiments import run_experiment
    from rcm_kin.simulation.loop import tracking_metrics

    assert budget_weights(2.0, 1.0) == Weights()
    row, = weights_batch([(2.0, 1.0)], params, duration=DURATION, points=2)
    m = tracking_metrics(run_experiment("sine", "scheduled", DURATION, params))
    assert [row.max_error_roll_deg, row.max_error_pitch_deg, row.rms_pwm_pitch] == pytest.approx(
        [m["roll"].max_error_deg, m["pitch"].max_error_deg, m["pitch"].rms_pwm], rel=1e-12)
    softer, = weights_batch([(4.0, 0.5)], params, duration=DURATION, points=2)
    assert softer.rms_pwm_roll != row.rms_pwm_roll
    assert row.stable and row.spectral_radius < 1.0
    greedy, = weights_batch([(1e-9, 1.0)], params, duration=DURATION, points=2)   # an error budget no loop meets
    assert greedy.spectral_radius > 1.0 and not greedy.stable


def test_a_workers_warnings_reach_the_caller_once_each(capfd):
    """A Dask worker's warnings come back with its batch and are raised again in the caller (the
    CLI prints each as one warning line), not printed raw by the worker."""
    import warnings

    from rcm_kin.errors import CompilerFallbackWarning
    from rcm_kin.parallel import dask_client, map_batches

    def warn_and_sum(batch):    # pickled by value: a local function
        warnings.warn(f"batch of {len(batch)}", CompilerFallbackWarning)
        return sum(batch)

    with dask_client(workers=1) as client:
        capfd.readouterr()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert map_batches(client, warn_and_sum, [[1, 2], [3]], progress=False) == [3, 3]
        err = capfd.readouterr().err
    assert sorted(str(w.message) for w in caught if w.category is CompilerFallbackWarning) == [
        "batch of 1", "batch of 2"]
    assert "CompilerFallbackWarning" not in err
