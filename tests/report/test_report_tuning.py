"""The report's section on the gains tuned by simulation: the fresh runs on the nominal robot are the
simulations themselves, the study's numbers are the JSON's, the choice and its reason follow the
scores, and the template names the chosen design and the command that reproduces it.

The study here is a small synthetic one in the format of ``DesignStudy.to_dict`` (written out, not
computed by the code under test), with a gain file of a known design; the shipped pair is checked
when it is there."""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.report.render import render_section

LINK = re.compile(r'(?:href|src)="([^"#]+)"')
CONTROLLERS = ("thesis", "lqr", "fixed", "scheduled")
SETS = ("tuning", "held_out")
COMMAND = "rcm-kin schedule psm --tune --generations 12 --budget 600 --out tuned"     # the synthetic study's
SHIPPED_COMMAND = "rcm-kin schedule psm --tune --generations 20 --budget 600 --out tuned"   # urdf/psm_tuned/README.md
DESIGN = {"roll_kp": 400.0, "roll_kd": -8.0, "pitch_kp": 300.0, "pitch_kd": -1.0, "pitch_ki": 500.0,
          "roll_friction_pwm": 5.0, "pitch_friction_pwm": 15.0, "friction_ramp_deg_s": 1.5, "pitch_feedforward": 1.0}
DRAWS = 64
SLOPES = {"roll_kp_roll_slope": 0.0, "roll_kp_pitch_slope": 0.0, "pitch_kp_roll_slope": 0.0,
          "pitch_kp_pitch_slope": 0.0}


def _space(kind: str) -> list[dict]:
    names = list(DESIGN) + (list(SLOPES) if kind == "scheduled" else [])
    units = {"roll_kp": "PWM/deg", "pitch_kp": "PWM/deg", "roll_kd": "PWM/(deg/s)", "pitch_kd": "PWM/(deg/s)",
             "pitch_ki": "PWM/(deg s)", "roll_friction_pwm": "PWM", "pitch_friction_pwm": "PWM",
             "friction_ramp_deg_s": "deg/s"}
    return [{"name": n, "low": 0.0, "high": 1000.0, "unit": units.get(n, "1"), "reason": f"why {n}", "log": False}
            for n in names]


def _judged(scale: float, radius, seed: int) -> dict:
    errors = np.random.default_rng(seed).uniform(0.05, 0.5, (DRAWS, 2, 2)) * scale
    return {"summary": {}, "spectral_radius": radius, "score": None,
            "per_draw": {"max_error_deg": errors.tolist(), "mean_error_deg": (errors / 3).tolist(),
                         "saturation_s": np.zeros((DRAWS, 2, 2)).tolist(),
                         "unstable": np.zeros((DRAWS, 2), bool).tolist()},
            "per_draw_axes": ["draw", "experiment", "axis (roll, pitch)"]}


def synthetic_study(scheduled_scores=(0.299, 0.297), chosen="fixed") -> dict:
    """A study of 64 draws per set: the fixed design DESIGN, the scheduled one DESIGN with flat slopes,
    scores as written here."""
    scores = {"tuning": {"thesis": 2.0, "lqr": 4.1, "fixed": 0.30, "scheduled": scheduled_scores[0]},
              "held_out": {"thesis": 2.0, "lqr": 3.9, "fixed": 0.31, "scheduled": scheduled_scores[1]}}
    radius = {"thesis": None, "lqr": 0.990081, "fixed": 0.996403, "scheduled": 0.996403}
    judged = {d: {c: {**_judged({"thesis": 1.0, "lqr": 2.0}.get(c, 0.2), radius[c], k), "score": scores[d][c]}
                  for k, c in enumerate(CONTROLLERS)} for d in SETS}
    variants = {"design without friction compensation": (0.47, 0.996403, 0),
                "thesis law": (115.2, 1.012222, 0), "thesis law, Kd flipped (damping)": (104.1, 0.9999972, 0)}
    structures = {d: {name: {"score": s, "spectral_radius": r, "unstable_runs": u, "summary": {}}
                      for name, (s, r, u) in variants.items()} for d in SETS}
    searches = {kind: {"values": {**DESIGN, **(SLOPES if kind == "scheduled" else {})}, "score_tuning_subset": 0.29,
                       "evaluations": 100 * (k + 1), "generations": 12, "wall_s": 150.0 + k, "stopped": "generations",
                       "runs_per_s": 80.0, "history": [1.0, 0.5], "space": _space(kind)}
                for k, kind in enumerate(("fixed", "scheduled"))}
    designs = {"fixed": dict(DESIGN), "scheduled": {**DESIGN, **SLOPES}}
    return {"seeds": {"tuning": 0, "held_out": 1}, "samples": DRAWS, "tune_samples": 16,
            "rejected_as_inconsistent_with_holds": [5, 7], "stability_points": 41, "radius_limit": 0.999,
            "chosen": chosen, "experiments": ["sine", "target"], "schedule_margin": 0.02, "scores": scores,
            "values": designs[chosen],
            "criteria": {"tuning": {"median_at_or_below_thesis": True, "worst_no_worse": True,
                                    "no_unstable_run": True, "frozen_loop_stable": True, "saturation_no_more": True},
                         "held_out": {"median_at_or_below_thesis": True, "worst_no_worse": False,
                                      "no_unstable_run": True, "frozen_loop_stable": True,
                                      "saturation_no_more": True}},
            "searches": searches, "structures": structures, "budget_s": 600.0, "generations_limit": 12,
            "designs": designs, "judged": judged}


