/* The compiled closed loop of rcm-kin (rcm_kin.simulation.kernel builds, caches and loads it):
   the firmware's rules, the controller laws, the plant step and the loop over ticks, in C.

   Each firmware rule is a declared twin of its plain statement in rcm_kin/firmware_rules.py, and
   the drive-train axis (axis_advance and what it calls) a declared twin of the numba kernels of
   rcm_kin/dynamics/stick_slip.py (advance): the same operations in the same order, so the engines
   agree to rounding (tests/simulation/test_rules.py holds each twin to its original). Python's
   min(a, b) and max(a, b) are written as py_min and py_max (the later argument only when strictly
   beyond, as Python and numba do), np.sign as np_sign (0 and NaN give themselves), np.round as
   nearbyint (half to even), tanh and exp are the C library's. Build with -ffp-contract=off: no
   fused multiply-adds the Python side does not do.

   The numbers that belong to Python modules arrive as #defines that rcm_kin.simulation.kernel writes
   before this text (and hashes with it into the library's cache key): RK_STATE_SIZE,
   RK_MAX_ELEMENTS, RK_COUPLING_SWEEPS (rcm_kin.dynamics.axis_friction), RK_P, RK_PID,
   RK_STATE_FEEDBACK, RK_THESIS (rcm_kin.simulation.kernel_forms), RK_DRIVE_TRAIN, RK_SMOOTH
   (rcm_kin.simulation.kernel). Numbers that may change at run time (the insertion gain, the
   firmware scale) are arguments.

   The plant's CasADi functions are called through their C entry point by address:
   int f(const double** arg, double** res, long long* iw, double* w, int mem); each gets the plant's
   parameters in the argument slot after its own inputs. */

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#if !defined(RK_STATE_SIZE) || !defined(RK_MAX_ELEMENTS) || !defined(RK_COUPLING_SWEEPS) || !defined(RK_P) \
    || !defined(RK_PID) || !defined(RK_STATE_FEEDBACK) || !defined(RK_THESIS) || !defined(RK_DRIVE_TRAIN) \
    || !defined(RK_SMOOTH)
#error "built by rcm_kin.simulation.kernel, which defines the constants of the Python modules"
#endif

typedef long long i64;
typedef int (*casadi_function)(const double **arg, double **res, i64 *iw, double *w, int mem);

static inline double py_max(double a, double b) { return b > a ? b : a; }
static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline i64 py_max_int(i64 a, i64 b) { return b > a ? b : a; }
static inline i64 py_min_int(i64 a, i64 b) { return b < a ? b : a; }
static inline double np_sign(double x) { return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : x; }


/* --- the firmware's rules: twins of rcm_kin.firmware_rules ------------------------------------- */

/* firmware_rules._cell: the cell index (largest i with grid[i] <= x, at most n - 2), x clamped */
static inline i64 cell(const double *grid, i64 n, double *x) {
    double v = py_min(py_max(*x, grid[0]), grid[n - 1]);
    i64 i = 0;
    while (i + 2 < n && grid[i + 1] <= v)
        i += 1;
    *x = v;
    return i;
}

/* firmware_rules.bilinear: the first n_out of the `values` values of table[pitch][roll] at the pose */
static inline void bilinear(const double *roll_grid, i64 n_roll, const double *pitch_grid, i64 n_pitch,
                            const double *table, i64 values, double roll, double pitch, double *out, i64 n_out) {
    double r = roll, p = pitch;
    i64 i = cell(roll_grid, n_roll, &r), j = cell(pitch_grid, n_pitch, &p);
    double fr = (r - roll_grid[i]) / (roll_grid[i + 1] - roll_grid[i]);
    double fp = (p - pitch_grid[j]) / (pitch_grid[j + 1] - pitch_grid[j]);
    const double *a = table + (j * n_roll + i) * values, *b = a + values;          /* [j, i], [j, i + 1] */
    const double *c = table + ((j + 1) * n_roll + i) * values, *d = c + values;    /* [j + 1, i], [j + 1, i + 1] */
    for (i64 m = 0; m < n_out; m++) {
        double low = a[m] + (b[m] - a[m]) * fr;
        double high = c[m] + (d[m] - c[m]) * fr;
        out[m] = low + (high - low) * fp;
    }
}

