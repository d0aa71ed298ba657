"""Property-based fuzzing of the command line (hypothesis): random argument lists for every sub-command,
drawn from valid, boundary and hostile values (NaN, inf, huge, empty, negative, wrong arity, wrong types,
odd paths, malformed TOML and CSV files). Every case must end with status 0 or 2, never a traceback; on
status 2 stderr is one line ``error: ...``; on status 0 ``--json`` output is strict JSON and text output
holds no NaN or infinity; every case finishes within ``CASE_SECONDS`` and ``CASE_BYTES`` of address space.

Deterministic in CI: ``derandomize=True`` and ``EXAMPLES`` cases per command. A longer run:
``RCM_KIN_FUZZ_EXAMPLES=2000 python -m pytest tests/cli/test_cli_fuzz.py``. A survey that records every
failing case instead of stopping at the first: ``RCM_KIN_FUZZ_SURVEY=findings.json`` (written at the end).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rcm_kin.cli import main

EXAMPLES = int(os.environ.get("RCM_KIN_FUZZ_EXAMPLES", "20"))   # cases per command
SURVEY = os.environ.get("RCM_KIN_FUZZ_SURVEY")
CASE_SECONDS = 30          # a case that runs longer has no bound on its work
CASE_BYTES = 8 << 30       # address space of the whole test process during a case

# words no argument of this CLI can accept: a case holding one must end with status 2
NEVER_VALID_NUMBERS = ["nan", "NaN", "inf", "-inf", "1e300", "-1e300", "abc", "", "1,5", "0x10", "1e400",
                       "-" + "9" * 400]
NUMBER_EDGES = ["0", "-0", "-1", "1e-300"]
NEVER_VALID_COUNTS = ["2.5", "nan", "abc", "", "10000000000", "99999999999999999999"]
COUNT_EDGES = ["0", "1", "-1", "100000"]
FINDINGS: list[dict] = []
NEVER_VALID: set[str] = set(NEVER_VALID_NUMBERS) | set(NEVER_VALID_COUNTS)


# --- files the cases point at ----------------------------------------------------------------------------
def _step_log(rows: int = 1200, bad: str | None = None) -> str:
    """A synthetic open-loop roll step (telemetry CSV): PWM -40 from 0.5 s, first-order angle response."""
    t = np.arange(rows) * 0.0025
    pwm = np.where(t >= 0.5, -40.0, 0.0)
    angle = np.where(t >= 0.5, 8.0 * (1 - np.exp(-(t - 0.5) / 0.2)), 0.0)
    lines = ["__time,/t/roll/position,/t/roll/velocity,/t/roll/effort,/t/pitch/position,/t/pitch/velocity"]
    for i, (ti, a, u) in enumerate(zip(t, angle, pwm)):
        value = bad if bad is not None and 600 <= i < 700 else f"{a:.6f}"
        lines.append(f"{ti:.4f},{value},{u:.1f},0,0.0,0.0")
    return "\n".join(lines) + "\n"


def _write_files(root: Path) -> dict[str, list[str]]:
    """The path pools: valid, boundary and hostile files of each kind, written into ``root``."""
    shipped = (Path(__file__).resolve().parents[2] / "urdf/psm_drive.toml").read_text()
    params = {"good": shipped,
              "nan": shipped.replace("volts_per_pwm = 0.117", "volts_per_pwm = nan  # 0.117", 1),
              "zero_gear": shipped.replace("gear_ratio = 20.0", "gear_ratio = 0.0", 1),
              "neg_res": shipped.replace("resistance = 0.582", "resistance = -1e300", 1),
              "inf_kt": shipped.replace("torque_constant = 0.0302", "torque_constant = inf", 1),
              "string": shipped.replace("coulomb = 1.0734", 'coulomb = "big"', 1),
              "bad_syntax": "[roll\ngear_ratio = = 3\n",
              "empty": ""}
    for name, text in params.items():
        (root / f"params_{name}.toml").write_text(text)
    (root / "binary.bin").write_bytes(bytes(range(256)) * 8)
    logs = {"good": _step_log(), "inf": _step_log(bad="inf"), "nan": _step_log(bad="nan"),
            "header": _step_log(rows=0), "short": _step_log(rows=3), "text": "hello\nworld\n"}
    (root / "logs").mkdir()
    for name, text in logs.items():
        (root / f"log_{name}.csv").write_text(text)
    (root / "logs" / "roll_step_response_roll_0_pitch_0.csv").write_text(logs["good"])
    bundled = Path(__file__).resolve().parents[2] / "src/rcm_kin/simulation/figure_eight.csv"
    shutil.copy(bundled, root / "trajectory.csv")
    (root / "trajectory_inf.csv").write_text("unix_time,x,y,z\n0,0,0,0.06\n0.01,inf,0,0.06\n0.02,0,0,0.06\n")
    (root / "unrelated.txt").write_text("someone's notes\n")
    (root / "empty_dir").mkdir()
    (root / "not_a_trajectory.csv").write_text(logs["good"])
    p = lambda *names: [str(root / n) for n in names]  # noqa: E731
    odd = ["", *p("missing/x", "binary.bin", "empty_dir"), "/dev/null", "/"]
    never = {"params": p(*(f"params_{n}.toml" for n in params if n != "good")) + odd,
             "log": p("log_inf.csv", "log_nan.csv", "log_header.csv", "log_short.csv", "log_text.csv") + odd,
             "trajectory": p("trajectory_inf.csv", "not_a_trajectory.csv") + odd,
             "out_file": ["", *p("unrelated.txt", "empty_dir", "missing/x/y.toml")],
             "out_dir": ["", *p("unrelated.txt")],
             "png": ["", *p("view.txt", "missing/x.png")], "html": ["", *p("empty_dir", "missing/x.html")],
             "xml": ["", *p("unrelated.txt", "empty_dir", "missing/x.xml")]}
    valid = {"params": p("params_good.toml"), "log": p("log_good.csv"), "trajectory": p("trajectory.csv"),
             "out_file": p("new.toml", "fresh.csv"), "out_dir": p("out_dir", "new_dir/deep"),
             "png": p("view.png"), "html": p("view.html"), "xml": p("model.xml")}
    NEVER_VALID.update(w for pool in never.values() for w in pool)
    return {kind: (valid[kind], never[kind]) for kind in valid}


# --- argument lists ----------------------------------------------------------------------------------------
def numbers(*valid: str) -> tuple[list[str], list[str]]:
    """A pool: (valid words, boundary and hostile words)."""
    return list(valid), NUMBER_EDGES + NEVER_VALID_NUMBERS


def counts(*valid: str) -> tuple[list[str], list[str]]:
    return list(valid), COUNT_EDGES + NEVER_VALID_COUNTS


def words(valid: list[str], hostile: list[str]) -> tuple[list[str], list[str]]:
    return list(valid), list(hostile)


def specs(files: dict[str, list[str]]) -> dict[str, dict]:
    """Per command: the words it starts with, its positionals (pools; a list pool of lists is nargs),
    its required and optional options (name -> pool, or None for a flag), the slow flag (a slow
    command gets at least one hostile value, so that CI does not run its minute-long work) and the
    share of the example budget (torque-map: half, each valid case draws three figures)."""
    robots = words(["psm", "mtm", "davinci"], ["kuka", "", "PSM"])
    joint_q = numbers("0", "0.1", "-0.2", "0.08", "30", "-30", "90", "0.5")
    params = {"--params": files["params"]}
    log = files["log"][0] + [str(Path(files["log"][0][0]).parent / "logs")], files["log"][1]
    return {
        "info": {"argv": ["info"], "pos": [robots], "opt": {"--json": None}},
        "fk": {"argv": ["fk"], "pos": [robots, joint_q, joint_q, joint_q], "opt": {"--deg": None, "--json": None}},
        "ik": {"argv": ["ik"], "pos": [robots, numbers("0.01", "0.02"), numbers("0.02", "0"),
                                       numbers("-0.07", "-0.06", "-0.2")],
               "opt": {"--rpy": [numbers("180", "0"), numbers("0", "10"), numbers("0", "-10")], "--deg": None,
                       "--json": None}},
        "gravity": {"argv": ["gravity"], "pos": [robots, joint_q, joint_q, joint_q],
                    "opt": {"--deg": None, "--no-counterweights": None, "--json": None, **params}},
        "torque-map": {"argv": ["torque-map", "psm"], "req": {"--out": files["out_dir"]}, "share": 0.5,
                       "opt": {"--roll": words(["-30:30:5", "0:10:2"],
                                               ["0:0:1", "-30:30:100000", "30:-30:5", "a:b:c", "", "nan:1:3",
                                                "0:1e300:3", "-1e300:1e300:3", "0:1:0"]),
                               "--pitch": words(["-30:30:4"], ["0:0:1", "5:5:1", "0:1:100000000", "::"]),
                               "--insertion": numbers("0.08", "0.05"), "--no-counterweights": None,
                               "--format": words(["csv", "npz"], ["parquet", "", "CSV"]), "--no-figures": None,
                               "--json": None, **params}},
        "calibrate": {"argv": ["calibrate"], "pos": [log], "slow": True, "guard": "--params={bad_params}",
                      "opt": {"--out": files["out_file"], "--json": None, **params}},
        "dynamics": {"argv": ["dynamics", "psm"], "req": {"--q": [joint_q, joint_q, joint_q]},
                     "opt": {"--v": [numbers("0", "1"), numbers("0"), numbers("0")],
                             "--u": [numbers("10", "255", "300"), numbers("-90"), numbers("0")],
                             "--no-coulomb": None, "--json": None, **params}},
        "linearize": {"argv": ["linearize", "psm"], "req": {"--roll": numbers("10", "-5"),
                                                             "--pitch": numbers("-5", "0")},
                      "opt": {"--insertion": numbers("0.08", "0.5"), "--no-coulomb": None, "--json": None,
                              **params}},
        "schedule": {"argv": ["schedule", "psm"], "req": {"--out": files["out_dir"]},
                     "opt": {"--grid": words(["thesis", "-10,10:-10,10"], ["0:0", "a:b", "", "1e300,0:0,1", "nan:0",
                                                                      ",".join(map(str, range(-30, 31))) + ":0"]),
                             "--insertion": numbers("0.08"), "--gravity-feedforward": None,
                             "--friction-feedforward": None, "--friction-ramp": numbers("5"),
                             "--check-points": counts("2", "3"), "--roll-error-deg": numbers("1"),
                             "--json": None, **params}},
        "simulate": {"argv": ["simulate", "psm"],
                     "req": {"--experiment": words(["sine", "step", "target"], ["x"]),
                             "--controller": words(["p", "pid", "scheduled", "thesis", "lqr-fixed"], ["none"])},
                     "opt": {"--duration": numbers("0.5", "1", "1e6"), "--rate": numbers("400", "100", "5", "1e9"),
                             "--trajectory": files["trajectory"],
                             "--pwm-limit": [numbers("100"), numbers("100"), numbers("100")],
                             "--skip": numbers("0.1", "10"), "--noise-counts": numbers("1"),
                             "--seed": counts("0", "3"), "--plot": files["out_dir"], "--json": None, **params}},
        "sysid": {"argv": ["sysid"], "pos": [log], "req": {"--joint": words(["roll", "pitch"], ["yaw"])},
                  "opt": {"--method": words(["step", "prbs"], ["x"]), "--order": counts("2", "3"),
                          "--zeros": counts("0", "1"), "--samples": counts("50", "400", "1000"),
                          "--segment": counts("100", "500"), "--pose": [numbers("0"), numbers("0")],
                          "--out": files["out_dir"], "--json": None, **params}},
        "greybox": {"argv": ["greybox"], "pos": [log], "req": {"--joint": words(["roll", "pitch"], ["yaw"])},
                    "slow": True, "guard": "--params={bad_params}",
                    "opt": {"--samples": counts("50", "400"), "--out": files["out_file"], "--json": None, **params}},
        "identify": {"argv": ["identify", "psm"], "pos": [log], "req": {"--out": files["out_file"]},
                     "slow": True, "guard": "--params={bad_params}",
                     "opt": {"--joint": words(["roll", "pitch"], ["yaw"]), "--seed": counts("0"), "--force": None,
                             "--json": None, **params}},
        "predict": {"argv": ["predict", "psm"], "pos": [log], "req": {"--joint": words(["roll", "pitch"], ["yaw"])},
                    "opt": {"--plot": files["png"], "--band": numbers("0.9", "0.5"), "--json": None, **params}},
        "excite": {"argv": ["excite", "psm"], "req": {"--duration": numbers("10", "1", "600"),
                                                      "--out": files["out_file"]},
                   "slow": True, "guard": "--params={bad_params}",
                   "opt": {"--joint": words(["roll", "pitch"], ["yaw"]), "--harmonics": counts("2", "20"),
                           "--seed": counts("0"), "--force": None, "--json": None, **params}},
        "view": {"argv": ["view"], "pos": [robots], "req": {"--png": files["png"]},
                 "opt": {"--q": [joint_q, joint_q, joint_q], "--deg": None,
                         "--frames": words(["rcm", "tool_tip"], ["nope"]), "--html": files["html"], "--json": None}},
        "safety simulate": {"argv": ["safety", "simulate"],
                            "pos": [words(["ellipsoid", "slide", "heart", "psm"], ["x"])],
                            "opt": {"--filter": words(["blend", "qp", "none"], ["x"]),
                                    "--kappa": numbers("1", "0.01", "1e-9"),
                                    "--trajectory": files["trajectory"], "--json": None}},
        "safety certify": {"argv": ["safety", "certify"], "pos": [words(["1", "2", "3", "4"], ["5", "0"])],
                           "opt": {"--delta": numbers("0.001", "0.015"), "--error-bound": numbers("0.007"),
                                   "--r-max": numbers("0.017"), "--eps-bar": numbers("0.001"), "--json": None}},
        "report": {"argv": ["report"], "req": {"--out": files["out_dir"]}, "slow": True, "guard": "--map-points=0",
                   "opt": {"--data": files["log"], "--map-points": counts("3", "61"), "--json": None}},
        "export": {"argv": ["export"], "pos": [robots], "share": 0.5,
                   "opt": {"--mjcf": files["xml"], "--c": files["out_dir"], "--force": None, "--json": None, **params}},
        "robustness": {"argv": ["robustness", "psm"], "slow": True, "guard": "--params={bad_params}",
                       "req": {"--controller": words(["p", "scheduled", "thesis"], ["none"]),
                               "--experiment": words(["sine", "target"], ["x"]), "--samples": counts("2", "4")},
                       "opt": {"--seed": counts("0", "7"), "--duration": numbers("0.5", "1e6"),
                               "--skip": numbers("0.1", "10"), "--workers": counts("1", "2"),
                               "--batch-size": counts("1", "3"), "--out": files["out_dir"], "--json": None,
                               **params}},
        "sweep": {"argv": ["sweep", "psm"], "pos": [words(["counterweights", "weights"], ["x"])],
                  "req": {"--out": files["out_dir"]}, "slow": True, "guard": "--params={bad_params}",
                  "opt": {"--points": counts("3", "5"), "--main-mass": [numbers("0.5"), numbers("1.0")],
                          "--duration": numbers("0.5", "3"), "--workers": counts("1"), "--json": None, **params}},
    }


@st.composite
def argv_of(draw, spec: dict) -> list[str]:
    """One argument list for ``spec``: its words, positionals, required and some optional options; each
    value valid with probability 3/4, else a boundary or hostile one; sometimes a word dropped or one
    too many (wrong arity)."""
    argv = list(spec["argv"])

    def pick(pool):
        valid, hostile = pool
        return draw(st.sampled_from(hostile if draw(st.integers(0, 3)) == 3 else valid))

    for pool in spec.get("pos", []):
        argv.append(pick(pool))
    chosen = dict(spec.get("req", {}))
    optional = sorted(spec.get("opt", {}))
    chosen.update({k: spec["opt"][k] for k in draw(st.lists(st.sampled_from(optional), unique=True, max_size=4))})
    for name, pool in chosen.items():
        if pool is None:
            argv.append(name)
        elif isinstance(pool, list):              # nargs: one word per pool
            argv += [name] + [pick(p) for p in pool]
        else:
            argv.append(f"{name}={pick(pool)}")
    arity = draw(st.sampled_from(["ok"] * 8 + ["drop", "extra"]))
    if arity == "drop" and len(argv) > len(spec["argv"]):
        argv.pop(draw(st.integers(len(spec["argv"]), len(argv) - 1)))
    elif arity == "extra":
        argv.append(draw(st.sampled_from(["0", "x", "--nope", "nan"])))
    return argv


def never_valid(argv: list[str]) -> list[str]:
    """The words of ``argv`` that no argument accepts (a value after ``=`` counts as a word)."""
    return [w for w in argv if w in NEVER_VALID or (w.startswith("--") and w.split("=", 1)[-1] in NEVER_VALID
                                                    and "=" in w)]


# --- running a case --------------------------------------------------------------------------------------
class _Unbounded(Exception):
    """A case ran past CASE_SECONDS."""


class _WouldServe(Exception):
    """``view`` without a file reached the live meshcat server (which would run until stopped)."""


def _alarm(signum, frame):
    raise _Unbounded(f"ran longer than {CASE_SECONDS} s")


def run_case(argv: list[str]) -> dict:
    """``main(argv)`` in-process: status, stdout, stderr (warnings as the console would show them), seconds."""
    out, err = io.StringIO(), io.StringIO()
    show = lambda m, c, f, n, file=None, line=None: err.write(warnings.formatwarning(m, c, f, n, line))  # noqa: E731
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    start = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CASE_SECONDS)
    status, crash = None, None
    try:
        resource.setrlimit(resource.RLIMIT_AS, (CASE_BYTES if hard == resource.RLIM_INFINITY else min(hard, CASE_BYTES),
                                                hard))
        with warnings.catch_warnings(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            warnings.simplefilter("default")
            warnings.showwarning = show
            try:
                status = main(argv)
            except _WouldServe:               # the valid end of ``view`` without --png/--html
                status = 0
            except SystemExit as exc:
                status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    except (_Unbounded, MemoryError) as exc:
        crash = f"{type(exc).__name__}: {exc}"
    except BaseException as exc:  # noqa: BLE001 - the finding is any exception that escapes main
        crash = f"traceback {type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    return {"status": status, "crash": crash, "out": out.getvalue(), "err": err.getvalue(),
            "seconds": time.perf_counter() - start}


def _reject_constant(name: str):
    raise ValueError(f"not strict JSON: {name}")


NULL_BY_CONTRACT = {"certificate", "segment_samples"}   # JSON keys whose null means "none", not a failed number
NON_FINITE_TEXT = re.compile(r"(?<![\w.])[-+]?(nan|inf|infinity)(?![\w])", re.IGNORECASE)


def _nulls(value, where: str = "") -> list[str]:
    """Where ``value`` (parsed JSON) holds null, but for keys that are null by contract."""
    if isinstance(value, dict):
        return [w for k, v in value.items() if k not in NULL_BY_CONTRACT for w in _nulls(v, f"{where}.{k}")]
    if isinstance(value, list):
        return [w for i, v in enumerate(value) for w in _nulls(v, f"{where}[{i}]")]
    return [where or "."] if value is None else []


def problems(argv: list[str], result: dict) -> list[str]:
    """What is wrong with the outcome of one case (empty: the contract holds)."""
    if result["crash"]:
        return [result["crash"]]
    found = []
    status, out, err = result["status"], result["out"], result["err"]
    if status not in (0, 2):
        found.append(f"exit status {status}")
    if result["seconds"] > CASE_SECONDS:        # the alarm cannot interrupt every native call
        found.append(f"ran {result['seconds']:.0f} s")
    if "Traceback" in err:
        found.append("traceback on stderr")
    if status == 2 and not (err.startswith("error: ") and err.count("\n") == 1):
        found.append(f"stderr not one 'error:' line: {err[:300]!r}")
    if status == 0 and never_valid(argv):
        found.append(f"accepted {never_valid(argv)[0][:60]!r}")
    if status == 0 and "--json" in argv and "--help" not in argv:
        try:
            nulls = _nulls(json.loads(out, parse_constant=_reject_constant))
            if nulls:
                found.append(f"null (a non-finite number?) in the JSON at {nulls[0]}")
        except ValueError as exc:
            found.append(f"--json output not strict JSON ({str(exc)[:100]})")
    elif status == 0 and NON_FINITE_TEXT.search(out):
        found.append(f"non-finite number in the output: {NON_FINITE_TEXT.search(out).group(0)}")
    return found


# --- the tests ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A folder of input files, made the working directory (so an empty path writes there, not in the repo)."""
    root = tmp_path_factory.mktemp("fuzz")
    files = _write_files(root)
    cwd = os.getcwd()
    os.chdir(root)
    yield files
    os.chdir(cwd)
    if SURVEY:
        Path(SURVEY).write_text(json.dumps(FINDINGS, indent=1))