@pytest.fixture(scope="module")
def gain_file(tmp_path_factory):
    """gains.json of DESIGN on the nominal LQR/LQI schedule, as `schedule psm --tune` writes it."""
    from rcm_kin.codegen.firmware_export import write_gain_schedule
    from rcm_kin.simulation.experiments import psm_schedule
    from rcm_kin.tuning.design import tuned_schedule

    folder = tmp_path_factory.mktemp("gains")
    write_gain_schedule(tuned_schedule(psm_schedule(), DESIGN), folder, gravity_feedforward=True,
                        friction_feedforward=True)
    return folder / "gains.json"


def _write(folder, study: dict):
    path = folder / "tuning.json"
    path.write_text(json.dumps(study))
    return path


@pytest.fixture(scope="module")
def built(tmp_path_factory, gain_file):
    """The section of the synthetic study (fixed chosen) and its report folder."""
    from rcm_kin.report.sections.tuning import tuning_section

    out = tmp_path_factory.mktemp("report")
    study = synthetic_study()
    return out, study, tuning_section(out, _write(tmp_path_factory.mktemp("study"), study), gain_file)


def _rows(table, key_columns: int = 1) -> dict:
    return {tuple(row[:key_columns]) if key_columns > 1 else row[0]: row[key_columns:] for row in table.rows}


def test_fresh_runs_are_the_simulations(built, gain_file):
    """The nominal robot's table: the thesis law's and the tuned file's rows are tracking_metrics
    from 1 s of run_experiment, called here."""
    from rcm_kin.simulation.experiments import run_experiment
    from rcm_kin.simulation.loop import tracking_metrics

    s = built[2]
    assert len(s.fresh.rows) == 2 * 3 * 2 and s.skip_s == 1.0
    rows = {(e, c.split(" ")[0], a): row for e, c, a, *row in s.fresh.rows}
    for experiment in ("sine", "target"):
        for name, label in (("thesis", "thesis"), ("tuned", "tuned"), ("scheduled-friction", "LQR/LQI")):
            run = run_experiment(experiment, name, gains=gain_file if name == "tuned" else None)
            for axis, m in tracking_metrics(run, 1.0).items():
                shown = [float(c) for c in rows[(experiment, label, axis)]]
                assert shown == pytest.approx([m.max_error_deg, m.mean_error_deg, m.saturation_s], abs=5.1e-4)


def test_the_studys_numbers_are_shown(built):
    from rcm_kin.tuning.figures import LABELS

    _, study, s = built
    scores = _rows(s.scores)
    for c in CONTROLLERS:
        label = LABELS[c] + (" (chosen)" if c == "fixed" else "")
        shown = scores[label]
        assert [float(v) for v in shown[:2]] == pytest.approx([study["scores"][d][c] for d in SETS], rel=1e-3)
        radius = [study["judged"][d][c]["spectral_radius"] for d in SETS]
        assert shown[2:] == (("n/a", "n/a") if c == "thesis" else tuple(f"{r:.6f}" for r in radius))
    assert _rows(s.criteria)["no unstable run"] == ("yes", "yes")
    assert _rows(s.criteria)["the worst draw's max error no worse"] == ("yes", "NO")
    values = _rows(s.values)
    assert list(values) == list(DESIGN)
    assert float(values["pitch_ki"][0]) == 500.0 and values["pitch_ki"][1] == "PWM/(deg s)"
    assert values["roll_kd"][3] == "why roll_kd"
    structures = _rows(s.structures)
    assert float(structures["thesis law"][1]) == 115.2 and structures["thesis law"][-1] == "frozen-loop radius >= 0.999"
    assert structures["thesis law, Kd flipped (damping)"][4] == "0.999997"
    assert structures["design without friction compensation"][-1] == ""
    assert s.draws["rejected"] == {"tuning": 5, "held_out": 7} and s.draws["samples"] == DRAWS
    assert [row[:3] for row in s.search.rows] == [("fixed", "12", "100"), ("scheduled", "12", "200")]
    assert s.command == COMMAND and s.machine_independent


