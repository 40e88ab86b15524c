"""The validity verdict of a fit: is this model acceptable, and if not, why not.

Following the reference study, a single model is *valid* when its optimum was found, its
parameters are physically reasonable and not on their bounds, and their confidence intervals are
reasonable. Every failed check adds a flag with a readable reason naming the parameters:

* ``failed`` / ``not_converged`` — the best start did not return a finite, converged optimum;
* ``at_bound`` — a free parameter ended at or near one of its bounds (position in the bounds, in
  the transform's own scale, within ``bound_tol`` of 0 or 1): the optimum is cut by the bounds;
  an initial temperature there gets its own advice (narrow the bounds from physics); a parameter
  only *near* a bound (not at it) whose confidence interval excludes the bound is a warning;
* ``non_physical`` — a value outside broad physical limits (``limits``: non-positive or absurd
  resistances and capacities, negative apertures…);
* ``time_constant`` — a time constant ``τ = −1/Re λ`` of the state matrix outside
  ``tau_range`` (seconds … years), or an unstable eigenvalue;
* ``not_identifiable`` / ``poorly_identifiable`` — a parameter combination the data do not
  determine (:func:`~jaxbox.validate.uncertainty`);
* ``wide_interval`` — a confidence interval wider than ``± max_rel_ci`` of the value.

Non-fatal observations (a time constant shorter than the sampling step, a global optimum
reached by a single start, non-white residuals) are returned as ``warnings``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

__all__ = ["Verdict", "Flag", "check_validity", "time_constants", "PHYSICAL_LIMITS"]

_YEAR = 365.25 * 86400.0

#: Broad physical limits per parameter-name prefix (SI): values outside are absurd for a building.
PHYSICAL_LIMITS: dict[str, tuple[float, float]] = {
    "R_": (0.0, 100.0),  # K/W, exclusive at 0
    "C_": (1e3, 1e11),  # J/K
    "gA": (0.0, 500.0),  # m²
    "fra_": (0.0, 10.0),  # -
    "T_": (-50.0, 80.0),  # °C
}


@dataclasses.dataclass(frozen=True)
class Flag:
    """One finding of the verdict.

    Attributes:
        kind: ``failed``, ``not_converged``, ``at_bound``, ``non_physical``, ``time_constant``,
            ``not_identifiable``, ``poorly_identifiable``, ``wide_interval``, ``no_intervals``
            (invalidating) or
            ``fast_dynamics``, ``multistart``, ``residuals`` (warnings).
        parameters: the parameters concerned (may be empty).
        message: the reason in words.
        severe: True when it makes the model invalid.
    """

    kind: str
    parameters: tuple[str, ...]
    message: str
    severe: bool = True

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "parameters": list(self.parameters),
            "message": self.message,
            "severe": self.severe,
        }


@dataclasses.dataclass(frozen=True)
class Verdict:
    """Whether a fit is a valid model, with the reasons when it is not.

    Attributes:
        valid: no invalidating flag.
        reasons: the invalidating findings in words.
        warnings: non-fatal observations in words.
        flags: every finding, structured.
        time_constants: time constants of the state matrix [s], ascending (constant nodes left
            out).
    """

    valid: bool
    reasons: tuple[str, ...]
    warnings: tuple[str, ...]
    flags: tuple[Flag, ...]
    time_constants: np.ndarray

    def __bool__(self) -> bool:
        return self.valid

    def flagged(self, kind: str | None = None) -> tuple[str, ...]:
        """Parameters named by the invalidating flags (of one ``kind``, or all)."""
        out: dict[str, None] = {}
        for f in self.flags:
            if f.severe and (kind is None or f.kind == kind):
                for n in f.parameters:
                    out.setdefault(n, None)
        return tuple(out)

    def to_dict(self) -> dict:
        return {
            "valid": self.valid,
            "reasons": list(self.reasons),
            "warnings": list(self.warnings),
            "flags": [f.to_dict() for f in self.flags],
            "time_constants_h": [float(t) / 3600.0 for t in self.time_constants],
        }

    def summary(self) -> str:
        head = "VALID" if self.valid else "NOT VALID"
        lines = [head]
        lines += [f"  - {r}" for r in self.reasons]
        lines += [f"  (warning) {w}" for w in self.warnings]
        return "\n".join(lines)


def _fmt_time(seconds: float) -> str:
    if not np.isfinite(seconds):
        return "∞"
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.3g} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.3g} h"
    if seconds < _YEAR:
        return f"{seconds / 86400:.3g} d"
    return f"{seconds / _YEAR:.3g} years"


def _fmt(value: float, unit: str) -> str:
    return f"{value:.4g} {unit}".rstrip()


_STATE_MATRIX: dict = {}


def _state_matrix(model, params) -> np.ndarray:
    """The state matrix A [1/s] at ``params`` (jitted once per model)."""
    fn = _STATE_MATRIX.get(model)
    if fn is None:
        import jax

        fn = _STATE_MATRIX[model] = jax.jit(lambda theta: model.state_space(theta)[0])
    theta = {k: np.asarray(v, dtype=float) for k, v in params.items()}
    return np.asarray(fn(theta), dtype=float)


def time_constants(model, params: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Time constants ``τ = −1/Re λ`` [s] of the state matrix A at ``params``, ascending.

    Nodes held at a constant temperature are left out (their eigenvalue 0 is by design).

    Returns:
        (τ [s], eigenvalues λ [1/s]); ``τ = inf`` or negative for a non-decaying or unstable mode.
    """
    A = _state_matrix(model, params)
    dyn = [i for i, n in enumerate(model.network.nodes) if not getattr(n, "constant", False)]
    A = A[np.ix_(dyn, dyn)]
    lam = np.linalg.eigvals(A)
    with np.errstate(divide="ignore"):
        tau = np.where(lam.real != 0, -1.0 / lam.real, np.inf)
    order = np.argsort(tau)
    return tau[order], lam[order]


