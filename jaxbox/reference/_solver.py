"""The solver: sequential quadratic programming on the full collocation NLP.

States and parameters are solved for simultaneously, with exact derivatives from JAX: sparse
Jacobians of the constraints and residuals (assembled from per-element blocks); the Hessian of
the Lagrangian is the Gauss–Newton one (``JᵀJ``, positive semi-definite, robust far from the
solution) until the iterates are close to it (scaled constraint violation and relative Newton
decrement below 1e-6), then the exact one from JAX for quadratic final convergence
(``hessian="auto"``; ``"exact"`` and ``"gauss-newton"`` use one throughout). Each step solves
the KKT system of the quadratic subproblem by the null-space method: the constraint Jacobian with
respect to the states is square and banded, is factorised once per iteration (sparse LU), and
the step is a particular solution of the linearised constraints plus a null-space component in
the free parameters, from a Levenberg–Marquardt-damped reduced system. Steps are accepted on the
ℓ1 merit function ``f + ν‖c‖₁`` with a second-order correction against the Maratos effect.

Scaling as in the reference study: states (and their constraints) are divided by the infinity
norm of each state's initial trajectory (at least 1 K). The initial state trajectory comes from
an exact simulation with the initial parameters, linearly interpolated to the collocation
points.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from ..simulate._exact import discretize_foh_numpy
from ._grid import _assemble, _Sparsity
from ._radau import radau_iia
from ._transcription import _jargs, _Transcription

#: "auto" switches from Gauss-Newton to the exact Hessian below this scaled constraint violation
#: and relative Newton decrement.
_SWITCH = 1e-6
#: a step is accepted when the merit function decreases by at least this share of the predicted
#: decrease.
_ETA = 1e-4


class _Failure(Exception):
    def __init__(self, status: str, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


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
    out = np.empty((len(h) + 1, B.shape[0]))
    out[0] = x = x0
    cache = {}
    with np.errstate(all="ignore"):
        for k, hk in enumerate(h):
            if hk not in cache:
                cache[hk] = discretize_foh_numpy(A, B, hk)
            Phi, G0, G1 = cache[hk]
            x = Phi @ x + G0 @ ue[k] + G1 @ (ue[k + 1] - ue[k])
            out[k + 1] = x
    return out


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
    damping = _Damping()
    dscale = np.zeros(p)
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
    _check_finite(c, r, "the constraints or residuals are not finite at the start")
    for it in range(max_iterations + 1):
        last["it"] = it
        f = 0.5 * float(r @ r)
        viol = float(np.max(np.abs(c)))
        red = _null_space(sp, c, r, gx, jx, gz, jz, it)
        decrement = _decrement(red.Hr, red.gr)
        if hessian == "exact" or (
            hessian == "auto" and (switched or (viol <= _SWITCH and decrement <= _SWITCH * f))
        ):
            ex = _exact(fns["hvp"], w, red, jargs, nx, p)
            dec_e = _decrement(ex.Hr, ex.gr)
            # not positive definite under "auto": a Gauss-Newton step this time
            if hessian == "exact" or np.isfinite(dec_e):
                red, decrement, switched = ex, dec_e, True
        red = dataclasses.replace(red, Hr=0.5 * (red.Hr + red.Hr.T))
        entry = {
            "iteration": it,
            "cost": 2 * f,
            "constraint_violation": viol,
            "reduced_gradient": float(np.max(np.abs(red.gr))),
            "decrement": decrement,
            "hessian": "gauss-newton" if red.HY is None else "exact",
        }
        history.append(entry)
        stats.update(
            reduced_gradient=entry["reduced_gradient"],
            newton_decrement=decrement,
            multipliers_max=float(np.max(np.abs(red.lam))),
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
        dscale = np.maximum(dscale, np.abs(np.diag(red.Hr)))
        dfloor = np.maximum(dscale, 1e-12 * max(float(np.max(dscale)), 1e-300))
        c1 = float(np.sum(np.abs(c)))
        damping.nu = max(damping.nu, 1.01 * float(np.max(np.abs(red.lam))))
        step = _step(values, w, red, dfloor, c1, f, damping, stats, nx)
        if step is None:
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
        w, ratio, dz = step
        entry.update(
            mu=damping.mu, step=float(np.max(np.abs(dz))), ratio=float(ratio), nu=damping.nu
        )
        last["w"] = w
        c, r, gx, jx, gz, jz = evaluate(w)
        _check_finite(c, r, f"non-finite constraints or residuals at iteration {it}")
    stats["penalty"] = damping.nu
    return (
        w,
        max_iterations,
        "max_iterations",
        (
            f"stopped after {max_iterations} iterations (constraint violation {viol:.1e}, Newton "
            f"decrement {decrement:.1e}); raise max_iterations or check the problem"
        ),
    )


def _check_finite(c, r, message: str) -> None:
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
        raise _Failure("nonfinite", message)


@dataclasses.dataclass(frozen=True)
class _Reduced:
    """One iteration's KKT system reduced to the free parameters (the null-space method).

    A step ``dX = YX + ZX dz`` of the scaled states satisfies the linearised constraints for any
    parameter step ``dz``; the damped reduced system ``(Hr + μ D) dz = −gr`` chooses ``dz``.
    ``HY``/``HZ`` are set when ``Hr`` is the exact reduced Hessian of the Lagrangian, ``None``
    for the Gauss–Newton one.
    """

    lu: scipy.sparse.linalg.SuperLU  # the state Jacobian of the constraints, factorised
    YX: np.ndarray  # particular state step [nx]
    ZX: np.ndarray  # state change per parameter change [nx, p]
    gX: np.ndarray  # gradient of ½‖r‖² in the states [nx]
    gZ: np.ndarray  # gradient of ½‖r‖² in the parameters [p]
    lam: np.ndarray  # constraint multipliers [nx]
    JY: np.ndarray  # residual change along YX [R]
    JZ: np.ndarray  # residual change per parameter step along the null space [R, p]
    Hr: np.ndarray  # reduced Hessian [p, p]
    gr: np.ndarray  # reduced gradient [p]
    HY: np.ndarray | None = None  # Hessian of the Lagrangian times (YX, 0) [nx + p]
    HZ: np.ndarray | None = None  # Hessian of the Lagrangian times the null space [nx + p, p]


def _null_space(sp: _Sparsity, c, r, gx, jx, gz, jz, it: int) -> _Reduced:
    """Factorise the state Jacobian of the constraints and reduce the KKT system (Gauss–Newton
    reduced Hessian and gradient: always computed, cheap, and the fallback)."""
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
    return _Reduced(lu, YX, ZX, gX, gZ, lam, JY, JZ, Hr=JZ.T @ JZ, gr=JZ.T @ (r + JY))


def _exact(hvp, w, red: _Reduced, jargs, nx: int, p: int) -> _Reduced:
    """The reduced system with the exact Hessian of the Lagrangian (Hessian-vector products
    along the particular step and the null space)."""
    dirs = np.zeros((p + 1, nx + p))
    dirs[0, :nx] = red.YX
    dirs[1:, :nx] = red.ZX.T
    dirs[1:, nx:] = np.eye(p)
    HV = np.asarray(hvp(jnp.asarray(w), jnp.asarray(red.lam), jnp.asarray(dirs), jargs))
    HY, HZ = HV[0], HV[1:].T
    Hr = red.ZX.T @ HZ[:nx] + HZ[nx:]
    gr = red.ZX.T @ (red.gX + HY[:nx]) + (red.gZ + HY[nx:])
    return dataclasses.replace(red, Hr=Hr, gr=gr, HY=HY, HZ=HZ)


@dataclasses.dataclass
class _Damping:
    """Levenberg–Marquardt damping ``mu`` of the reduced system (``grow``: its growth factor
    after a rejection) and the penalty ``nu`` of the ℓ1 merit function."""

    mu: float = 1e-3
    grow: float = 2.0
    nu: float = 0.0

    def accept(self, ratio: float) -> None:
        if ratio > 0.25:
            self.mu = max(self.mu / 10.0, 1e-12)
        elif ratio < 0.1:
            self.mu *= 2.0
        self.grow = 2.0

    def reject(self) -> None:
        self.mu, self.grow = self.mu * self.grow, self.grow * 2


def _step(values, w, red: _Reduced, dfloor, c1: float, f: float, damping: _Damping, stats, nx):
    """The first damped step accepted on the merit function, as ``(w, ratio, dz)``; ``None``
    when the damping grows past 1e20 (or the prediction is not finite) without one."""
    while True:
        try:
            cho = scipy.linalg.cho_factor(red.Hr + damping.mu * np.diag(dfloor))
        except (np.linalg.LinAlgError, ValueError):
            damping.reject()
            if damping.mu > 1e20:
                raise _Failure(
                    "failed", "the reduced Hessian stays indefinite under any damping"
                ) from None
            continue
        dz = -scipy.linalg.cho_solve(cho, red.gr)
        dX = red.YX + red.ZX @ dz
        d = np.concatenate([dX, dz])
        gd = float(red.gX @ dX + red.gZ @ dz)
        pred_f = -(gd + 0.5 * _curvature(red, d, dz))
        if c1 > 0 and pred_f < 0:
            damping.nu = max(damping.nu, -2.0 * pred_f / c1)
        pred = pred_f + damping.nu * c1
        phi = f + damping.nu * c1
        trial, ratio = _trial(values, w + d, red.lu, phi, pred, damping.nu, stats, nx)
        if ratio >= _ETA:
            damping.accept(ratio)
            return trial, ratio, dz
        stats["n_rejected"] += 1
        damping.reject()
        if damping.mu > 1e20 or not np.isfinite(pred):
            return None


def _curvature(red: _Reduced, d, dz) -> float:
    """``dᵀ H d`` under the Hessian in use: exact, or Gauss–Newton ``‖J d‖²``."""
    if red.HY is not None:
        return float(d @ (red.HY + red.HZ @ dz))
    Jd = red.JY + red.JZ @ dz
    return float(Jd @ Jd)


def _trial(values, trial, lu, phi: float, pred: float, nu: float, stats, nx: int):
    """The trial point and its ratio of actual to predicted merit decrease; when too small, a
    second-order correction (restoring the linearised constraints at the trial) is tried."""
    c_t, r_t = values(trial)
    ratio = _ratio(phi, _merit(c_t, r_t, nu), pred)
    if not ratio >= _ETA and np.all(np.isfinite(c_t)):
        soc = trial.copy()
        soc[:nx] -= lu.solve(c_t)
        c_s, r_s = values(soc)
        ratio_s = _ratio(phi, _merit(c_s, r_s, nu), pred)
        if ratio_s >= _ETA:
            stats["n_second_order_corrections"] += 1
            return soc, ratio_s
    return trial, ratio


def _ratio(phi: float, phi_t: float, pred: float) -> float:
    return (phi - phi_t) / pred if pred > 0 else -np.inf


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