def test_the_gain_tables_are_the_files(built, gain_file):
    """The tuned columns are the gain file's tables, the thesis's columns its Tables 4.4-4.8."""
    from rcm_kin.thesis import K_PITCH, K_ROLL

    raw = json.loads(gain_file.read_text())
    s = built[2]
    assert len(s.gains.rows) == 15
    kp_roll = [[float(c) for c in row[2:]] for row in s.gains.rows[:3]]
    np.testing.assert_allclose(np.array(kp_roll)[:, :3], np.array(raw["k_roll"])[..., 0], rtol=1e-3)
    np.testing.assert_allclose(np.array(kp_roll)[:, 3:], K_ROLL[..., 0], rtol=1e-3)
    ki = [[float(c) for c in row[2:]] for row in s.gains.rows[12:]]
    np.testing.assert_allclose(np.array(ki)[:, 3:], K_PITCH[..., 2], rtol=1e-3)
    assert s.shipped_is_chosen


def test_the_template_says_the_choice_and_the_command(built):
    out, _, s = built
    html = render_section(s)
    links = set(LINK.findall(html))
    assert {"tuning.png", "tuning_gains.png", "tuned_gains/gains.json", "tuned_gains/tuning.json"} <= links
    for link in links:
        assert not link.startswith("/") and "://" not in link and ".." not in link, link
        assert (out / link).stat().st_size > 0, link
    assert str(out) not in html
    assert "Chosen: tuned, one gain set." in html and "One gain set is as good on this robot" in html
    assert "+0.3 % on the tuning draws" not in html and "-0.3 % on the tuning draws" in html
    assert "every Kp slope at 0: it is itself one gain\nset, the fixed design." in html and s.same_designs
    assert f"<code>{COMMAND}</code>" in html
    assert "Which part does the work" in html and "same penalties" in html
    assert "does not hold the study's chosen design" not in html


def test_a_schedule_that_wins_is_chosen(tmp_path, gain_file):
    """Scheduled 2 % or more below one gain set on both draw sets: the scheduled design, said so;
    a study whose choice does not follow its scores is refused."""
    from rcm_kin.report.sections.tuning import tuning_section

    study = synthetic_study((0.25, 0.29), chosen="scheduled")
    study["designs"]["scheduled"]["roll_kp_roll_slope"] = 0.1
    s = tuning_section(tmp_path, _write(tmp_path, study), gain_file)
    assert s.chosen == "scheduled" and not s.flat_schedule and not s.same_designs and not s.shipped_is_chosen
    assert s.scheduled_against_fixed == pytest.approx({"tuning": 0.25 / 0.30 - 1, "held_out": 0.29 / 0.31 - 1})
    html = render_section(s)
    assert "Chosen: tuned, scheduled." in html and "at least 2 % below one gain set" in html
    assert "One gain set is as good" not in html and "does not hold the study's chosen design" in html
    with pytest.raises(RcmKinError, match="scores do not give"):
        tuning_section(tmp_path, _write(tmp_path, synthetic_study((0.299, 0.297), chosen="scheduled")), gain_file)


def test_an_early_study_without_structures_or_budget(tmp_path, gain_file):
    """A study written before the structures, the budget and the generation limit were recorded."""
    from rcm_kin.report.sections.tuning import reproducing_command, tuning_section

    study = copy.deepcopy(synthetic_study())
    for key in ("structures", "designs", "budget_s", "generations_limit"):
        del study[key]
    s = tuning_section(tmp_path, _write(tmp_path, study), gain_file)
    assert s.structures is None and s.budget_s is None and s.command == "rcm-kin schedule psm --tune --out tuned"
    assert "Which part does the work" not in render_section(s)
    study.update(samples=32, tune_samples=8, seeds={"tuning": 4, "held_out": 5}, budget_s=float("nan"))
    assert reproducing_command(study) == ("rcm-kin schedule psm --tune --draws 32 --tune-draws 8 --seed 4 "
                                          "--check-seed 5 --out tuned")


def test_the_report_runs_the_section(tmp_path):
    from rcm_kin.report import report_jobs

    labels = [job.label for job in report_jobs(tmp_path, None, 3)]
    assert "gains tuned by simulation" in labels


def test_the_shipped_study_and_gains(tmp_path):
    """The shipped pair: the gain file holds the study's chosen design, the scores are the JSON's."""
    from rcm_kin.control.schedule_file import SHIPPED_TUNED
    from rcm_kin.report.sections.tuning import tuning_section
    from rcm_kin.tuning.study import SHIPPED_STUDY

    if not (SHIPPED_STUDY.is_file() and SHIPPED_TUNED.is_file()):
        pytest.skip("the shipped tuned design (urdf/psm_tuned) is not written yet")
    study = json.loads(SHIPPED_STUDY.read_text())
    s = tuning_section(tmp_path)
    assert s.shipped_is_chosen and s.chosen == study["chosen"] and s.command == SHIPPED_COMMAND
    chosen = [row for row in s.scores.rows if row[0].endswith("(chosen)")]
    assert [float(v) for v in chosen[0][1:3]] == pytest.approx([study["scores"][d][s.chosen] for d in SETS], rel=1e-3)
    assert s.chosen_label in render_section(s)
