"""Write a gain schedule for the microcontroller: ``gain_schedule.h`` (C99), ``gains.json``, ``gains.csv``.

The header holds the tables at full double precision and ``rcm_gain_schedule``, the firmware's
bilinear interpolation (``interpolate`` of thesis Listing 4.14 along roll, then along pitch),
clamped to the grid's edge outside it: never extrapolated. A NaN angle gives NaN gains.
Optional feedforwards: the holding PWM table (``gravity_feedforward``) and the sliding-friction
compensation ``rcm_friction_feedforward`` (``friction_feedforward``;
:mod:`rcm_kin.control.friction`), which needs ``tanh`` from ``<math.h>`` (link
with ``-lm`` where the C library splits it out).

The header also holds the law itself, ``rcm_control_law``: one tick of the roll and pitch law of
:class:`~rcm_kin.simulation.controllers.StateFeedbackController` (the simulator's), in the same
order of operations, its options the ``RCM_LAW_*`` defines written here (``scheduled``,
``track_velocity``; gravity and friction follow the exported feedforwards). ``gains.json`` states
the same options and the law in words under ``"controller"``
(tests/codegen/test_control_law_header.py holds the C to the simulator tick for tick).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from rcm_kin.atomic import atomic_open, write_text
from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.control.stability import StabilitySurvey
from rcm_kin.errors import RcmKinError

STATE_CL = ["q_roll", "q_pitch", "q_insertion", "v_roll", "v_pitch", "v_insertion", "z_pitch"]

_FUNCTIONS = """
static inline double rcm_gs_interpolate(double x, double x0, double x1, double y0, double y1)
{
    return y0 + (y1 - y0) * ((x - x0) / (x1 - x0));
}

/* Cell of a strictly increasing grid holding x, after clamping x to the grid. */
static inline int rcm_gs_cell(const double *grid, int n, double *x)
{
    int i = 0;
    if (*x < grid[0]) *x = grid[0];
    if (*x > grid[n - 1]) *x = grid[n - 1];
    while (i < n - 2 && *x >= grid[i + 1]) i++;
    return i;
}

/* Bilinear interpolation of table[pitch][roll][k], k < width, into out[width]. */
static inline void rcm_gs_bilinear(const double *table, int width, double roll_deg, double pitch_deg, double *out)
{
    int i = rcm_gs_cell(RCM_GS_ROLL_DEG, RCM_GS_N_ROLL, &roll_deg);
    int j = rcm_gs_cell(RCM_GS_PITCH_DEG, RCM_GS_N_PITCH, &pitch_deg);
    double r0 = RCM_GS_ROLL_DEG[i], r1 = RCM_GS_ROLL_DEG[i + 1];
    double p0 = RCM_GS_PITCH_DEG[j], p1 = RCM_GS_PITCH_DEG[j + 1];
    int k;
    for (k = 0; k < width; k++) {
        double a = table[(j * RCM_GS_N_ROLL + i) * width + k], b = table[(j * RCM_GS_N_ROLL + i + 1) * width + k];
        double c = table[((j + 1) * RCM_GS_N_ROLL + i) * width + k];
        double d = table[((j + 1) * RCM_GS_N_ROLL + i + 1) * width + k];
        double low = rcm_gs_interpolate(roll_deg, r0, r1, a, b);
        double high = rcm_gs_interpolate(roll_deg, r0, r1, c, d);
        out[k] = rcm_gs_interpolate(pitch_deg, p0, p1, low, high);
    }
}

/* Gains at (roll, pitch) in degrees: k_roll = {Kp, Kd}, k_pitch = {Kp, Kd, Ki}
   (PWM/deg, PWM/(deg/s), PWM/(deg s)); the firmware applies u = -(Kp e + Kd v [+ Ki int e]),
   e = r - y in degrees, PWM with the hardware sign. */
static inline void rcm_gain_schedule(double roll_deg, double pitch_deg, double k_roll[2], double k_pitch[3])
{
    rcm_gs_bilinear(&RCM_GS_K_ROLL[0][0][0], 2, roll_deg, pitch_deg, k_roll);
    rcm_gs_bilinear(&RCM_GS_K_PITCH[0][0][0], 3, roll_deg, pitch_deg, k_pitch);
}