@pytest.fixture(scope="module")
def no_server():
    """``view`` without a file serves until stopped: a case ends (status 0) where the server would start,
    so that a hostile ``--png ''`` that falls through to serving is seen as accepted."""
    import meshcat

    original = meshcat.Visualizer

    def refuse(*args, window=None, **kwargs):
        if window is None:
            raise _WouldServe
        return original(*args, window=window, **kwargs)

    meshcat.Visualizer = refuse
    yield
    meshcat.Visualizer = original


COMMANDS = ["info", "fk", "ik", "gravity", "torque-map", "calibrate", "dynamics", "linearize", "schedule",
            "simulate", "sysid", "greybox", "identify", "predict", "excite", "view", "safety simulate",
            "safety certify", "report", "export", "robustness", "sweep"]


@pytest.mark.parametrize("command", COMMANDS)
def test_fuzz_command(command, workspace, no_server):
    spec = specs(workspace)[command]

    @settings(max_examples=max(1, round(EXAMPLES * spec.get("share", 1))), derandomize=True, deadline=None,
              database=None, print_blob=False,
              suppress_health_check=list(HealthCheck))
    @given(argv_of(spec))
    def case(argv):
        if spec.get("slow") and not never_valid(argv):
            argv = argv + [spec["guard"].format(bad_params=workspace["params"][1][0])]
        result = run_case(argv)
        found = problems(argv, result)
        if SURVEY:
            FINDINGS.append({"command": command, "argv": argv, "status": result["status"],
                             "seconds": round(result["seconds"], 2), "problems": found, "err": result["err"][-300:]})
            return
        assert not found, f"rcm-kin {' '.join(repr(w) for w in argv)}: {found}"

    case()


