"""Sum-of-squares barrier certificates for the safety thesis's linear closed loops (its programs
1-4, digest Sec. 4), as semidefinite programs solved through cvxpy (Clarabel or SCS).

A certificate ``B(x)`` proves: ``B <= 0`` on the initial set ``X0``, ``B >= eps_bar > 0`` on the
unsafe set ``Xu``, and ``L_f B <= 0`` on the considered set ``X`` (Prajna; thesis Def. 8.3), via
Putinar multipliers: with each box written as ``g_j = -(x_j - lo_j)(x_j - hi_j) >= 0``,

    -B - sum q_j g_j,   B - eps_bar - sum q_j g_j,   -L_f B - sum q_j g_j   are sums of squares,

each ``q_j`` itself a sum of squares. A polynomial ``p`` is SOS when ``p = z^T Q z`` for the
monomial vector ``z`` of half its degree and some ``Q >= 0``: matching coefficients makes the
program an SDP. Variables are scaled to the unit box first (the thesis found this essential).
cvxpy is an optional extra: ``pip install 'rcm-kin[sos]'``.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np

from rcm_kin.errors import RcmKinError

PROGRAMS = ("1", "2", "3", "4")


# ---------------------------------------------------------------------------------------------
# Polynomials: {exponent tuple: coefficient}; coefficients are numbers or cvxpy expressions
# ---------------------------------------------------------------------------------------------
def monomials(n: int, degrees) -> list[tuple[int, ...]]:
    """Exponent tuples of ``n`` variables with total degree in ``degrees``, graded order."""
    out = []
    for d in sorted(set(degrees)):
        out += [e for e in itertools.product(range(d + 1), repeat=n) if sum(e) == d][::-1]
    return out


def poly_add(*polys: dict) -> dict:
    out: dict = {}
    for p in polys:
        for e, c in p.items():
            out[e] = out[e] + c if e in out else c
    return out


def poly_scale(p: dict, s) -> dict:
    return {e: s * c for e, c in p.items()}


def poly_mul(p: dict, q: dict) -> dict:
    """Product; at least one factor must have numeric coefficients (the program stays linear)."""
    out: dict = {}
    for (e1, c1), (e2, c2) in itertools.product(p.items(), q.items()):
        e = tuple(a + b for a, b in zip(e1, e2))
        term = c1 * c2
        out[e] = out[e] + term if e in out else term
    return out


def poly_diff(p: dict, i: int) -> dict:
    out = {}
    for e, c in p.items():
        if e[i] > 0:
            d = list(e)
            d[i] -= 1
            out[tuple(d)] = e[i] * c
    return out


def poly_eval(p: dict, x: np.ndarray, cache: dict | None = None) -> np.ndarray:
    """Numeric polynomial at points ``x`` (N, n): ``sum c prod(x ** e)``. ``cache``: a dict kept
    for several polynomials evaluated at these same ``x``, each power ``x ** k`` and monomial then
    computed once. The same floats either way: a power is taken as ``x ** e`` is, on the whole
    (N, n) array (NumPy's kernel for a power depends on the arrays' shapes, not on the values;
    ``tests/safety/test_sos.py`` holds the two equal), its column picked."""
    x = np.atleast_2d(x)
    powers, monomials = ({}, {}) if cache is None else (cache.setdefault("powers", {}), cache.setdefault("terms", {}))

    def monomial(e: tuple) -> np.ndarray:
        if e not in monomials:
            for k in set(e) - powers.keys():
                powers[k] = x ** np.array((k,) * len(e))
            monomials[e] = np.prod(np.column_stack([powers[k][:, j] for j, k in enumerate(e)]), axis=1)
        return monomials[e]

    return sum(float(c) * monomial(e) for e, c in p.items())


def poly_text(p: dict, variables) -> str:
    """``p`` as ``+c x^2 y  +c x ...``: signed coefficients, highest total degree first."""
    return "  ".join(_term_text(e, c, variables) for e, c in sorted(p.items(), key=lambda t: -sum(t[0])))


def _term_text(exponents: tuple[int, ...], coefficient: float, variables) -> str:
    factors = [v if k == 1 else f"{v}^{k}" for v, k in zip(variables, exponents) if k]
    return " ".join([f"{coefficient:+.6g}"] + factors)


def linear_field(M: np.ndarray) -> list[dict]:
    """``xdot = M x`` as one polynomial per state."""
    n = M.shape[0]
    unit = [tuple(int(i == j) for i in range(n)) for j in range(n)]
    return [{unit[j]: float(M[i, j]) for j in range(n) if M[i, j] != 0} for i in range(n)]


def lie_derivative(B: dict, field: list[dict]) -> dict:
    return poly_add(*[poly_mul(field[i], poly_diff(B, i)) for i in range(len(field))])


# ---------------------------------------------------------------------------------------------
# Sets and programs
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Box:
    lower: tuple[float, ...]
    upper: tuple[float, ...]

    def constraints(self) -> list[dict]:
        """``g_j = -(x_j - lo)(x_j - hi) >= 0`` per variable."""
        n = len(self.lower)
        out = []
        for j, (lo, hi) in enumerate(zip(self.lower, self.upper)):
            x = {tuple(int(i == j) for i in range(n)): 1.0}
            one = {(0,) * n: 1.0}
            out.append(poly_scale(poly_mul(poly_add(x, poly_scale(one, -lo)), poly_add(x, poly_scale(one, -hi))), -1.0))
        return out

    def scaled(self, scale: np.ndarray) -> "Box":
        return Box(tuple(np.array(self.lower) / scale), tuple(np.array(self.upper) / scale))

    def grid(self, points: int) -> np.ndarray:
        axes = [np.linspace(lo, hi, points) for lo, hi in zip(self.lower, self.upper)]
        return np.array(list(itertools.product(*axes)))


@dataclass(frozen=True)
class BarrierProgram:
    """A closed loop ``xdot = M x`` and the sets and degrees of its certificate search."""

    name: str
    variables: tuple[str, ...]
    M: np.ndarray                 # closed-loop matrix (SI)
    X: Box
    X0: Box
    Xu: Box
    eps_bar: float
    b_degrees: tuple[int, ...]    # monomial degrees of B
    q_half_degree: int            # multipliers q = z^T Q z with z of degree <= this
    scale: np.ndarray             # variables are divided by this (to the unit box)

    def __post_init__(self):
        if not (np.isfinite(self.eps_bar) and self.eps_bar > 0):
            raise RcmKinError(f"program '{self.name}': eps_bar is a finite number > 0, got {self.eps_bar}")
        for label, box in (("X", self.X), ("X0", self.X0), ("Xu", self.Xu)):
            if not np.all(np.isfinite([*box.lower, *box.upper])):
                raise RcmKinError(f"program '{self.name}': the set {label} has a non-finite bound "
                                  f"({list(box.lower)} to {list(box.upper)} m); check `delta`, `error_bound`, `r_max`",
                                  parameter=("delta", "error_bound", "r_max"))
            if not all(lo < hi for lo, hi in zip(box.lower, box.upper)):
                raise RcmKinError(f"program '{self.name}': the set {label} is empty "
                                  f"({list(box.lower)} to {list(box.upper)} m); check `delta`, `error_bound`, `r_max`",
                                  parameter=("delta", "error_bound", "r_max"))
            if not all(X_lo <= lo and hi <= X_hi for lo, hi, X_lo, X_hi in
                       zip(box.lower, box.upper, self.X.lower, self.X.upper)):
                raise RcmKinError(f"program '{self.name}': the set {label} leaves the considered set X")
        if not self.eps_bar > 0:
            raise RcmKinError(f"eps_bar must be positive, got {self.eps_bar}")


TAU = 0.11                        # s, the slide's first-order time constant


def thesis_program(number: str, delta: float | None = None, error_bound: float | None = None,
                   r_max: float | None = None, eps_bar: float | None = None) -> BarrierProgram:
    """The thesis's programs with its parameters (override ``delta`` = the separation of X0 and
    Xu, ``error_bound`` = delta_err of programs 3-4, ``r_max`` of program 2, ``eps_bar``)."""
    if number == "1":
        d, e = delta if delta is not None else 1e-3, eps_bar if eps_bar is not None else 1e-3
        return BarrierProgram("slide, first order, zero reference", ("x",), np.array([[-(9 + 1) / TAU]]),
                              Box((-0.1,), (0.1,)), Box((-0.1,), (0.05 - d,)), Box((0.05,), (0.1,)), e,
                              (0, 1, 2, 3, 4), 2, np.array([0.1]))
    if number == "2":
        d, e = delta if delta is not None else 0.015, eps_bar if eps_bar is not None else 0.1
        r = r_max if r_max is not None else 0.017
        M = np.array([[-1.2 / TAU, 1.2 / TAU], [0.0, 0.0]])
        return BarrierProgram("slide, first order, reference as a state", ("x", "x_ref"), M,
                              Box((-0.1, -0.1), (0.1, r)), Box((-0.1, -0.1), (0.05 - d, r)),
                              Box((0.05, -0.1), (0.1, r)),
                              e, tuple(range(7)), 1, np.array([0.1, 0.1]))
    if number == "3":
        d, e = delta if delta is not None else 0.004, eps_bar if eps_bar is not None else 1e-2
        b = error_bound if error_bound is not None else 0.009
        return BarrierProgram("slide, first-order error state", ("x_err",), np.array([[-1.2 / TAU]]),
                              Box((-0.03,), (0.03,)), Box((-b + d,), (0.03,)), Box((-0.03,), (-b,)), e,
                              tuple(range(7)), 2, np.array([0.03]))
    if number == "4":
        d, e = delta if delta is not None else 0.005, eps_bar if eps_bar is not None else 0.05
        b = error_bound if error_bound is not None else 0.008
        wn, zeta = 18.0, 0.5719
        A = np.array([[0.0, 1.0], [-wn**2, -2 * zeta * wn]])
        Bm = np.array([[0.0], [wn**2]])
        M = A - Bm @ np.array([[5.173, 0.214]])
        return BarrierProgram("slide, second-order error state", ("x_err", "v_err"), M,
                              Box((-0.03, -0.5), (0.03, 0.5)), Box((-b + d, -0.5), (0.03, 0.5)),
                              Box((-0.03, -0.5), (-b, 0.5)), e, (0, 1, 2, 3, 4), 1, np.array([0.03, 0.5]))
    raise RcmKinError(f"unknown program '{number}' (choose from {', '.join(PROGRAMS)})")


@dataclass(frozen=True)
class Certificate:
    feasible: bool
    status: str
    B: dict                       # exponent tuple -> coefficient, in the program's SI variables
    program: BarrierProgram
    check: SamplingCheck | None = None    # check_by_sampling of B (None: the solver gave no B)

    def as_dict(self) -> dict:
        return {"variables": list(self.program.variables),
                "terms": [{"exponents": list(e), "coefficient": float(c)} for e, c in sorted(self.B.items())]}


def find_certificate(program: BarrierProgram, solver: str | None = None) -> Certificate:
    """Search a certificate of ``program`` (an SDP through cvxpy)."""
    try:
        import cvxpy as cp
    except ImportError:
        raise RcmKinError("the SOS certificates need cvxpy: pip install 'rcm-kin[sos]'") from None
    n = len(program.variables)
    s = program.scale
    # scaled variables y = x / s: ydot = S^-1 M S y
    field = linear_field(np.diag(1 / s) @ program.M @ np.diag(s))
    X, X0, Xu = (box.scaled(s) for box in (program.X, program.X0, program.Xu))
    constraints = []

    def sos(half_degree: int) -> dict:
        z = monomials(n, range(half_degree + 1))
        Q = cp.Variable((len(z), len(z)), symmetric=True)
        constraints.append(Q >> 0)
        out: dict = {}
        for (i, a), (j, b) in itertools.product(enumerate(z), enumerate(z)):
            e = tuple(x + y for x, y in zip(a, b))
            out[e] = out[e] + Q[i, j] if e in out else Q[i, j]
        return out

    def require_sos(p: dict) -> None:
        degree = max(sum(e) for e in p)
        target = sos((degree + 1) // 2)
        for e in set(p) | set(target):
            constraints.append((p.get(e, 0.0) - target.get(e, 0.0)) == 0)

    def multiplier_terms(box: Box) -> dict:
        return poly_add(*[poly_mul(g, sos(program.q_half_degree)) for g in box.constraints()])

    coefficients = cp.Variable(len(monomials(n, program.b_degrees)))
    B = {e: coefficients[k] for k, e in enumerate(monomials(n, program.b_degrees))}
    one = {(0,) * n: 1.0}
    require_sos(poly_add(poly_scale(B, -1.0), poly_scale(multiplier_terms(X0), -1.0)))
    require_sos(poly_add(B, poly_scale(one, -program.eps_bar), poly_scale(multiplier_terms(Xu), -1.0)))
    lie = lie_derivative(B, [{e: c for e, c in f.items()} for f in field])
    require_sos(poly_add(poly_scale(lie, -1.0), poly_scale(multiplier_terms(X), -1.0)))
    problem = cp.Problem(cp.Minimize(0), constraints)
    try:
        with warnings.catch_warnings():          # "solution may be inaccurate": judged by sampling below
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=solver or ("CLARABEL" if "CLARABEL" in cp.installed_solvers() else "SCS"))
    except cp.error.SolverError as exc:
        return Certificate(False, f"solver error: {exc}", {}, program)
    solved = problem.status in ("optimal", "optimal_inaccurate") and coefficients.value is not None
    values = {} if not solved else {
        e: float(coefficients.value[k]) / float(np.prod(s ** np.array(e)))
        for k, e in enumerate(monomials(n, program.b_degrees))}
    # a certificate counts once it passes the sampling check as well (the solver's word alone can be
    # inaccurate)
    check = check_by_sampling(values, program) if solved else None
    return Certificate(solved and check.passed, problem.status, values, program, check)


@dataclass(frozen=True)
class SamplingCheck:
    """The three conditions on dense grids of the sets (the analogue of SOSTOOLS' findsos)."""

    initial_max_B: float          # max of B on X0 (<= 0 required)
    unsafe_min_B: float           # min of B on Xu (> 0 required)
    max_lie: float                # max of L_f B on X (<= 0 required), 1/s units of B
    passed: bool


def check_by_sampling(B: dict, program: BarrierProgram, points: int = 201, tol: float = 1e-9) -> SamplingCheck:
    """Evaluate a certificate (SI variables) on ``points`` per axis of X0, Xu and X. ``tol`` is
    relative to the largest |coefficient contribution| (the solver's round-off)."""
    n = len(program.variables)
    grad = [poly_diff(B, i) for i in range(n)]
    x0, xu, x = (box.grid(points) for box in (program.X0, program.Xu, program.X))
    on_x: dict = {}          # the gradient's components share their powers and monomials
    lie = sum((x @ program.M[i]) * poly_eval(grad[i], x, on_x) for i in range(n))
    scale = max(1e-12, max(abs(c) * float(np.prod(program.scale ** np.array(e))) for e, c in B.items()))
    b0, bu = poly_eval(B, x0).max(), poly_eval(B, xu).min()
    passed = bool(b0 <= tol * scale and bu > 0 and lie.max() <= tol * scale * np.abs(program.M).max())
    return SamplingCheck(float(b0), float(bu), float(lie.max()), passed)