/* the laws integrated at E = integral: the PID's -(c1 + Ki E + c2), the pitch's -(c1 + c2 + Ki E) [+ ff] */
static inline double integral_law(int pid, int with_feedforward, double c1, double c2, double k_integral,
                                  double integral, double feedforward) {
    if (pid)
        return -(c1 + k_integral * integral + c2);
    double u = -(c1 + c2 + k_integral * integral);
    return with_feedforward ? u + feedforward : u;
}

/* firmware_rules.conditional_integral with the law integral_law: the command, *integral updated */
static inline double conditional_integral(double *integral, double error, double period, double limit, int pid,
                                          int with_feedforward, double c1, double c2, double k_integral,
                                          double feedforward) {
    double candidate = *integral + error * period;
    double u = integral_law(pid, with_feedforward, c1, c2, k_integral, candidate, feedforward);
    double held = integral_law(pid, with_feedforward, c1, c2, k_integral, *integral, feedforward);
    if (fabs(u) > limit && np_sign(u) == np_sign(u - held))
        return held;
    *integral = candidate;
    return u;
}

/* firmware_rules.quantise of each axis, counted from zero */
static inline void quantise(const double *position, const double *count, const double *noise, double *out) {
    for (int j = 0; j < 3; j++)
        out[j] = count[j] == 0.0 ? position[j] : (nearbyint(position[j] / count[j]) + noise[j]) * count[j];
}

/* firmware_rules.velocity_estimate, filtered updated in place */
static inline void velocity_estimate(const double *measured, const double *previous, double *filtered, double period,
                                     double roll_filter) {
    double raw0 = (measured[0] - previous[0]) / period;
    filtered[0] = roll_filter * filtered[0] + (1 - roll_filter) * raw0;
    filtered[1] = (measured[1] - previous[1]) / period;
    filtered[2] = (measured[2] - previous[2]) / period;
}

/* firmware_rules.saturate, into out */
static inline void saturate(const double *command, const double *limit, int whole_counts, double *out) {
    for (int j = 0; j < 3; j++) {
        out[j] = py_min(py_max(command[j], -limit[j]), limit[j]);
        if (whole_counts)
            out[j] = trunc(out[j]);
    }
}

/* firmware_rules.p_command: -Kp e */
static inline double p_command(double kp, double error) { return -kp * error; }

/* firmware_rules.insertion_command: Kp (r - y) */
static inline double insertion_command(double reference, double measured, double kp) {
    return kp * (reference - measured);
}

/* control.friction.FrictionCompensation.feedforward of one axis: -F tanh(rdot / v_ramp) */
static inline double friction_feedforward(double amplitude, double ramp, double rdot) {
    return -amplitude * tanh(rdot / ramp);
}


/* --- the controller laws (kinds of rcm_kin.simulation.kernel_forms) ------------------------------- */

typedef struct {
    i64 kind;
    const uint8_t *flags;                 /* scheduled, gravity, track_velocity, friction */
    const double *gains, *roll_grid, *pitch_grid, *table, *hold, *friction;
    i64 n_roll, n_pitch, table_values, hold_values;
} law_t;