@pytest.mark.parametrize("argv, status", [
    (["torque-map", "psm", "--roll=0:0:1", "--pitch=nan:1:3", "--out", "maps"], 2),
    (["dynamics", "psm", "--q", "0", "0", "0.08", "--v", "1e300", "0", "0", "--json"], 2),
    (["simulate", "psm", "--experiment", "sine", "--controller", "p", "--rate", "5"], 2),
    (["--version"], 0),
])
def test_console_script_one_line(argv, status, tmp_path):
    """A few cases through the installed entry point, as users call it: the status, no traceback, one
    stderr line on an error."""
    result = subprocess.run([sys.executable, "-m", "rcm_kin.cli", *argv], capture_output=True, text=True,
                            cwd=tmp_path, timeout=120)
    assert result.returncode == status and "Traceback" not in result.stderr, result.stderr
    if status == 2:
        assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1 and not result.stdout
    else:
        assert result.stdout.startswith("rcm-kin ")


# --- hostile file systems and signals (issue 28's classes) -------------------------------------------------
OUTPUT_COMMANDS = {   # argv with {out}, the file it writes there, whether {out} is a folder
    "torque-map": (["torque-map", "psm", "--roll=-5:5:5", "--pitch=-5:5:5", "--out", "{out}", "--no-figures"],
                   "torque_map.csv", True),
    "simulate --plot": (["simulate", "psm", "--experiment", "sine", "--controller", "p", "--duration", "1", "--plot",
                         "{out}"], "sine_p.png", True),
    "export --mjcf": (["export", "psm", "--mjcf", "{out}"], None, False),
}
HAZARDS = ["user file in the way", "link out of the folder", "subfolder link out", "folder in use",
           "file where the folder goes", "leftover temporary", "none"]


