"""Radau IIA direct collocation of the output-error estimation problem (the reference route).

The two verbs of the reference route; the work is done by one file per job:

* :mod:`._grid` — elements, nodes and index maps; the sparsity of the Jacobians (numpy);
* :mod:`._transcription` — the NLP (variables, constraints, objective and its quadrature) and
  its compiled functions;
* :mod:`._solver` — the initial point and the SQP iteration;
* :mod:`._result` — :class:`CollocationResult` and its summary.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse.linalg
from jaxtyping import Float

from .._x64 import require_x64
from ..fit import FitError, make_problem
from ..models import get_model
from ..simulate import Simulation
from ..simulate._simulate import check_theta
from ._grid import _assemble, _grid, _sparsity
from ._radau import MAX_POINTS, radau_iia
from ._result import CollocationResult, _result
from ._solver import _Failure, _initial_point, _sqp
from ._transcription import (
    _constraint_blocks,
    _constraints,
    _jargs,
    _transcribe,
    _Transcription,
)

__all__ = ["CollocationResult", "collocation_fit", "collocation_simulate", "OBJECTIVES"]

OBJECTIVES = ("samples", "quadrature")
"""The collocation objectives: squared errors at the samples, or their quadrature over time."""
HESSIANS = ("auto", "exact", "gauss-newton")


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
    :func:`jaxbox.fit.fit_model`, with the same meaning of every argument; the dynamics are enforced
    by collocation instead of simulation, and states and parameters are solved for
    simultaneously by SQP (see the module documentation). Not the default route: it is slower
    and carries a discretisation error (order ``2 n_c − 1`` at the samples), and exists to
    cross-check :func:`jaxbox.fit.fit_model` and for users of the collocation method.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        data: the identification :class:`~jaxbox.data.Dataset`.
        free, fixed, bounds, guess, weights: as in :func:`jaxbox.fit.fit_model`.
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
        FitError: an ill-posed problem or a bad option (as :func:`jaxbox.fit.fit_model`).
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
    settings = {
        "n_c": n_c,
        "subdivide": subdivide,
        "objective": objective,
        "hessian": hessian,
        "max_iterations": max_iterations,
        "ctol": ctol,
        "ftol": ftol,
    }
    stats = _initial_stats(tx)
    history: list[dict] = []
    w = np.concatenate([np.zeros(tx.sparsity.n_x), tx.z0])
    status, message, iterations = "failed", "", 0
    t_setup = None
    try:
        w = _initial_point(tx)
        jargs = _jargs(tx.args)
        _compile(tx, w, jargs, hessian)  # before the clock of the solve starts
        t_setup = time.perf_counter()
        w, iterations, status, message = _sqp(
            tx.fns, w, jargs, tx.sparsity, len(problem.free), hessian, max_iterations, ctol,
            ftol, stats, history,
        )  # fmt: skip
    except _Failure as err:
        status, message = err.status, err.message
    except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError) as err:
        status, message = "failed", f"the SQP solve stopped: {type(err).__name__}: {err}"
    t_end = time.perf_counter()
    if t_setup is None:
        t_setup = t_end
    timing = {"setup_s": t_setup - t_start, "solve_s": t_end - t_setup, "total_s": t_end - t_start}
    return _result(tx, data, w, status, message, iterations, stats, history, settings, timing)


def _initial_stats(tx: _Transcription) -> dict:
    """The sizes of the NLP and zeroed counters of the solve."""
    sp, n_free = tx.sparsity, len(tx.problem.free)
    return {
        "n_elements": tx.grid.n_elements,
        "n_variables": sp.n_x + n_free,
        "n_constraints": sp.n_c,
        "n_residuals": sp.n_r,
        "nnz_constraint_jacobian": len(sp.g_rows) + sp.n_c * n_free,
        "n_evaluations": 0,
        "n_rejected": 0,
        "n_second_order_corrections": 0,
    }


def _compile(tx: _Transcription, w, jargs, hessian: str) -> None:
    """Compile (or fetch) every function the solve will call."""
    jw = jnp.asarray(w)
    jax.block_until_ready(tx.fns["evaluate"](jw, jargs))
    if hessian != "gauss-newton":
        dirs = jnp.zeros((len(tx.problem.free) + 1, w.size))
        jax.block_until_ready(tx.fns["hvp"](jw, jnp.zeros(tx.sparsity.n_c), dirs, jargs))


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
) -> Simulation | tuple[Simulation, Float[np.ndarray, " nodes"], Float[np.ndarray, "nodes states"]]:
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