/* the thesis and state-feedback laws (ThesisController, StateFeedbackController) */
static void gain_scheduled(const law_t *law, double *memory, const double *measured, const double *velocity,
                           const double *reference, const double *rdot, const double *racc, double period,
                           const double *limit, double *scratch, double *command) {
    double e0 = reference[0] - measured[0], e1 = reference[1] - measured[1];
    int scheduled = law->flags[0], gravity = law->flags[1], track = law->flags[2], compensate = law->flags[3];
    int at_pose = scheduled || law->kind == RK_THESIS;
    double *k = scratch, *hold = scratch + 7;
    bilinear(law->roll_grid, law->n_roll, law->pitch_grid, law->n_pitch, law->table, law->table_values,
             at_pose ? measured[0] : 0.0, at_pose ? measured[1] : 0.0, k, 7);
    double v0 = velocity[0], v1 = velocity[1];
    if (law->kind == RK_THESIS) {
        command[0] = -(k[0] * e0 + k[1] * v0);
        command[1] = conditional_integral(&memory[0], e1, period, limit[1], 0, 0, k[2] * e1, k[3] * v1, k[4], 0.0);
        return;
    }
    if (track) {
        v0 = v0 - rdot[0];
        v1 = v1 - rdot[1];
    }
    if (gravity) {
        bilinear(law->roll_grid, law->n_roll, law->pitch_grid, law->n_pitch, law->hold, law->hold_values,
                 reference[0], reference[1], hold, 2);
    } else {
        hold[0] = 0.0;
        hold[1] = 0.0;
    }
    if (compensate) {
        hold[0] = hold[0] + friction_feedforward(law->friction[0], law->friction[2], rdot[0]);
        hold[1] = hold[1] + friction_feedforward(law->friction[1], law->friction[2], rdot[1]);
    }
    command[0] = -(k[0] * e0 + k[1] * v0) + hold[0];
    double feedforward = k[5] * rdot[1] + k[6] * racc[1] + hold[1];
    command[1] = conditional_integral(&memory[0], e1, period, limit[1], 0, 1, k[2] * e1, k[3] * v1, k[4], feedforward);
}

/* the controller's command (firmware units, before saturation) into out; memory updated in place; the
   insertion by its P loop (insertion_kp counts/m) */
static void command(const law_t *law, double *memory, const double *measured, const double *velocity,
                    const double *reference, const double *rdot, const double *racc, double period,
                    const double *limit, double insertion_kp, double *scratch, double *out) {
    double e0 = reference[0] - measured[0], e1 = reference[1] - measured[1];
    if (law->kind == RK_P) {
        out[0] = p_command(law->gains[0], e0);
        out[1] = p_command(law->gains[1], e1);
    } else if (law->kind == RK_PID) {                /* memory: integrals, previous errors */
        double e[2] = {e0, e1};
        for (int i = 0; i < 2; i++) {
            double de = isnan(memory[2 + i]) ? 0.0 : (e[i] - memory[2 + i]) / period;
            out[i] = conditional_integral(&memory[i], e[i], period, limit[i], 1, 0, law->gains[i] * e[i],
                                          law->gains[4 + i] * de, law->gains[2 + i], 0.0);
        }
        memory[2] = e0;
        memory[3] = e1;
    } else {                                         /* RK_STATE_FEEDBACK or RK_THESIS */
        gain_scheduled(law, memory, measured, velocity, reference, rdot, racc, period, limit, scratch, out);
    }
    out[2] = insertion_command(reference[2], measured[2], insertion_kp);
}


/* --- the drive-train axis: twins of rcm_kin.dynamics.stick_slip's numba kernels -------------------- */

/* stick_slip._implicit_friction: v after a step of J v' = F - B v - f, f from the friction set */
static inline double implicit_friction(double v, double J, double h, double F, double B, double static_,
                                       double coulomb, double stribeck) {
    double p = J * v + h * F;
    static_ = py_max(static_, coulomb);
    if (v == 0.0) {
        if (fabs(p) <= h * static_)
            return 0.0;
        return (p - h * coulomb * np_sign(p)) / (J + h * B);
    }
    double ratio = v / stribeck;
    double f = coulomb + (static_ - coulomb) * exp(-(ratio * ratio));
    double next = (p - h * f * np_sign(v)) / (J + h * B);
    return next * v <= 0.0 ? 0.0 : next;
}

/* stick_slip.slip_elements: the first n anchors moved to carry at most their slip forces; the spring's force */
static inline double slip_elements(double q, double *anchors, double k_each, double unit, i64 n) {
    double total = 0.0;
    for (i64 i = 0; i < n; i++) {
        double bound = unit * (double)(i + 1);
        if (k_each * (q - anchors[i]) > bound)
            anchors[i] = q - bound / k_each;
        else if (k_each * (q - anchors[i]) < -bound)
            anchors[i] = q + bound / k_each;
        total += k_each * (q - anchors[i]);
    }
    return total;
}