def _hazard(hazard: str, root: Path, folder: bool, name: str | None, stack: contextlib.ExitStack) -> tuple[Path, int]:
    """Set ``hazard`` up under ``root``: the output path to give and the status the run must end with."""
    from rcm_kin.atomic import claim

    out = root / ("out" if folder else "out.xml")
    target = out / name if folder else out
    (root / "notes.txt").write_text("the user's\n")
    if hazard == "user file in the way":
        out.mkdir() if folder else None
        target.write_text("the user's\n")
        return out, 2
    if hazard == "link out of the folder":
        out.mkdir() if folder else None
        target.symlink_to(root / "notes.txt")
        return out, 2
    if hazard == "subfolder link out":
        (root / "elsewhere").mkdir()
        (root / "elsewhere" / (name or "out.xml")).write_text("the user's\n")
        if not folder:
            (root / "deep").symlink_to(root / "elsewhere")
            return root / "deep" / "out.xml", 2         # an existing file through a linked folder
        out.mkdir()
        (out / "sub").symlink_to(root / "elsewhere")
        return out, 0                                   # the command writes beside the link, not through it
    if hazard == "folder in use":
        stack.enter_context(claim(out if folder else root, folder=True))
        return out, 2 if folder else 0
    if hazard == "file where the folder goes":
        out.write_text("the user's\n") if folder else out.mkdir()
        return out, 2
    if hazard == "leftover temporary":
        out.mkdir() if folder else None
        (out if folder else root).joinpath(".x.0011aabb.partial.csv").write_text("half")
        return out, 0
    return out, 0


