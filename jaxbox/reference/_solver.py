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

import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from ._grid import _assemble
from ._radau import radau_iia
from ._transcription import _jargs, _Transcription

#: "auto" switches from Gauss-Newton to the exact Hessian below this scaled constraint violation
#: and relative Newton decrement.
_SWITCH = 1e-6


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