/* stick_slip._substep: state [theta, w, q, v, z_1 .. z_MAX_ELEMENTS] advanced by h with pwm held */
static inline void substep(double *state, const double *th, i64 n, double unit, double pwm, double gravity,
                           double inertia, double ku, double kemf, double Jm, double h) {
    double Jx = th[0], b = th[1], Fc = th[2], Fs = th[3], vs = th[4], kp0 = th[5], sp = th[6];
    double kc = th[8], dc = th[9], Fcm = th[10], bm = th[11];
    double q = state[2];
    double kp = kp0 > 0.0 ? kp0 * exp(sp * q) : 0.0;
    double k_each = kp / (double)n;
    double spring = k_each * (q - state[4]);
    for (i64 i = 1; i < n; i++)
        spring += k_each * (q - state[4 + i]);
    if (kc > 0.0) {
        double stretch = kc * (state[0] - q), coupling = dc + h * kc;
        double w = state[1], v = state[3];
        for (int sweep = 0; sweep < RK_COUPLING_SWEEPS; sweep++) {
            w = implicit_friction(state[1], Jm, h, ku * pwm - stretch + coupling * v, kemf + bm + coupling,
                                  Fcm, Fcm, 1.0);
            v = implicit_friction(state[3], inertia + Jx, h, stretch + coupling * w - gravity - spring,
                                  b + coupling + h * kp, Fs, Fc, vs);
        }
        state[1] = w;
        state[3] = v;
        state[0] += h * w;
    } else {
        double F = ku * pwm - gravity - spring;
        state[3] = implicit_friction(state[3], inertia + Jx + Jm, h, F, b + bm + kemf + h * kp, Fs + Fcm, Fc + Fcm, vs);
        state[1] = state[3];
    }
    state[2] += h * state[3];
    if (kc <= 0.0)
        state[0] = state[2];
    if (kp > 0.0)
        slip_elements(state[2], state + 4, k_each, unit, n);
}

/* stick_slip.advance: one period of substeps with pwm, gravity and inertia held */
static void axis_advance(const double *th, double ku, double kemf, double Jm, double gravity, double inertia,
                         double pwm, double *state, double period, i64 substeps) {
    double h = period / (double)substeps;
    i64 n = py_min_int(py_max_int((i64)th[12], 1), RK_MAX_ELEMENTS);      /* stick_slip.elements_of */
    double unit = th[7] * (2.0 / (double)(n * (n + 1)));                 /* stick_slip.force_unit */
    for (i64 s = 0; s < substeps; s++)
        substep(state, th, n, unit, pwm, gravity, inertia, ku, kemf, Jm, h);
}


/* --- the plant ------------------------------------------------------------------------------------- */

typedef struct {
    i64 kind;                             /* RK_DRIVE_TRAIN or RK_SMOOTH */
    const i64 *addresses;                 /* of the CasADi functions */
    const double *parameters;             /* of parametric functions: the slot after their own inputs */
    const double *friction;               /* (3, friction_size): AxisFriction vectors */
    i64 friction_size;
    const double *input_gain, *damping, *reflected_inertia;
    double period;
    i64 substeps;
} plant_t;

typedef struct {                          /* a plant step's buffers and CasADi's work arrays */
    double values[24];                    /* q, v, M, h, x(T) */
    double axis[RK_STATE_SIZE];
    const double **arg;
    double **res;
    i64 *iw;
    double *w;
} work_t;

/* the buffers of the plant step: work (n_work, 4), each function's sizes of arg, res, iw, w (arg at least
   3 slots: the parameters after two inputs); 0, or -1 when they cannot be allocated */
static int work_alloc(work_t *work, const i64 *sizes, i64 n_work) {
    i64 size[4] = {3, 2, 2, 2};
    for (i64 r = 0; r < n_work; r++)
        for (int c = 0; c < 4; c++)
            size[c] = py_max_int(size[c], sizes[4 * r + c]);
    work->arg = calloc((size_t)size[0], sizeof(double *));
    work->res = calloc((size_t)size[1], sizeof(double *));
    work->iw = calloc((size_t)size[2], sizeof(i64));
    work->w = calloc((size_t)size[3], sizeof(double));
    return work->arg && work->res && work->iw && work->w ? 0 : -1;
}