@pytest.mark.parametrize("hazard", HAZARDS)
@pytest.mark.parametrize("command", OUTPUT_COMMANDS)
def test_fuzz_outputs_on_a_hostile_file_system(command, hazard, tmp_path):
    """Every hazard ends as it must: refused in one line with the user's files untouched, or written."""
    argv_template, name, folder = OUTPUT_COMMANDS[command]
    with contextlib.ExitStack() as stack:
        out, status = _hazard(hazard, tmp_path, folder, name, stack)
        before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file() and not p.is_symlink()}
        result = run_case([w.format(out=out) for w in argv_template])
    assert result["crash"] is None and result["status"] == status, (hazard, result)
    if status == 2:
        assert result["err"].startswith("error: ") and result["err"].count("\n") == 1, (hazard, result["err"])
        assert all(p.read_bytes() == data for p, data in before.items()), hazard     # nothing of theirs touched
    else:
        assert (out / name if folder else out).is_file(), hazard
        assert all(p.read_bytes() == data for p, data in before.items() if p.parent != out), hazard


@pytest.mark.slow
def test_fuzz_sigterm_at_any_moment_leaves_a_whole_file_or_none(tmp_path):
    """SIGTERM at random moments of a torque map: status 143 with no table, or 0 with the whole table
    (or, during the imports before the command begins or the interpreter's exit after it ended, the
    signal's default: nothing written and nothing said, or the whole table)."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src"), "OPENBLAS_NUM_THREADS": "1"}

    @settings(max_examples=6, derandomize=True, deadline=None, database=None, print_blob=False,
              suppress_health_check=list(HealthCheck))
    @given(st.floats(0.3, 4.0))
    def case(delay):
        out = tmp_path / f"maps_{delay:.3f}"
        child = subprocess.Popen([sys.executable, "-m", "rcm_kin.cli", "torque-map", "psm", "--roll=-30:30:301",
                                  "--pitch=-30:30:301", "--out", str(out), "--no-figures"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        time.sleep(delay)
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=60)
        table = out / "torque_map.csv"
        if child.returncode == -signal.SIGTERM:       # killed before the command began, or after it ended
            assert (not out.exists() and not err) or len(table.read_text().splitlines()) == 301 * 301 + 1
        elif child.returncode == 143:
            assert err.strip().splitlines()[-1].startswith("error: terminated (SIGTERM)")
            assert not table.exists() or len(table.read_text().splitlines()) == 301 * 301 + 1
        else:
            assert child.returncode == 0 and len(table.read_text().splitlines()) == 301 * 301 + 1
        assert not any("partial" in p.name for p in out.glob("*")) if out.exists() else True

    case()
