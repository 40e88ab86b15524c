"""Fit results: the best start's parameters, every start's outcome, and timings."""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np

from ._problem import Problem
from ._uses import ModelUses

__all__ = ["FitResult", "StartReport", "BOUND_TOLERANCE"]

#: a parameter whose position within its bounds (in its transform's scale) is closer than this
#: to 0 or 1 is reported ``at_bound``.
BOUND_TOLERANCE = 1e-3


@dataclasses.dataclass(frozen=True, eq=False)
class StartReport:
    """Outcome of every start of a multistart fit.

    Attributes:
        initial: starting values [S, p] (physical, free parameters).
        params: final values [S, p].
        cost: final cost per start [K²] (weighted mean squared error).
        steps: Levenberg–Marquardt iterations per start.
        status: ``converged``, ``max_steps``, ``nonfinite`` or ``failed (…)`` per start.
    """

    initial: np.ndarray
    params: np.ndarray
    cost: np.ndarray
    steps: np.ndarray
    status: tuple[str, ...]

    @property
    def n(self) -> int:
        return len(self.status)

    @property
    def converged(self) -> np.ndarray:
        return np.asarray([s == "converged" for s in self.status])

    @property
    def usable(self) -> np.ndarray:
        """Starts whose result may be used: converged, or stopped at the step cap with a finite
        cost. Non-finite and failed starts are never usable."""
        return np.asarray([s in ("converged", "max_steps") for s in self.status]) & np.isfinite(
            self.cost
        )

    def best_index(self) -> int | None:
        """Lowest-cost converged start; else lowest-cost usable start; else None."""
        for mask in (self.converged & np.isfinite(self.cost), self.usable):
            if mask.any():
                idx = np.flatnonzero(mask)
                return int(idx[np.argmin(self.cost[idx])])
        return None

    def status_summary(self) -> str:
        return ", ".join(f"{v} {k}" for k, v in Counter(self.status).items())

    def n_at_best(self, rtol: float = 1e-4, atol: float = 1e-10) -> int:
        """How many usable starts reached the best cost within ``max(rtol·best, atol)`` [K²]."""
        best = self.best_index()
        if best is None:
            return 0
        c = self.cost[best]
        return int(np.sum(self.usable & (self.cost <= c + max(rtol * c, atol))))


@dataclasses.dataclass(frozen=True, eq=False)
class FitResult(ModelUses):
    """The estimate of a fit and everything needed to report, validate or refit it.

    Attributes:
        problem: the estimation problem (model, free/fixed split, bounds, guess, weights).
        data: the identification dataset.
        params: every model parameter at the optimum (SI), free and fixed.
        cost: best cost [K²], the weighted mean squared output error.
        converged: whether the best start converged (else it hit the step cap).
        best: index of the best start.
        starts: every start's outcome.
        timing: ``compile_s`` and ``fit_s`` [s].
        settings: solver settings (max_steps, rtol, atol, seed).
    """

    problem: Problem
    data: object
    params: dict
    cost: float
    converged: bool
    best: int
    starts: StartReport
    timing: dict
    settings: dict

    @classmethod
    def from_best(cls, *, problem, data, report, best, timing, settings) -> FitResult:
        params = dict(problem.fixed)
        params.update({n: float(v) for n, v in zip(problem.free, report.params[best], strict=True)})
        params = {n: float(params[n]) for n in problem.model.param_names}
        return cls(
            problem=problem,
            data=data,
            params=params,
            cost=float(report.cost[best]),
            converged=report.status[best] == "converged",
            best=best,
            starts=report,
            timing=dict(timing),
            settings=dict(settings),
        )

    @property
    def model(self):
        return self.problem.model

    @property
    def free(self) -> tuple[str, ...]:
        return self.problem.free

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        return self.problem.bounds

    @property
    def n_samples(self) -> int:
        return len(self.data)

    def bound_position(self) -> dict[str, float]:
        """Position of each free parameter in its bounds, 0 (lower) … 1 (upper), transform scale."""
        pos = self.problem.transform.relative_position(
            np.asarray([self.params[n] for n in self.free])
        )
        return {n: float(x) for n, x in zip(self.free, pos, strict=True)}

    def at_bound(self, tol: float = BOUND_TOLERANCE) -> dict[str, bool]:
        """Whether each free parameter ended within ``tol`` of a bound (fixed ones: False)."""
        pos = self.bound_position()
        out = {n: False for n in self.model.param_names}
        for n, x in pos.items():
            out[n] = bool(np.isfinite(x) and (x < tol or x > 1 - tol))
        return out

    def params_table(self) -> dict[str, dict]:
        """Per parameter: value, unit, lower, upper, free, at_bound."""
        at = self.at_bound()
        bounds = self.bounds
        table = {}
        for spec in self.model.parameters:
            n = spec.name
            lo, hi = bounds.get(n, (spec.lower, spec.upper))
            table[n] = {
                "value": self.params[n],
                "unit": spec.unit,
                "lower": lo,
                "upper": hi,
                "free": n in self.free,
                "at_bound": at[n],
            }
        return table

    def summary(self) -> str:
        """A readable table of the estimate."""
        lines = [
            f"model {self.model.name}: {len(self.free)} free parameters, {self.n_samples} samples, "
            f"RMS error {np.sqrt(self.cost):.4f} K "
            f"({'converged' if self.converged else 'NOT converged'})",
            f"starts: {self.starts.n} ({self.starts.status_summary()}), "
            f"{self.starts.n_at_best()} reached the best cost",
            f"{'parameter':<10} {'value':>12} {'unit':<4} {'lower':>10} {'upper':>10}  note",
        ]
        for n, row in self.params_table().items():
            note = "fixed" if not row["free"] else ("AT BOUND" if row["at_bound"] else "")
            lines.append(
                f"{n:<10} {row['value']:>12.5g} {row['unit']:<4} {row['lower']:>10.3g} "
                f"{row['upper']:>10.3g}  {note}"
            )
        for output, kelvin in self.model.sensor_offsets(self.params).items():
            lines.append(f"sensor offset of {output}: {kelvin:+.3f} K (the constant heat input)")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"FitResult(model={self.model.name!r}, cost={self.cost:.6g}, "
            f"converged={self.converged}, starts={self.starts.n})"
        )