static void work_free(work_t *work) {
    free((void *)work->arg);
    free(work->res);
    free(work->iw);
    free(work->w);
}

static inline void call(i64 address, work_t *work) {
    ((casadi_function)(intptr_t)address)(work->arg, work->res, work->iw, work->w, 0);
}

/* one period of the plant (DriveTrainPlant.step or the smooth period map) under u (3,), x in place */
static void plant_step(const plant_t *plant, double *x, const double *u, work_t *work) {
    double *values = work->values;
    if (plant->kind == RK_SMOOTH) {                  /* x (6,) -> period_map(x, u) */
        double *out = values + 18;
        work->arg[0] = x, work->arg[1] = u, work->arg[2] = plant->parameters, work->res[0] = out;
        call(plant->addresses[0], work);
        for (int i = 0; i < 6; i++)
            x[i] = out[i];
        return;
    }
    double *q = values, *v = values + 3, *M = values + 6, *h = values + 15, *axis = work->axis;
    for (int i = 0; i < 3; i++) {
        q[i] = x[6 + i];
        v[i] = x[9 + i];
    }
    work->arg[0] = q, work->arg[1] = plant->parameters, work->res[0] = M;
    call(plant->addresses[0], work);
    work->arg[0] = q, work->arg[1] = v, work->arg[2] = plant->parameters, work->res[0] = h;
    call(plant->addresses[1], work);
    for (int i = 0; i < 3; i++) {
        for (int r = 0; r < RK_STATE_SIZE; r++)
            axis[r] = x[3 * r + i];
        axis_advance(plant->friction + i * plant->friction_size, plant->input_gain[i], plant->damping[i],
                     plant->reflected_inertia[i], h[i], M[4 * i] - plant->reflected_inertia[i], u[i], axis,
                     plant->period, plant->substeps);
        for (int r = 0; r < RK_STATE_SIZE; r++)
            x[3 * r + i] = axis[r];
    }
}


/* --- the entry points (rcm_kin.simulation.kernel calls them with ctypes) ---------------------------- */

/* one plant step per row of u (n_u, 3), x in place; 0, or -1 when the buffers cannot be allocated */
int rk_plant_steps(double *x, const double *u, i64 n_u, i64 kind, const i64 *addresses, const i64 *sizes,
                   i64 n_work, const double *parameters, const double *friction, i64 friction_size,
                   const double *input_gain, const double *damping, const double *reflected_inertia, double period,
                   i64 substeps) {
    plant_t plant = {kind, addresses, parameters, friction, friction_size, input_gain, damping, reflected_inertia,
                     period, substeps};
    work_t work = {0};
    int status = work_alloc(&work, sizes, n_work);
    for (i64 k = 0; status == 0 && k < n_u; k++)
        plant_step(&plant, x, u + 3 * k, &work);
    work_free(&work);
    return status;
}

/* ticks first .. stop - 1 of loop.simulate (k < 0: settling), as the numba-free twin of the readable loop:
   the loop's state (x, previous, filtered, memory) advanced in place, the ticks k >= 0 logged (n_ref, 3);
   scale (3,): joint units to firmware units; insertion_kp: the insertion's P gain (counts/m); law and
   plant as rk_plant_steps and law_t. Returns the tick where the state stopped being finite, or stop
   (first - 1 when the buffers cannot be allocated). */