/* Pitch feedforward coefficients {F_v, F_a}: u_ff = lambda * (F_v rdot + F_a rddot),
   rdot in deg/s, rddot in deg/s^2 (the model inverse pinv(B) (xdot_ref - A x_ref) without its
   position term, which the holding PWM carries). */
static inline void rcm_pitch_feedforward(double roll_deg, double pitch_deg, double ff[2])
{
    rcm_gs_bilinear(&RCM_GS_FF_PITCH[0][0][0], 2, roll_deg, pitch_deg, ff);
}
"""

_HOLDING = """
/* Gravity feedforward: the PWM {roll, pitch} that holds the arm at (roll, pitch) in degrees,
   hardware sign; add it to the feedback. */
static inline void rcm_holding_pwm(double roll_deg, double pitch_deg, double u_hold[2])
{
    rcm_gs_bilinear(&RCM_GS_U_HOLD[0][0][0], 2, roll_deg, pitch_deg, u_hold);
}
"""

_FRICTION = """
/* Friction compensation: the PWM (hardware sign) that cancels the sliding Coulomb friction of
   axis 0 (roll) or 1 (pitch) while the REFERENCE moves at rdot_deg_s (deg/s):
   u_fc = -RCM_FC_PWM_<axis> * tanh(rdot / RCM_FC_RAMP_DEG_S), negative for a rising reference
   (a positive PWM lowers the angle); 0 for any other axis. Add it to the feedback. */
static inline double rcm_friction_feedforward(double rdot_deg_s, int axis)
{
    double amplitude = axis == 0 ? RCM_FC_PWM_ROLL : (axis == 1 ? RCM_FC_PWM_PITCH : 0.0);
    return -amplitude * tanh(rdot_deg_s / RCM_FC_RAMP_DEG_S);
}
"""


_LAW = """
static inline int rcm_law_sign(double x)
{
    return (x > 0.0) - (x < 0.0);
}

/* One tick of the roll LQR / pitch LQI law (the simulator's StateFeedbackController; options
   RCM_LAW_*), firmware units: measured angles (deg), the firmware velocity estimate (deg/s), the
   reference (deg), its velocity (deg/s) and acceleration (deg/s^2), the period (s) and the pitch
   PWM limit (counts, for the conditional anti-windup). e = r - y, w = v - rdot (v when
   !RCM_LAW_TRACK_VELOCITY), gains and {F_v, F_a} at the measured pose (roll = pitch = 0 when
   !RCM_LAW_SCHEDULED), u_ff = the holding PWM at the reference (RCM_LAW_GRAVITY) + the friction
   feedforward of rdot (RCM_LAW_FRICTION):
     pwm[0] = -(Kp e + Kd w) + u_ff[0]
     pwm[1] = -(Kp e + Kd w + Ki E) + F_v rdot + F_a rddot + u_ff[1]
   with E = *pitch_integral + e T (deg s), kept unless pwm[1] is then beyond the limit and the
   integration pushed it further out: then E stays, pwm[1] is the law at the old E, and the
   function returns 1 (else 0). PWM with the hardware sign, before saturation: saturate at the
   limits and truncate to whole counts after it. */
static inline int rcm_control_law(const double measured_deg[2], const double velocity_deg_s[2],
                                  const double reference_deg[2], const double reference_velocity_deg_s[2],
                                  const double reference_acceleration_deg_s2[2], double period_s,
                                  double pitch_pwm_limit, double *pitch_integral, double pwm[2])
{
    double k_roll[2], k_pitch[3], ff[2], hold[2] = {0.0, 0.0};
    double e0 = reference_deg[0] - measured_deg[0], e1 = reference_deg[1] - measured_deg[1];
    double v0 = velocity_deg_s[0], v1 = velocity_deg_s[1];
    double feedforward, pd, candidate, u, held;
#if RCM_LAW_SCHEDULED
    rcm_gain_schedule(measured_deg[0], measured_deg[1], k_roll, k_pitch);
    rcm_pitch_feedforward(measured_deg[0], measured_deg[1], ff);
#else
    rcm_gain_schedule(0.0, 0.0, k_roll, k_pitch);
    rcm_pitch_feedforward(0.0, 0.0, ff);
#endif
#if RCM_LAW_TRACK_VELOCITY
    v0 = v0 - reference_velocity_deg_s[0];
    v1 = v1 - reference_velocity_deg_s[1];
#endif
%s    pwm[0] = -(k_roll[0] * e0 + k_roll[1] * v0) + hold[0];
    feedforward = ff[0] * reference_velocity_deg_s[1] + ff[1] * reference_acceleration_deg_s2[1] + hold[1];
    pd = k_pitch[0] * e1 + k_pitch[1] * v1;
    candidate = *pitch_integral + e1 * period_s;
    u = -(pd + k_pitch[2] * candidate) + feedforward;
    held = -(pd + k_pitch[2] * *pitch_integral) + feedforward;
    if ((u > pitch_pwm_limit || u < -pitch_pwm_limit) && rcm_law_sign(u) == rcm_law_sign(u - held)) {
        pwm[1] = held;
        return 1;
    }
    pwm[1] = u;
    *pitch_integral = candidate;
    return 0;
}
"""

_LAW_GRAVITY = """#if RCM_LAW_GRAVITY
    rcm_holding_pwm(reference_deg[0], reference_deg[1], hold);