def _limit(name: str, limits: Mapping[str, tuple[float, float]]):
    if name in limits:
        return limits[name]
    best = None
    for prefix, rng in limits.items():
        if name.startswith(prefix) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, rng)
    return None if best is None else best[1]


def check_validity(
    result,
    uncertainty=None,
    *,
    max_rel_ci: float = 0.5,
    bound_tol: float = 0.01,
    tau_range: tuple[float, float] = (1.0, 10 * _YEAR),
    limits: Mapping[str, tuple[float, float]] | None = None,
    residuals=None,
    check_intervals: bool = True,
) -> Verdict:
    """The validity verdict of a fit, with reasons.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        uncertainty: its :class:`~jaxbox.validate.Uncertainty` (computed when ``None`` and
            ``check_intervals``).
        max_rel_ci: widest acceptable confidence interval, as a fraction of the value
            (half-width; 0.5 accepts ``θ̂ ± 50 %``).
        bound_tol: a free parameter within this fraction of its range (in the transform's
            scale: logarithmic for R and C) from a bound is *near* the bound.
        tau_range: acceptable time constants [s] (default 1 s … 10 years).
        limits: physical limits per parameter name or name prefix (SI), merged over
            :data:`PHYSICAL_LIMITS`; the lower limit of ``R_`` is exclusive.
        residuals: an optional :class:`~jaxbox.validate.ResidualAnalysis`; non-white residuals
            add a warning (never invalidate).
        check_intervals: skip the interval and identifiability checks when False.

    Returns:
        :class:`Verdict` (truthy when valid).
    """
    model = result.model
    specs = {s.name: s for s in model.parameters}
    lims = dict(PHYSICAL_LIMITS)
    lims.update(limits or {})
    flags: list[Flag] = []

    # -- optimum -------------------------------------------------------------------------------
    status = result.starts.status[result.best]
    values = np.asarray([result.params[n] for n in model.param_names], dtype=float)
    if status == "nonfinite" or not math.isfinite(result.cost) or not np.all(np.isfinite(values)):
        flags.append(
            Flag("failed", (), "the optimum is not finite: the fit failed; check data and bounds")
        )
    elif status.startswith("failed"):
        flags.append(Flag("failed", (), f"the best start failed ({status}); the fit is not usable"))
    elif not result.converged:
        steps = int(result.starts.steps[result.best])
        flags.append(
            Flag(
                "not_converged",
                (),
                f"the best start stopped at the step cap ({steps} iterations) without "
                "converging: raise max_steps, add starts or check the bounds",
            )
        )

    # -- bounds ----------------------------------------------------------------------------------
    tau, _ = time_constants(model, result.params) if np.all(np.isfinite(values)) else ([], [])
    tau = np.asarray(tau, dtype=float)
    A = _state_matrix(model, result.params) if np.all(np.isfinite(values)) else None
    nodes = list(model.network.nodes)
    with np.errstate(invalid="ignore", divide="ignore"):  # a non-physical value: nan position
        pos = result.bound_position()
    bounds = result.bounds
    near: dict[str, tuple[int, float]] = {}  # "near" (not "at") a bound: flag index, bound
    for n in result.free:
        x = pos.get(n, float("nan"))
        if not np.isfinite(x):
            continue
        if x < bound_tol or x > 1 - bound_tol:
            side = "lower" if x < 0.5 else "upper"
            lo, hi = bounds[n]
            b = lo if side == "lower" else hi
            unit = specs[n].unit
            on = "at" if min(x, 1 - x) < 1e-3 else "near"
            if specs[n].is_initial_state:
                node = next((i for i, m in enumerate(nodes) if m.T0 == n), None)
                extra = ""
                if node is not None and A is not None and A[node, node] < 0:
                    extra = f" (its own time constant is {_fmt_time(-1.0 / A[node, node])})"
                msg = (
                    f"initial temperature {n} = {_fmt(result.params[n], unit)} is pinned {on} its "
                    f"{side} bound {_fmt(b, unit)}{extra}: a slow state started at a limit "
                    "biases the energy balance; narrow its bounds from physical insight (e.g. "
                    "between the zone and ambient or boundary temperatures) or fix it"
                )
            else:
                msg = (
                    f"{n} = {_fmt(result.params[n], unit)} is {on} its {side} bound "
                    f"{_fmt(b, unit)}: the bounds cut the optimum; the model structure does not "
                    "suit the data, or the bound is too tight"
                )
                if on == "near":
                    near[n] = (len(flags), b)
            flags.append(Flag("at_bound", (n,), msg))

    # -- physical values ---------------------------------------------------------------------
    for n in model.param_names:
        v = result.params[n]
        rng = _limit(n, lims)
        if rng is None or not np.isfinite(v):
            continue
        lo, hi = rng
        unit = specs[n].unit
        bad_low = v <= lo if n.startswith("R_") and lo == 0 else v < lo
        if bad_low or v > hi:
            flags.append(
                Flag(
                    "non_physical",
                    (n,),
                    f"{n} = {_fmt(v, unit)} is not physical for a building (expected "
                    f"{'>' if n.startswith('R_') and lo == 0 else '≥'} {lo:g} and ≤ {hi:g} "
                    f"{unit})",
                )
            )

    # -- time constants ----------------------------------------------------------------------
    tmin, tmax = tau_range
    for t in tau:
        if not np.isfinite(t) or t <= 0:
            flags.append(
                Flag(
                    "time_constant",
                    (),
                    "the state matrix has a mode that does not decay (unstable or "
                    "integrating): the parameters are not physical",
                )
            )
        elif t < tmin or t > tmax:
            flags.append(
                Flag(
                    "time_constant",
                    (),
                    f"time constant {_fmt_time(t)} lies outside {_fmt_time(tmin)} … "
                    f"{_fmt_time(tmax)}: not physical for a building",
                )
            )
    step = float(result.data.step)
    fast = [t for t in tau if np.isfinite(t) and 0 < t < step and tmin <= t]
    if fast:
        flags.append(
            Flag(
                "fast_dynamics",
                (),
                f"time constant {_fmt_time(min(fast))} is shorter than the sampling step "
                f"{_fmt_time(step)}: the data do not resolve it",
                severe=False,
            )
        )

    # -- intervals and identifiability ---------------------------------------------------------
    if check_intervals and uncertainty is None and not any(f.kind == "failed" for f in flags):
        from ._uncertainty import uncertainty as _uncertainty

        try:
            uncertainty = _uncertainty(result)
        except ValueError as err:  # no degrees of freedom left
            flags.append(Flag("no_intervals", (), f"no confidence intervals: {err}"))
    if check_intervals and uncertainty is not None:
        for c in uncertainty.combinations:
            kind = "not_identifiable" if c.singular else "poorly_identifiable"
            flags.append(Flag(kind, c.parameters, c.text))
        pct = round(100 * uncertainty.level)
        # near (not at) a bound but significantly away from it: a warning, not a reason
        for n, (k, b) in near.items():
            if n not in uncertainty.names:
                continue
            lo, hi = uncertainty.ci95[uncertainty.names.index(n)]
            if np.isfinite(lo) and np.isfinite(hi) and not lo <= b <= hi:
                f = flags[k]
                flags[k] = dataclasses.replace(
                    f,
                    message=f"{f.message} (its {pct} % interval [{lo:.4g}, {hi:.4g}] excludes "
                    "the bound, so the estimate stands)",
                    severe=False,
                )
        for i, n in enumerate(uncertainty.names):
            r = uncertainty.rel_ci[i]
            if np.isfinite(uncertainty.std[i]) and r > max_rel_ci:
                flags.append(
                    Flag(
                        "wide_interval",
                        (n,),
                        f"{n}: the {pct} % confidence interval is ±{100 * r:.3g} % of its value "
                        f"(more than ±{100 * max_rel_ci:.3g} %): the data hardly determine it",
                    )
                )

    # -- warnings ------------------------------------------------------------------------------
    st = result.starts
    if st.n > 1 and st.n_at_best() == 1:
        flags.append(
            Flag(
                "multistart",
                (),
                f"only 1 of {st.n} starts reached the best cost: the sample may be too small to "
                "trust the global optimum; add starts",
                severe=False,
            )
        )
    if residuals is not None:
        for o in residuals:
            if not o.white:
                flags.append(
                    Flag(
                        "residuals",
                        (),
                        f"residuals of {o.name} are not white (Ljung–Box p = "
                        f"{o.ljung_box.p_value:.2g}, cumulated periodogram p = "
                        f"{o.periodogram.p_value:.2g}): dynamics or inputs are missing, and "
                        "the confidence intervals, which assume white residuals, are too narrow",
                        severe=False,
                    )
                )

    reasons = tuple(f.message for f in flags if f.severe)
    warnings = tuple(f.message for f in flags if not f.severe)
    return Verdict(
        valid=not reasons,
        reasons=reasons,
        warnings=warnings,
        flags=tuple(flags),
        time_constants=np.asarray(tau, dtype=float),
    )
