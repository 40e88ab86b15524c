"""The transcription: the collocation NLP of one estimation problem and its compiled functions.

Within element ``k`` of length ``h_k`` the state is the polynomial through its start ``X_k`` and
its ``n_c`` Radau IIA points ``X_{k,1} … X_{k,n_c}`` (the last one at the element end); the inputs
are linear between samples, as in the simulators. Decision variables: the states at every element
start (the final instant included) and collocation point, and the free parameters. Equality
constraints, all in kelvin:

* dynamics at each collocation point: ``Σ_l D_{jl} X_{k,l} − h_k (A X_{k,j} + B u(t_{k,j})) = 0``;
* continuity: ``X_{k+1} − X_{k,n_c} = 0``;
* initial state: ``X_0 − x0(θ) = 0``.

Objective (``objective=``):

* ``"samples"`` (default): the sum at the samples, ``Σ_k Σ_j (q_j / N) (ŷ_jk − y_jk)²`` — the cost
  of :func:`jaxbox.fit.fit_model`, so both routes minimise the same function and differ only by the
  collocation discretisation of the dynamics;
* ``"quadrature"``: the Gauss–Radau quadrature of ``(1/T) ∫ eᵀ Q e dt`` with the measurements
  linearly interpolated between samples (the reference study's form).

States (and their constraints) are divided by per-state scales ``sx`` (set from the initial
trajectory by the solver); parameters live in the bound transform of
:func:`jaxbox.fit.make_problem`. The compiled functions (values, per-element Jacobian blocks,
Hessian-vector products of the Lagrangian) are built once per problem structure and kept in the
``"collocation"`` room of :mod:`jaxbox._compiled`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .._compiled import cached, jit
from ..fit import Problem, problem_arrays
from ._grid import _Grid, _grid, _Sparsity, _sparsity
from ._radau import radau_iia


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


def _functions(problem: Problem, n_c: int, shapes: tuple) -> dict:
    """The compiled functions of ``problem``'s structure with ``n_c`` points and the argument
    ``shapes``, kept in the ``"collocation"`` room of :mod:`jaxbox._compiled`."""
    key = ("collocation", *problem.structure_key, problem.transform.kinds, n_c, shapes)
    return cached(key, lambda: _build_functions(problem, n_c))[0]


def _build_functions(problem: Problem, n_c: int) -> dict:
    """``evaluate`` (constraints, residuals and their Jacobian blocks), ``hvp`` (Hessian of the
    Lagrangian times directions) and ``matrices`` (A, B, C, D, x0 of internal parameters)."""
    model, tr = problem.model, problem.transform
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

    return {
        "evaluate": jit(evaluate),
        "hvp": jit(hvp),
        "matrices": jit(matrices),
    }


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
        fns=_functions(problem, n_c, tuple(np.shape(v) for v in args.values())),
        z0=z0,
        ue=ue,
        u=u,
        y=y,
        sqrt_w=sqrt_w,
    )


def _jargs(args: dict) -> dict:
    return {k: jnp.asarray(v) for k, v in args.items()}