#endif
"""

_LAW_FRICTION = """#if RCM_LAW_FRICTION
    hold[0] = hold[0] + rcm_friction_feedforward(reference_velocity_deg_s[0], 0);
    hold[1] = hold[1] + rcm_friction_feedforward(reference_velocity_deg_s[1], 1);
#endif
"""


def _c_array(values: np.ndarray) -> str:
    if values.ndim == 1:
        return "{" + ", ".join(f"{v:.17g}" for v in values) + "}"
    return "{" + ", ".join(_c_array(v) for v in values) + "}"


def _friction(schedule: GainSchedule):
    if schedule.friction is None:
        raise RcmKinError("this gain schedule has no friction compensation to export (schedule_gains adds it)")
    return schedule.friction


def _friction_lines(schedule: GainSchedule) -> list[str]:
    fc = _friction(schedule)
    return ["", "#include <math.h>", "",
            "/* friction compensation: sliding-friction PWM amplitude per axis (counts) and its ramp (deg/s) */",
            f"#define RCM_FC_PWM_ROLL {float(fc.pwm[0])!r}", f"#define RCM_FC_PWM_PITCH {float(fc.pwm[1])!r}",
            f"#define RCM_FC_RAMP_DEG_S {float(fc.ramp_deg_s)!r}"]      # repr: shortest exact, always a double


def _law_flags(scheduled: bool, gravity: bool, track_velocity: bool, friction: bool) -> dict[str, bool]:
    return {"scheduled": bool(scheduled), "gravity": bool(gravity), "track_velocity": bool(track_velocity),
            "friction": bool(friction)}


def _law_defines(flags: dict[str, bool]) -> list[str]:
    return ["", "/* the control law rcm_control_law: options of the simulator's StateFeedbackController */",
            *(f"#define RCM_LAW_{name.upper()} {int(on)}" for name, on in flags.items())]


def _law_words(flags: dict[str, bool]) -> str:
    """The law of ``rcm_control_law`` with options ``flags`` (``scheduled``, ``gravity``,
    ``track_velocity``, ``friction``) in words, for ``gains.json``."""
    w = "w = v - rdot" if flags["track_velocity"] else "w = v"
    at = "at the measured pose (bilinear, clamped)" if flags["scheduled"] else "at roll = pitch = 0"
    extra = (" + u_hold(r)" if flags["gravity"] else "") + (" + u_fc(rdot)" if flags["friction"] else "")
    terms = ((", u_hold(r) the u_hold table at the reference pose" if flags["gravity"] else "")
             + (", u_fc(rdot) = -pwm tanh(rdot / ramp_deg_s) of friction_feedforward" if flags["friction"] else ""))
    return (f"roll u = -(Kp e + Kd w){extra}; pitch u = -(Kp e + Kd w + Ki E) + F_v rdot + F_a rddot{extra}; "
            f"e = r - y (deg), {w} (deg/s, v the firmware velocity estimate), gains and F_v, F_a {at}{terms}, "
            "E the pitch error integral (deg s) by conditional integration (E + e T kept unless the pitch command "
            "is then beyond its PWM limit and integrating pushed it further out); PWM with the hardware sign, "
            "before saturation")


def header_text(schedule: GainSchedule, gravity_feedforward: bool = False, friction_feedforward: bool = False,
                scheduled: bool = True, track_velocity: bool = True) -> str:
    """The C99 header of a schedule; with ``friction_feedforward`` also the friction compensation
    (``RCM_FC_*`` constants and ``rcm_friction_feedforward``). Its ``rcm_control_law`` runs the
    :class:`~rcm_kin.simulation.controllers.StateFeedbackController` of ``scheduled``,
    ``track_velocity`` and the feedforwards exported (``RCM_LAW_*``)."""
    flags = _law_flags(scheduled, gravity_feedforward, track_velocity, friction_feedforward)
    w = schedule.weights
    tables = [("RCM_GS_K_ROLL", schedule.k_roll, "roll {Kp PWM/deg, Kd PWM/(deg/s)}"),
              ("RCM_GS_K_PITCH", schedule.k_pitch, "pitch {Kp PWM/deg, Kd PWM/(deg/s), Ki PWM/(deg s)}"),
              ("RCM_GS_FF_PITCH", schedule.ff_pitch, "pitch feedforward {F_v PWM/(deg/s), F_a PWM/(deg/s^2)}")]
    if gravity_feedforward:
        tables.append(("RCM_GS_U_HOLD", schedule.u_hold, "holding PWM {roll, pitch}"))
    lines = [
        "/* gain_schedule.h: model-based gain schedule of the PSM roll LQR and pitch LQI.",
        "   Generated by rcm-kin (rcm-kin schedule); do not edit by hand.",
        f"   Models linearised at insertion {schedule.insertion:g} m; Bryson budgets: roll error "
        f"{w.roll_error_deg:g} deg, rate {w.roll_rate_deg_s:g} deg/s, PWM {w.roll_pwm:g}; pitch error "
        f"{w.pitch_error_deg:g} deg, rate {w.pitch_rate_deg_s:g} deg/s, integral {w.pitch_integral_deg_s:g} deg s, "
        f"PWM {w.pitch_pwm:g}.",
        "   Tables are indexed [pitch][roll] like the thesis firmware's. C99. */",
        "#ifndef RCM_GAIN_SCHEDULE_H",
        "#define RCM_GAIN_SCHEDULE_H",
        "",
        f"#define RCM_GS_N_ROLL {len(schedule.roll_deg)}",
        f"#define RCM_GS_N_PITCH {len(schedule.pitch_deg)}",
        f"#define RCM_GS_GRAVITY_FEEDFORWARD {int(gravity_feedforward)}",
        f"#define RCM_GS_FRICTION_FEEDFORWARD {int(friction_feedforward)}",
        *(_friction_lines(schedule) if friction_feedforward else []),
        *_law_defines(flags),
        "",
        f"static const double RCM_GS_ROLL_DEG[RCM_GS_N_ROLL] = {_c_array(schedule.roll_deg)};",
        f"static const double RCM_GS_PITCH_DEG[RCM_GS_N_PITCH] = {_c_array(schedule.pitch_deg)};",
    ]
    for name, table, what in tables:
        lines += ["", f"/* {what} */",
                  f"static const double {name}[RCM_GS_N_PITCH][RCM_GS_N_ROLL][{table.shape[-1]}] = {{\n    "
                  + ",\n    ".join(_c_array(row) for row in table) + "};"]
    text = ("\n".join(lines) + "\n" + _FUNCTIONS + (_HOLDING if gravity_feedforward else "")
            + (_FRICTION if friction_feedforward else "")
            + _LAW % ((_LAW_GRAVITY if gravity_feedforward else "") + (_LAW_FRICTION if friction_feedforward else "")))
    return text + "\n#endif /* RCM_GAIN_SCHEDULE_H */\n"


def gains_payload(schedule: GainSchedule, survey: StabilitySurvey | None = None,
                  gravity_feedforward: bool = False, friction_feedforward: bool = False,
                  scheduled: bool = True, track_velocity: bool = True) -> dict:
    """``gains.json`` content (the contract keys first, then extensions; ``"controller"``: the
    options of the header's ``rcm_control_law`` and its law in words)."""
    points = []
    for j, pitch in enumerate(schedule.pitch_deg):
        for i, roll in enumerate(schedule.roll_deg):
            points.append({"roll_deg": float(roll), "pitch_deg": float(pitch), "A": schedule.A[j, i].tolist(),
                           "B": schedule.B[j, i].tolist(), "A_cl": schedule.A_cl[j, i].tolist(),
                           "poles_cl": [[e.real, e.imag] for e in np.linalg.eigvals(schedule.A_cl[j, i])]})
    payload = {
        "roll_deg": schedule.roll_deg.tolist(), "pitch_deg": schedule.pitch_deg.tolist(),
        "k_roll": schedule.k_roll.tolist(), "k_pitch": schedule.k_pitch.tolist(), "points": points,
        "insertion_m": schedule.insertion,
        "units": {"k_roll": ["PWM/deg", "PWM/(deg/s)"], "k_pitch": ["PWM/deg", "PWM/(deg/s)", "PWM/(deg s)"],
                  "ff_pitch": ["PWM/(deg/s)", "PWM/(deg/s^2)"], "u_hold": ["PWM", "PWM"],
                  "A": "SI, state [q; v] (rad, m, rad/s, m/s)", "B": "per PWM count"},
        "law": "u = -(Kp e + Kd v [+ Ki int e]), e = r - y (deg), PWM with the hardware sign; v as the law's options "
               "say (the velocity error v - rdot where controller.track_velocity): see \"controller\"",
        "state": ["q_roll", "q_pitch", "q_insertion", "v_roll", "v_pitch", "v_insertion"],
        "state_cl": STATE_CL, "input": ["pwm_roll", "pwm_pitch", "pwm_insertion"],
        "weights": vars(schedule.weights).copy(),
        "ff_pitch": schedule.ff_pitch.tolist(),
    }
    if gravity_feedforward:
        payload["u_hold"] = schedule.u_hold.tolist()
    if friction_feedforward:
        fc = _friction(schedule)
        payload["friction_feedforward"] = {
            "pwm": list(fc.pwm), "ramp_deg_s": fc.ramp_deg_s, "axes": ["roll", "pitch"],
            "units": {"pwm": "PWM", "ramp_deg_s": "deg/s"},
            "law": "u_fc = -pwm tanh(rdot / ramp_deg_s), rdot the reference velocity (deg/s), PWM with the "
                   "hardware sign"}
    flags = _law_flags(scheduled, gravity_feedforward, track_velocity, friction_feedforward)
    payload["controller"] = {**flags, "function": "rcm_control_law", "law": _law_words(flags)}
    if survey is not None:
        payload["stability"] = {"points_per_axis": len(survey.roll_deg), "stable": survey.stable, **survey.weakest()}
    return payload


def write_gain_schedule(schedule: GainSchedule, folder: Path, survey: StabilitySurvey | None = None,
                        gravity_feedforward: bool = False, friction_feedforward: bool = False,
                        scheduled: bool = True, track_velocity: bool = True) -> list[Path]:
    """Write ``gains.json``, ``gains.csv`` and ``gain_schedule.h`` into ``folder`` (the friction
    compensation, a constant per axis, goes into the JSON and the header only; the control law's
    options ``scheduled`` and ``track_velocity`` too)."""
    folder = Path(folder)
    files = [folder / "gains.json", folder / "gains.csv", folder / "gain_schedule.h"]
    options = (gravity_feedforward, friction_feedforward, scheduled, track_velocity)
    try:
        text = header_text(schedule, *options)
        write_text(files[0], json.dumps(gains_payload(schedule, survey, *options), indent=1))
        with atomic_open(files[1], "w", newline="") as fh:
            writer = csv.writer(fh)
            header = ["roll_deg", "pitch_deg", "kp_roll", "kd_roll", "kp_pitch", "kd_pitch", "ki_pitch",
                      "ff_v_pitch", "ff_a_pitch", "u_hold_roll", "u_hold_pitch", "max_real_pole_cl"]
            writer.writerow(header)
            for j, pitch in enumerate(schedule.pitch_deg):
                for i, roll in enumerate(schedule.roll_deg):
                    writer.writerow([roll, pitch, *schedule.k_roll[j, i], *schedule.k_pitch[j, i],
                                     *schedule.ff_pitch[j, i], *schedule.u_hold[j, i],
                                     np.linalg.eigvals(schedule.A_cl[j, i]).real.max()])
        write_text(files[2], text)
    except OSError as exc:
        raise RcmKinError(f"cannot write the gain schedule into {folder}: {exc.strerror}") from None
    return files