i64 rk_run(i64 first, i64 stop, double *x, i64 n_x, double *previous, double *filtered, double *memory,
           const double *ref_fw, const double *vel_fw, const double *acc_fw, i64 n_ref, const double *noise,
           i64 n_noise, double period, const double *limit, const double *count, double roll_filter, int quantise_pwm,
           const double *scale, double insertion_kp, i64 kind, const uint8_t *flags, const double *gains,
           const double *roll_grid, i64 n_roll, const double *pitch_grid, i64 n_pitch, const double *table,
           i64 table_values, const double *hold_table, i64 hold_values, const double *friction_ff, i64 plant_kind,
           const i64 *addresses, const i64 *sizes, i64 n_work, const double *parameters, const double *friction,
           i64 friction_size, const double *input_gain, const double *damping, const double *reflected_inertia,
           i64 substeps, double *log_measured, double *log_position, double *log_command, double *log_pwm) {
    law_t law = {kind, flags, gains, roll_grid, pitch_grid, table, hold_table, friction_ff, n_roll, n_pitch,
                 table_values, hold_values};
    plant_t plant = {plant_kind, addresses, parameters, friction, friction_size, input_gain, damping,
                     reflected_inertia, period, substeps};
    work_t work = {0};
    if (work_alloc(&work, sizes, n_work) != 0) {
        work_free(&work);
        return first - 1;
    }
    double true_[3], measured[3], out[3], u[3], rdot[3] = {0}, racc[3] = {0}, scratch[9] = {0};
    i64 n_settle = n_noise - n_ref - 1, end = stop;
    for (i64 k = first; k < stop && end == stop; k++) {
        i64 i = py_max_int(k, 0);
        int moving = k >= 0;
        for (int j = 0; j < 3; j++)
            true_[j] = x[j] * scale[j];
        quantise(true_, count, noise + 3 * (k + n_settle + 1), measured);
        velocity_estimate(measured, previous, filtered, period, roll_filter);
        for (int j = 0; j < 3; j++) {
            rdot[j] = moving ? vel_fw[3 * i + j] : 0.0;
            racc[j] = moving ? acc_fw[3 * i + j] : 0.0;
        }
        command(&law, memory, measured, filtered, ref_fw + 3 * i, rdot, racc, period, limit, insertion_kp, scratch,
                out);
        saturate(out, limit, quantise_pwm, u);
        if (moving) {
            for (int j = 0; j < 3; j++) {
                log_measured[3 * k + j] = measured[j], log_position[3 * k + j] = true_[j];
                log_command[3 * k + j] = out[j], log_pwm[3 * k + j] = u[j];
            }
        }
        plant_step(&plant, x, u, &work);
        for (i64 j = 0; j < n_x; j++)
            if (!isfinite(x[j]))
                end = k;
        if (end == stop)
            for (int j = 0; j < 3; j++)
                previous[j] = measured[j];
    }
    work_free(&work);
    return end;
}


/* the rules and the axis alone, for the twins' tests */

void rk_bilinear(const double *roll_grid, i64 n_roll, const double *pitch_grid, i64 n_pitch, const double *table,
                 i64 values, double roll, double pitch, double *out, i64 n_out) {
    bilinear(roll_grid, n_roll, pitch_grid, n_pitch, table, values, roll, pitch, out, n_out);
}

double rk_conditional_integral(double *integral, double error, double period, double limit, int pid,
                               int with_feedforward, double c1, double c2, double k_integral, double feedforward) {
    return conditional_integral(integral, error, period, limit, pid, with_feedforward, c1, c2, k_integral,
                                feedforward);
}

void rk_quantise(const double *position, const double *count, const double *noise, double *out) {
    quantise(position, count, noise, out);
}

void rk_velocity_estimate(const double *measured, const double *previous, double *filtered, double period,
                          double roll_filter) {
    velocity_estimate(measured, previous, filtered, period, roll_filter);
}

void rk_saturate(const double *command, const double *limit, int whole_counts, double *out) {
    saturate(command, limit, whole_counts, out);
}

double rk_p_command(double kp, double error) { return p_command(kp, error); }

double rk_insertion_command(double reference, double measured, double kp) {
    return insertion_command(reference, measured, kp);
}

double rk_friction_feedforward(double amplitude, double ramp, double rdot) {
    return friction_feedforward(amplitude, ramp, rdot);
}

void rk_advance(const double *th, double ku, double kemf, double Jm, double gravity, double inertia, double pwm,
                double *state, double period, i64 substeps) {
    axis_advance(th, ku, kemf, Jm, gravity, inertia, pwm, state, period, substeps);
}
