"""The result of a collocation fit: what it found, how the solve went, and its summary."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

from ..fit import Problem
from ..models import RCModel
from ..simulate import Simulation, simulate_model
from ._transcription import _jargs, _Transcription


@dataclasses.dataclass(frozen=True)
class CollocationResult:
    """The outcome of :func:`collocation_fit`.

    Attributes:
        problem: the estimation problem (as built by :func:`jaxbox.fit.make_problem`).
        data: the identification dataset.
        params: every model parameter at the solution (SI), free and fixed.
        cost: the NLP objective at the solution [K²]: the weighted mean squared output error at
            the samples (``objective="samples"``, the cost of :func:`jaxbox.fit.fit_model`) or its
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
    t: Float[np.ndarray, " samples"]
    x: Float[np.ndarray, "samples states"]
    y: Float[np.ndarray, "samples outputs"]
    t_nodes: Float[np.ndarray, " nodes"]
    x_nodes: Float[np.ndarray, "nodes states"]
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


def _result(
    tx: _Transcription, data, w, status, message, iterations, stats, history, settings, timing
) -> CollocationResult:
    """The result at the scaled variables ``w`` (the solution, or the last iterate)."""
    problem, grid, args, fns = tx.problem, tx.grid, tx.args, tx.fns
    y, sqrt_w, u = tx.y, tx.sqrt_w, tx.u
    n = grid.n_states
    nx = tx.sparsity.n_x
    V = w[:nx].reshape(grid.n_nodes, n)
    z = w[nx:]
    x_nodes = V * args["sx"]
    p_free = problem.transform.to_physical(np.asarray(z, dtype=float))
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
