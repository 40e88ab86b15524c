"""Radau IIA direct collocation of the output-error estimation problem (the reference route).

Transcription
-------------
The horizon is cut into elements whose boundaries are the sample instants (each sample interval
optionally subdivided into ``subdivide`` equal elements). Within element ``k`` of length ``h_k``
the state is the polynomial through its start ``X_k`` and its ``n_c`` Radau IIA points
``X_{k,1} … X_{k,n_c}`` (the last one at the element end); the inputs are linear between samples,
as in the simulators. Decision variables: the states at every element start (the final instant
included) and collocation point, and the free parameters. Equality constraints, all in kelvin:

* dynamics at each collocation point: ``Σ_l D_{jl} X_{k,l} − h_k (A X_{k,j} + B u(t_{k,j})) = 0``;
* continuity: ``X_{k+1} − X_{k,n_c} = 0``;
* initial state: ``X_0 − x0(θ) = 0``.

Objective (``objective=``):

* ``"samples"`` (default): the sum at the samples, ``Σ_k Σ_j (q_j / N) (ŷ_jk − y_jk)²`` — the cost
  of :func:`jaxbox.fit.fit`, so both routes minimise the same function and differ only by the
  collocation discretisation of the dynamics;
* ``"quadrature"``: the Gauss–Radau quadrature of ``(1/T) ∫ eᵀ Q e dt`` with the measurements
  linearly interpolated between samples (the reference study's form).

Solver
------
A sequential quadratic programming (SQP) method on the full NLP, states and parameters
simultaneously, with exact derivatives from JAX: sparse Jacobians of the constraints and
residuals (assembled from per-element blocks); the Hessian of the Lagrangian is the Gauss–Newton
one (``JᵀJ``, positive semi-definite, robust far from the solution) until the iterates are close
to it (scaled constraint violation and relative Newton decrement below 1e-6), then the exact one
from JAX for quadratic final convergence (``hessian="auto"``; ``"exact"`` and ``"gauss-newton"``
use one throughout). Each step solves the KKT
system of the quadratic subproblem by the null-space method: the constraint Jacobian with respect
to the states is square and banded, is factorised once per iteration (sparse LU), and the step is
a particular solution of the linearised constraints plus a null-space component in the free
parameters, from a Levenberg–Marquardt-damped reduced system. Steps are accepted on the ℓ1 merit
function ``f + ν‖c‖₁`` with a second-order correction against the Maratos effect.

Scaling as in the reference study: states (and their constraints) are divided by the infinity
norm of each state's initial trajectory (at least 1 K); parameters live in the bound transform
of :func:`jaxbox.fit.make_problem` (log scale for resistances and capacities), so bounds hold at
every iterate. The initial state trajectory comes from an exact simulation with the initial
parameters, linearly interpolated to the collocation points.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .._x64 import require_x64
from ..fit import FitError, Problem, make_problem, problem_arrays
from ..models import RCModel, get_model
from ..simulate import Simulation
from ..simulate._simulate import check_theta
from ._radau import MAX_POINTS, radau_iia

__all__ = ["CollocationResult", "collocation_fit", "collocation_simulate", "OBJECTIVES"]

OBJECTIVES = ("samples", "quadrature")
HESSIANS = ("auto", "exact", "gauss-newton")
#: "auto" switches from Gauss-Newton to the exact Hessian below this scaled constraint violation
#: and relative Newton decrement.
_SWITCH = 1e-6

_CACHE: dict = {}


# ---- the transcription: grid, index maps and data on the grid --------------------------------


@dataclasses.dataclass(frozen=True)
class _Grid:
    """Elements, nodes and index maps for N samples, ``n_c`` points and ``subdivide``."""

    n_c: int
    subdivide: int
    n_states: int
    t: np.ndarray  # sample times [N]
    h: np.ndarray  # element lengths [K]
    t_nodes: np.ndarray  # node times [M], M = (n_c + 1) K + 1
    win: np.ndarray  # node rows of element k: start, collocation points, next start [K, n_c + 2]
    sample_rows: np.ndarray  # node row of each sample [N]
    colloc_rows: np.ndarray  # node rows of the collocation points [K * n_c]
    frac: np.ndarray  # position of each node within its sample interval, 0 … 1 [M]
    interval: np.ndarray  # sample interval of each node [M]

    @property
    def n_elements(self) -> int:
        return len(self.h)

    @property
    def n_nodes(self) -> int:
        return len(self.t_nodes)

    def interp(self, values: np.ndarray) -> np.ndarray:
        """Sample values [N, q] linearly interpolated onto the nodes [M, q]."""
        i, f = self.interval, self.frac[:, None]
        return values[i] + f * (values[i + 1] - values[i])


def _grid(t: np.ndarray, n_c: int, subdivide: int, n_states: int) -> _Grid:
    rad = radau_iia(n_c)
    n = len(t)
    s = subdivide
    K = (n - 1) * s
    dt = np.diff(t)
    h = np.repeat(dt / s, s)
    sub = np.tile(np.arange(s), n - 1)  # sub-element index within its sample interval
    interval_e = np.repeat(np.arange(n - 1), s)
    starts = t[interval_e] + sub * h
    tau = rad.tau  # 0, c_1 … c_n_c
    # node rows: element k owns rows k (n_c + 1) + 0 … n_c; the final start is row M − 1
    t_nodes = np.concatenate([(starts[:, None] + h[:, None] * tau[None, :]).ravel(), t[-1:]])
    frac = np.concatenate([((sub[:, None] + tau[None, :]) / s).ravel(), [1.0]])
    interval = np.concatenate([np.repeat(interval_e, n_c + 1), [n - 2]])
    base = np.arange(K) * (n_c + 1)
    win = base[:, None] + np.arange(n_c + 2)[None, :]
    colloc_rows = (base[:, None] + 1 + np.arange(n_c)[None, :]).ravel()
    sample_rows = np.arange(n) * s * (n_c + 1)
    return _Grid(
        n_c=n_c,
        subdivide=s,
        n_states=n_states,
        t=t,
        h=h,
        t_nodes=t_nodes,
        win=win,
        sample_rows=sample_rows,
        colloc_rows=colloc_rows,
        frac=frac,
        interval=interval,
    )


def _element(win, uc, h, A, B, Dm):
    """Constraints of one element in kelvin [n_c + 1, n]: dynamics at the points, continuity."""
    dyn = Dm @ win[:-1] - h * (win[1:-1] @ A.T + uc @ B.T)
    return jnp.concatenate([dyn, (win[-1] - win[-2])[None]], axis=0)


def _constraints(V, A, B, x0, uc, h, sx, win, Dm):
    """Scaled constraints [n (1 + (n_c + 1) K)] for scaled node states V [M, n]."""
    X = V * sx
    e = jax.vmap(_element, in_axes=(0, 0, 0, None, None, None))(X[win], uc, h, A, B, Dm)
    return jnp.concatenate([(X[0] - x0) / sx, (e / sx).ravel()])


def _constraint_blocks(V, A, B, uc, h, sx, win, Dm):
    """Element constraint Jacobians w.r.t. the scaled window [K, n_c + 1, n, n_c + 2, n]."""

    def scaled(wv, u_k, h_k):
        return _element(wv * sx, u_k, h_k, A, B, Dm) / sx

    return jax.vmap(jax.jacfwd(scaled), in_axes=(0, 0, 0))(V[win], uc, h)


def _outputs(V, C, D, sx, rows, u_obj):
    return (V[rows] * sx) @ C.T + u_obj @ D.T


def _residuals(V, C, D, sx, rows, u_obj, y_obj, w_obj):
    return ((_outputs(V, C, D, sx, rows, u_obj) - y_obj) * w_obj).ravel()


def _residual_blocks(V, C, D, sx, rows, u_obj, w_obj):
    """Jacobian blocks of the residuals w.r.t. the scaled node states [R, p, n]."""

    def one(v, u, w):
        return ((v * sx) @ C.T + u @ D.T) * w

    return jax.vmap(jax.jacfwd(one))(V[rows], u_obj, w_obj)


@dataclasses.dataclass(frozen=True)
class _Sparsity:
    """Row and column indices of the sparse Jacobians (numpy, built once per problem)."""

    g_rows: np.ndarray
    g_cols: np.ndarray
    j_rows: np.ndarray
    j_cols: np.ndarray
    n_x: int
    n_c: int
    n_r: int


def _sparsity(grid: _Grid, rows: np.ndarray, n_out: int) -> _Sparsity:
    n, nc, K = grid.n_states, grid.n_c, grid.n_elements
    # element constraints: rows n + (k (n_c + 1) + i) n + a, columns win[k, l] n + b
    r = n + (np.arange(K)[:, None, None] * (nc + 1) + np.arange(nc + 1)[None, :, None]) * n
    r = r + np.arange(n)[None, None, :]  # [K, nc+1, n]
    c = grid.win[:, :, None] * n + np.arange(n)[None, None, :]  # [K, nc+2, n]
    g_rows = np.broadcast_to(r[:, :, :, None, None], (K, nc + 1, n, nc + 2, n)).ravel()
    g_cols = np.broadcast_to(c[:, None, None, :, :], (K, nc + 1, n, nc + 2, n)).ravel()
    g_rows = np.concatenate([np.arange(n), g_rows])
    g_cols = np.concatenate([np.arange(n), g_cols])
    R = len(rows)
    jr = np.arange(R)[:, None, None] * n_out + np.arange(n_out)[None, :, None]
    jc = rows[:, None, None] * n + np.arange(n)[None, None, :]
    j_rows = np.broadcast_to(jr, (R, n_out, n)).ravel()
    j_cols = np.broadcast_to(jc, (R, n_out, n)).ravel()
    n_x = grid.n_nodes * n
    return _Sparsity(g_rows, g_cols, j_rows, j_cols, n_x, n_x, R * n_out)


# ---- compiled functions (one set per problem structure) --------------------------------------


def _functions(problem: Problem, n_c: int):
    model, tr = problem.model, problem.transform
    key = (*problem.structure_key, tr.kinds, n_c)
    if key in _CACHE:
        return _CACHE[key]
    n = model.n_states

    def matrices(z, a):
        p = tr.to_physical(z, a["lo"], a["hi"], a["sc"])
        theta = problem.theta(p, a["fixed"])
        A, B, C, D = model.state_space(theta)
        return A, B, C, D, model.initial_state(theta)

    def split(w, a):
        m = a["uc"].shape[0] * (n_c + 1) + 1
        return w[: m * n].reshape(m, n), w[m * n :]

    def values(w, a):
        V, z = split(w, a)
        A, B, C, D, x0 = matrices(z, a)
        c = _constraints(V, A, B, x0, a["uc"], a["h"], a["sx"], a["win"], a["Dm"])
        r = _residuals(V, C, D, a["sx"], a["rows"], a["u_obj"], a["y_obj"], a["w_obj"])
        return c, r

    def evaluate(w, a):
        V, z = split(w, a)
        c, r = values(w, a)
        A, B, C, D, _ = matrices(z, a)
        gx = _constraint_blocks(V, A, B, a["uc"], a["h"], a["sx"], a["win"], a["Dm"])
        jx = _residual_blocks(V, C, D, a["sx"], a["rows"], a["u_obj"], a["w_obj"])

        def of_z(zz):
            return values(jnp.concatenate([V.ravel(), zz]), a)

        gz, jz = jax.jacfwd(of_z)(z)
        return c, r, gx, jx, gz, jz

    def hvp(w, lam, dirs, a):
        def lagrangian(ww):
            c, r = values(ww, a)
            return 0.5 * jnp.dot(r, r) + jnp.dot(lam, c)

        grad = jax.grad(lagrangian)
        return jax.vmap(lambda d: jax.jvp(grad, (w,), (d,))[1])(dirs)

    fns = {
        "evaluate": jax.jit(evaluate),
        "hvp": jax.jit(hvp),
        "matrices": jax.jit(matrices),
    }
    _CACHE[key] = fns
    return fns


# ---- result -----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class CollocationResult:
    """The outcome of :func:`collocation_fit`.

    Attributes:
        problem: the estimation problem (as built by :func:`jaxbox.fit.make_problem`).
        data: the identification dataset.
        params: every model parameter at the solution (SI), free and fixed.
        cost: the NLP objective at the solution [K²]: the weighted mean squared output error at
            the samples (``objective="samples"``, the cost of :func:`jaxbox.fit.fit`) or its
            time-averaged Radau quadrature (``"quadrature"``).
        cost_samples: the weighted mean squared error at the samples of the collocation
            trajectory [K²] (equal to ``cost`` for ``objective="samples"``).
        t: sample times [s] since the first sample, [N].
        x: collocation states at the samples [°C], [N, n].
        y: collocation outputs at the samples [°C], [N, p].
        t_nodes: times of every node [s]: element starts and collocation points in time order
            (the last collocation point of an element and the next element's start share a
            time), [M].
        x_nodes: states at every node [°C], [M, n].
        status: ``"converged"``, ``"max_iterations"``, ``"nonfinite"`` or ``"failed"``.
        message: what happened, in words.
        iterations: SQP iterations.
        constraint_violation: largest scaled constraint residual (divided by the state scale).
        constraint_violation_raw: largest constraint residual [K].
        stats: solver statistics (sizes, evaluations, rejected steps, penalty, final damping,
            reduced gradient, Newton decrement, state scales, ...).
        history: one dict per iteration (cost, constraint violation, damping, step, ratio).
        timing: ``setup_s`` (problem, arrays, compilation, initial simulation), ``solve_s``,
            ``total_s`` [s].
        settings: ``n_c``, ``subdivide``, ``objective``, ``hessian`` and the tolerances.
    """

    problem: Problem
    data: object
    params: dict
    cost: float
    cost_samples: float
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    t_nodes: np.ndarray
    x_nodes: np.ndarray
    status: str
    message: str
    iterations: int
    constraint_violation: float
    constraint_violation_raw: float
    stats: dict
    history: tuple
    timing: dict
    settings: dict

    @property
    def model(self) -> RCModel:
        return self.problem.model

    @property
    def free(self) -> tuple[str, ...]:
        return self.problem.free

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def post_simulate(self, data=None, *, method: str = "diffrax", **options) -> Simulation:
        """Simulate the model with the estimated parameters (default: adaptive diffrax).

        ``data`` defaults to the identification data; ``options`` go to
        :func:`jaxbox.simulate.simulate_model` (e.g. ``rtol``, ``atol``).
        """
        from ..simulate import simulate_model

        return simulate_model(
            self.model, self.params, self.data if data is None else data, method=method, **options
        )

    def summary(self) -> str:
        s = self.stats
        lines = [
            f"model {self.model.name}: Radau IIA collocation, n_c={self.settings['n_c']}, "
            f"{s['n_elements']} elements, objective {self.settings['objective']}",
            f"status {self.status}: {self.message}",
            f"cost {self.cost:.10g} K², RMS error {np.sqrt(self.cost_samples):.6f} K at the "
            "samples",
            f"{self.iterations} SQP iterations ({self.settings['hessian']} Hessian), "
            f"{s['n_evaluations']} evaluations, {s['n_rejected']} rejected steps; "
            f"{s['n_variables']} variables, {s['n_constraints']} constraints",
            f"constraint violation {self.constraint_violation:.2e} (scaled), "
            f"{self.constraint_violation_raw:.2e} K",
            f"time: setup {self.timing['setup_s']:.2f} s, solve {self.timing['solve_s']:.2f} s",
        ]
        for name in self.model.param_names:
            note = "" if name in self.free else "  fixed"
            unit = self.model.parameter(name).unit
            lines.append(f"  {name:<10} {self.params[name]:>14.7g} {unit}{note}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"CollocationResult(model={self.model.name!r}, status={self.status!r}, "
            f"cost={self.cost:.6g}, iterations={self.iterations}, "
            f"constraint_violation={self.constraint_violation:.2e})"
        )


# ---- the SQP solver ---------------------------------------------------------------------------


class _Failure(Exception):
    def __init__(self, status: str, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


def _check_options(n_c, subdivide, objective, hessian):
    if not isinstance(n_c, int | np.integer) or not 1 <= n_c <= MAX_POINTS:
        raise FitError(f"n_c must be an integer from 1 to {MAX_POINTS}, got {n_c!r}")
    if not isinstance(subdivide, int | np.integer) or subdivide < 1:
        raise FitError(f"subdivide must be a positive integer, got {subdivide!r}")
    if objective not in OBJECTIVES:
        raise FitError(f"unknown objective {objective!r}; choose one of {OBJECTIVES}")
    if hessian not in HESSIANS:
        raise FitError(f"unknown hessian {hessian!r}; choose one of {HESSIANS}")


def collocation_fit(
    model,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    n_c: int = 3,
    subdivide: int = 1,
    objective: str = "samples",
    hessian: str = "auto",
    max_iterations: int = 100,
    ctol: float = 1e-10,
    ftol: float = 1e-14,
) -> CollocationResult:
    """Estimate the parameters of ``model`` by Radau IIA direct collocation (the reference route).

    The estimation problem (free/fixed split, bounds, guesses, weights) is the one of
    :func:`jaxbox.fit.fit`, with the same meaning of every argument; the dynamics are enforced
    by collocation instead of simulation, and states and parameters are solved for
    simultaneously by SQP (see the module documentation). Not the default route: it is slower
    and carries a discretisation error (order ``2 n_c − 1`` at the samples), and exists to
    cross-check :func:`jaxbox.fit.fit` and for users of the collocation method.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        data: the identification :class:`~jaxbox.data.Dataset`.
        free, fixed, bounds, guess, weights: as in :func:`jaxbox.fit.fit`.
        n_c: Radau collocation points per element (1 … 5).
        subdivide: elements per sample interval (1: element boundaries at the samples).
        objective: ``"samples"`` (sum at the samples, the fit's cost) or ``"quadrature"``.
        hessian: ``"auto"`` (Gauss–Newton far from the solution, the exact Hessian of the
            Lagrangian close to it), ``"exact"`` or ``"gauss-newton"``.
        max_iterations: SQP iteration cap.
        ctol: tolerance on the scaled constraint violation (max norm, dimensionless).
        ftol: tolerance on the Newton decrement relative to the objective: converged when the
            quadratic model predicts a relative decrease below ``ftol`` and the constraints
            hold to ``ctol``.

    Returns:
        :class:`CollocationResult`; check ``status`` (a failed solve is reported there, with a
        message, not raised).

    Raises:
        FitError: an ill-posed problem or a bad option (as :func:`jaxbox.fit.fit`).
    """
    require_x64()
    t_start = time.perf_counter()
    model = get_model(model)
    _check_options(n_c, subdivide, objective, hessian)
    n_c, subdivide = int(n_c), int(subdivide)
    problem = make_problem(
        model, data, free=free, fixed=fixed, bounds=bounds, guess=guess, weights=weights
    )
    tx = _transcribe(problem, data, n_c, subdivide, objective)
    grid, args, sparsity, fns = tx.grid, tx.args, tx.sparsity, tx.fns
    settings = {
        "n_c": n_c,
        "subdivide": subdivide,
        "objective": objective,
        "hessian": hessian,
        "max_iterations": max_iterations,
        "ctol": ctol,
        "ftol": ftol,
    }
    stats = {
        "n_elements": grid.n_elements,
        "n_variables": sparsity.n_x + len(problem.free),
        "n_constraints": sparsity.n_c,
        "n_residuals": sparsity.n_r,
        "nnz_constraint_jacobian": len(sparsity.g_rows) + sparsity.n_c * len(problem.free),
        "n_evaluations": 0,
        "n_rejected": 0,
        "n_second_order_corrections": 0,
    }
    history: list[dict] = []
    w = np.concatenate([np.zeros(sparsity.n_x), tx.z0])
    status, message, iterations = "failed", "", 0
    t_setup = None
    try:
        w = _initial_point(tx)
        jargs = _jargs(args)
        # compile (or fetch) every function before the clock of the solve starts
        jw = jnp.asarray(w)
        jax.block_until_ready(fns["evaluate"](jw, jargs))
        if hessian != "gauss-newton":
            n_free = len(problem.free)
            dirs = jnp.zeros((n_free + 1, w.size))
            jax.block_until_ready(fns["hvp"](jw, jnp.zeros(sparsity.n_c), dirs, jargs))
        t_setup = time.perf_counter()
        w, iterations, status, message = _sqp(
            fns, w, jargs, sparsity, len(problem.free), hessian, max_iterations, ctol, ftol,
            stats, history,
        )  # fmt: skip
    except _Failure as err:
        status, message = err.status, err.message
    except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError) as err:
        status, message = "failed", f"the SQP solve stopped: {type(err).__name__}: {err}"
    t_end = time.perf_counter()
    if t_setup is None:
        t_setup = t_end
    return _result(
        problem, data, grid, args, fns, w, sparsity, status, message, iterations, stats,
        history, settings,
        {"setup_s": t_setup - t_start, "solve_s": t_end - t_setup, "total_s": t_end - t_start},
        tx.y, tx.sqrt_w, tx.u,
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class _Transcription:
    """The NLP of one problem and dataset: grid, data on the grid, sparsity, compiled functions.

    ``args`` holds the numpy arguments of the compiled functions; ``args["sx"]`` (the state
    scales) is set by :func:`_initial_point`.
    """

    problem: Problem
    grid: _Grid
    args: dict
    sparsity: _Sparsity
    fns: dict
    z0: np.ndarray
    ue: np.ndarray
    u: np.ndarray
    y: np.ndarray
    sqrt_w: np.ndarray


def _transcribe(problem: Problem, data, n_c: int, subdivide: int, objective: str):
    model = problem.model
    t, u, y, sqrt_w = problem_arrays(problem, data)
    n, n_out = model.n_states, len(model.outputs)
    grid = _grid(t, n_c, subdivide, n)
    rad = radau_iia(n_c)
    tr = problem.transform
    z0 = tr.to_internal(np.asarray([problem.guess_dict[p] for p in problem.free]))
    u_nodes = grid.interp(u)
    uc = u_nodes[: grid.n_elements * (n_c + 1)].reshape(grid.n_elements, n_c + 1, -1)[:, 1:]
    ue = u_nodes[np.concatenate([np.arange(grid.n_elements) * (n_c + 1), [grid.n_nodes - 1]])]
    if objective == "samples":
        rows = grid.sample_rows
        u_obj, y_obj = u, y
        w_obj = np.broadcast_to(sqrt_w, y.shape)
    else:
        rows = grid.colloc_rows
        u_obj = u_nodes[rows]
        y_obj = grid.interp(y)[rows]
        span = t[-1] - t[0]
        bh = (grid.h[:, None] * rad.b[None, :]).ravel() / span
        w_obj = np.sqrt(bh[:, None] * np.asarray(problem.weights)[None, :])
    args = {
        "fixed": np.asarray([v for _, v in problem.fixed], dtype=float),
        "lo": tr.lower,
        "hi": tr.upper,
        "sc": tr.scale,
        "uc": uc,
        "h": grid.h,
        "sx": np.ones(n),
        "win": grid.win,
        "Dm": np.asarray(rad.D),
        "rows": rows,
        "u_obj": u_obj,
        "y_obj": y_obj,
        "w_obj": np.asarray(w_obj, dtype=float),
    }
    return _Transcription(
        problem=problem,
        grid=grid,
        args=args,
        sparsity=_sparsity(grid, rows, n_out),
        fns=_functions(problem, n_c),
        z0=z0,
        ue=ue,
        u=u,
        y=y,
        sqrt_w=sqrt_w,
    )


def _initial_point(tx: _Transcription) -> np.ndarray:
    """Scaled variables from an exact simulation with the initial parameters (sets the state
    scales in ``tx.args``)."""
    grid, n_c = tx.grid, tx.grid.n_c
    jargs = _jargs(tx.args)
    A, B, _, _, x0 = (np.asarray(a) for a in tx.fns["matrices"](jnp.asarray(tx.z0), jargs))
    xe = _simulate_elements(A, B, x0, tx.ue, grid.h)
    if not np.all(np.isfinite(xe)):
        raise _Failure(
            "nonfinite",
            "the simulation with the initial parameters is not finite; check the guess and "
            "the fixed values (capacities and resistances must be positive)",
        )
    elem = np.minimum(np.arange(grid.n_nodes) // (n_c + 1), grid.n_elements - 1)
    tau = np.concatenate([np.tile(radau_iia(n_c).tau, grid.n_elements), [1.0]])
    x_nodes0 = xe[elem] + tau[:, None] * (xe[elem + 1] - xe[elem])
    sx = np.maximum(np.max(np.abs(x_nodes0), axis=0), 1.0)
    tx.args["sx"] = sx
    return np.concatenate([(x_nodes0 / sx).ravel(), tx.z0])


def _simulate_elements(A, B, x0, ue, h) -> np.ndarray:
    """Exact first-order-hold simulation on the element grid (numpy): states at the starts."""
    n, m = B.shape
    out = np.empty((len(h) + 1, n))
    out[0] = x = x0
    cache = {}
    with np.errstate(all="ignore"):
        for k, hk in enumerate(h):
            if hk not in cache:
                M = np.zeros((n + 2 * m, n + 2 * m))
                M[:n, :n], M[:n, n : n + m] = A * hk, B * hk
                M[n : n + m, n + m :] = np.eye(m)
                E = scipy.linalg.expm(M) if np.all(np.isfinite(M)) else np.full(M.shape, np.nan)
                cache[hk] = (E[:n, :n], E[:n, n : n + m], E[:n, n + m :])
            Phi, G0, G1 = cache[hk]
            x = Phi @ x + G0 @ ue[k] + G1 @ (ue[k + 1] - ue[k])
            out[k + 1] = x
    return out


def _jargs(args: dict) -> dict:
    return {k: jnp.asarray(v) for k, v in args.items()}


def _assemble(sp: _Sparsity, gx, jx):
    n = sp.n_x
    g_data = np.concatenate([np.ones(sp.g_rows.size - gx.size), np.asarray(gx).ravel()])
    GX = scipy.sparse.csc_matrix((g_data, (sp.g_rows, sp.g_cols)), shape=(n, n))
    j_data = np.asarray(jx).ravel()
    JX = scipy.sparse.csr_matrix((j_data, (sp.j_rows, sp.j_cols)), shape=(sp.n_r, n))
    return GX, JX


def _sqp(fns, w, jargs, sp, p, hessian, max_iterations, ctol, ftol, stats, history):
    """The SQP iteration; returns (w, iterations, status, message), the last iterate on failure."""
    last = {"w": w, "it": 0}
    try:
        return _sqp_loop(
            fns, w, jargs, sp, p, hessian, max_iterations, ctol, ftol, stats, history, last
        )
    except _Failure as err:
        return last["w"], last["it"], err.status, err.message
    except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError) as err:
        return (
            last["w"],
            last["it"],
            "failed",
            (f"the SQP solve stopped at iteration {last['it']}: {type(err).__name__}: {err}"),
        )


def _sqp_loop(fns, w, jargs, sp, p, hessian, max_iterations, ctol, ftol, stats, history, last):
    nx = sp.n_x
    mu, grow = None, 2.0
    nu = 0.0
    dscale = np.zeros(p)
    eta = 1e-4
    switched = False

    def evaluate(ww):
        stats["n_evaluations"] += 1
        out = fns["evaluate"](jnp.asarray(ww), jargs)
        return [np.asarray(o) for o in out]

    def values(ww):
        stats["n_evaluations"] += 1
        c, r = fns["evaluate"](jnp.asarray(ww), jargs)[:2]
        return np.asarray(c), np.asarray(r)

    c, r, gx, jx, gz, jz = evaluate(w)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
        raise _Failure("nonfinite", "the constraints or residuals are not finite at the start")
    for it in range(max_iterations + 1):
        last["it"] = it
        f = 0.5 * float(r @ r)
        viol = float(np.max(np.abs(c)))
        GX, JX = _assemble(sp, gx, jx)
        try:
            lu = scipy.sparse.linalg.splu(GX)
        except RuntimeError as err:
            raise _Failure(
                "failed",
                f"the collocation equations are singular at iteration {it} ({err}); the "
                "parameters make the discretised dynamics degenerate",
            ) from None
        S = lu.solve(np.column_stack([c, gz]))
        YX, ZX = -S[:, 0], -S[:, 1:]
        gX, gZ = JX.T @ r, jz.T @ r
        lam = -lu.solve(gX, trans="T")
        JZ = JX @ ZX + jz
        JY = JX @ YX
        # Gauss-Newton reduced Hessian and gradient (always: cheap, and the fallback)
        Hr = JZ.T @ JZ
        gr = JZ.T @ (r + JY)
        decrement = _decrement(Hr, gr)
        exact = hessian == "exact" or (
            hessian == "auto" and (switched or (viol <= _SWITCH and decrement <= _SWITCH * f))
        )
        if exact:
            dirs = np.zeros((p + 1, nx + p))
            dirs[0, :nx] = YX
            dirs[1:, :nx] = ZX.T
            dirs[1:, nx:] = np.eye(p)
            HV = np.asarray(fns["hvp"](jnp.asarray(w), jnp.asarray(lam), jnp.asarray(dirs), jargs))
            HY, HZ = HV[0], HV[1:].T
            Hr_e = ZX.T @ HZ[:nx] + HZ[nx:]
            gr_e = ZX.T @ (gX + HY[:nx]) + (gZ + HY[nx:])
            dec_e = _decrement(Hr_e, gr_e)
            if hessian == "exact" or np.isfinite(dec_e):
                Hr, gr, decrement, switched = Hr_e, gr_e, dec_e, True
            else:  # not positive definite: a Gauss-Newton step this time
                exact = False
        Hr = 0.5 * (Hr + Hr.T)
        entry = {
            "iteration": it,
            "cost": 2 * f,
            "constraint_violation": viol,
            "reduced_gradient": float(np.max(np.abs(gr))),
            "decrement": decrement,
            "hessian": "exact" if exact else "gauss-newton",
        }
        history.append(entry)
        stats.update(
            reduced_gradient=entry["reduced_gradient"],
            newton_decrement=decrement,
            multipliers_max=float(np.max(np.abs(lam))),
        )
        if viol <= ctol and decrement <= ftol * f + 1e-300:
            return (
                w,
                it,
                "converged",
                (
                    f"constraints hold to {viol:.1e} (scaled) and the predicted relative decrease "
                    f"of the cost is {decrement / max(f, 1e-300):.1e}"
                ),
            )
        if it == max_iterations:
            break
        dscale = np.maximum(dscale, np.abs(np.diag(Hr)))
        dfloor = np.maximum(dscale, 1e-12 * max(float(np.max(dscale)), 1e-300))
        if mu is None:
            mu = 1e-3
        c1 = float(np.sum(np.abs(c)))
        nu = max(nu, 1.01 * float(np.max(np.abs(lam))))
        accepted = False
        while not accepted:
            M = Hr + mu * np.diag(dfloor)
            try:
                cho = scipy.linalg.cho_factor(M)
            except (np.linalg.LinAlgError, ValueError):
                mu, grow = mu * grow, grow * 2
                if mu > 1e20:
                    raise _Failure(
                        "failed", "the reduced Hessian stays indefinite under any damping"
                    ) from None
                continue
            dz = -scipy.linalg.cho_solve(cho, gr)
            dX = YX + ZX @ dz
            d = np.concatenate([dX, dz])
            gd = float(gX @ dX + gZ @ dz)
            if exact:
                Hd = HY + HZ @ dz
                dHd = float(d @ Hd)
            else:
                Jd = JY + JZ @ dz
                dHd = float(Jd @ Jd)
            pred_f = -(gd + 0.5 * dHd)
            if c1 > 0 and pred_f < 0:
                nu = max(nu, -2.0 * pred_f / c1)
            pred = pred_f + nu * c1
            phi = f + nu * c1
            trial = w + d
            c_t, r_t = values(trial)
            phi_t = _merit(c_t, r_t, nu)
            ratio = (phi - phi_t) / pred if pred > 0 else -np.inf
            if not ratio >= eta:
                # second-order correction: restore the linearised constraints at the trial
                if np.all(np.isfinite(c_t)):
                    soc = trial.copy()
                    soc[:nx] -= lu.solve(c_t)
                    c_s, r_s = values(soc)
                    phi_s = _merit(c_s, r_s, nu)
                    ratio_s = (phi - phi_s) / pred if pred > 0 else -np.inf
                    if ratio_s >= eta:
                        stats["n_second_order_corrections"] += 1
                        trial, ratio = soc, ratio_s
            if ratio >= eta:
                accepted = True
                if ratio > 0.25:
                    mu = max(mu / 10.0, 1e-12)
                elif ratio < 0.1:
                    mu *= 2.0
                grow = 2.0
                entry.update(mu=mu, step=float(np.max(np.abs(dz))), ratio=float(ratio), nu=nu)
                w = last["w"] = trial
            else:
                stats["n_rejected"] += 1
                mu, grow = mu * grow, grow * 2
                if mu > 1e20 or not np.isfinite(pred):
                    if viol <= ctol and decrement <= 1e-10 * f:
                        return (
                            w,
                            it,
                            "converged",
                            (
                                "no further decrease at round-off level; constraints hold to "
                                f"{viol:.1e} (scaled)"
                            ),
                        )
                    raise _Failure(
                        "failed",
                        f"no step decreases the merit function at iteration {it} (constraint "
                        f"violation {viol:.1e}, cost {2 * f:.6g}); try other starting values",
                    )
        c, r, gx, jx, gz, jz = evaluate(w)
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
            raise _Failure("nonfinite", f"non-finite constraints or residuals at iteration {it}")
    stats["penalty"] = nu
    return (
        w,
        max_iterations,
        "max_iterations",
        (
            f"stopped after {max_iterations} iterations (constraint violation {viol:.1e}, Newton "
            f"decrement {decrement:.1e}); raise max_iterations or check the problem"
        ),
    )


def _decrement(H, g) -> float:
    """Newton decrement ``gᵀ H⁻¹ g``; ``inf`` when H is not positive definite."""
    try:
        cho = scipy.linalg.cho_factor(0.5 * (H + H.T))
    except (np.linalg.LinAlgError, ValueError):
        return np.inf
    return float(g @ scipy.linalg.cho_solve(cho, g))


def _merit(c, r, nu):
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
        return np.inf
    return 0.5 * float(r @ r) + nu * float(np.sum(np.abs(c)))


def _result(
    problem, data, grid, args, fns, w, sp, status, message, iterations, stats, history,
    settings, timing, y, sqrt_w, u,
):  # fmt: skip
    n = grid.n_states
    nx = sp.n_x
    V = w[:nx].reshape(grid.n_nodes, n)
    z = w[nx:]
    x_nodes = V * args["sx"]
    p_free = np.asarray(problem.transform.to_physical(jnp.asarray(z)))
    params = dict(problem.fixed)
    params.update({k: float(v) for k, v in zip(problem.free, p_free, strict=True)})
    params = {k: float(params[k]) for k in problem.model.param_names}
    nan = float("nan")
    cost = cost_samples = viol = viol_raw = nan
    x = x_nodes[grid.sample_rows]
    yy = np.full(y.shape, nan)
    try:
        jargs = _jargs(args)
        c, r = (np.asarray(a) for a in fns["evaluate"](jnp.asarray(w), jargs)[:2])
        _, _, C, D, _ = (np.asarray(a) for a in fns["matrices"](jnp.asarray(z), jargs))
        yy = x @ C.T + u @ D.T
        cost = float(r @ r)
        cost_samples = float(np.sum(((yy - y) * sqrt_w) ** 2))
        scale = np.concatenate([args["sx"], np.tile(args["sx"], grid.n_elements * (grid.n_c + 1))])
        viol = float(np.max(np.abs(c)))
        viol_raw = float(np.max(np.abs(c * scale)))
    except (ArithmeticError, ValueError, RuntimeError):
        pass
    if status == "converged" and not np.isfinite(cost):
        status, message = "nonfinite", "the solution is not finite"
    stats = dict(stats)
    stats["state_scale"] = np.asarray(args["sx"]).tolist()
    return CollocationResult(
        problem=problem,
        data=data,
        params=params,
        cost=cost,
        cost_samples=cost_samples,
        t=grid.t,
        x=x,
        y=yy,
        t_nodes=grid.t_nodes,
        x_nodes=x_nodes,
        status=status,
        message=message,
        iterations=int(iterations),
        constraint_violation=viol,
        constraint_violation_raw=viol_raw,
        stats=stats,
        history=tuple(history),
        timing=timing,
        settings=settings,
    )


# ---- collocation as a simulator ---------------------------------------------------------------


@jax.jit
def _linear_system(A, B, x0, uc, h, win, Dm):
    """Constant part and state Jacobian blocks of the (affine) collocation equations."""
    n = A.shape[0]
    V0 = jnp.zeros((win.shape[0] * (Dm.shape[0] + 1) + 1, n))
    sx = jnp.ones(n)
    c0 = _constraints(V0, A, B, x0, uc, h, sx, win, Dm)
    return c0, _constraint_blocks(V0, A, B, uc, h, sx, win, Dm)


def collocation_simulate(
    model, theta: Mapping | None, data, *, n_c: int = 3, subdivide: int = 1, nodes: bool = False
):
    """Solve the collocation equations for fixed parameters (the Radau IIA method as a simulator).

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        theta: every parameter value (SI); ``None`` for the model's defaults.
        data: a :class:`~jaxbox.data.Dataset` with the model's inputs.
        n_c: Radau points per element (1 … 5).
        subdivide: elements per sample interval.
        nodes: also return ``(t_nodes [M], x_nodes [M, n])``, the states at every node.

    Returns:
        :class:`~jaxbox.simulate.Simulation` at the samples (and the nodes when asked).
    """
    require_x64()
    model = get_model(model)
    _check_options(n_c, subdivide, "samples", "exact")
    theta = check_theta(model, theta)
    u = data.array(list(model.inputs))
    t = np.asarray(data.t, dtype=float)
    grid = _grid(t, int(n_c), int(subdivide), model.n_states)
    rad = radau_iia(int(n_c))
    n = model.n_states
    u_nodes = grid.interp(u)
    uc = u_nodes[: grid.n_elements * (n_c + 1)].reshape(grid.n_elements, n_c + 1, -1)[:, 1:]
    th = {k: jnp.asarray(v, dtype=float) for k, v in theta.items()}
    A, B, C, D = model.state_space(th)
    x0 = model.initial_state(th)
    c0, gx = _linear_system(
        A, B, x0, jnp.asarray(uc), jnp.asarray(grid.h), jnp.asarray(grid.win), jnp.asarray(rad.D)
    )
    c0, gx = np.asarray(c0), np.asarray(gx)
    sp = _sparsity(grid, grid.sample_rows, len(model.outputs))
    GX, _ = _assemble(sp, gx, np.zeros(len(sp.j_rows)))
    x_nodes = -scipy.sparse.linalg.spsolve(GX, c0).reshape(grid.n_nodes, n)
    x = x_nodes[grid.sample_rows]
    y = x @ np.asarray(C).T + u @ np.asarray(D).T
    sim = Simulation(t, y, x)
    return (sim, grid.t_nodes, x_nodes) if nodes else sim
