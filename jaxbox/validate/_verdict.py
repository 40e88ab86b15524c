"""The validity verdict of a fit: is this model acceptable, and if not, why not.

Following the reference study, a single model is *valid* when its optimum was found, its
parameters are physically reasonable and not on their bounds, their confidence intervals are
reasonable, and it predicts: the data it was judged on are plausible and the validation error is
not far above the identification error. Each check is one small function of a
context (``_Judged``) returning a list of :class:`Flag`; :func:`check_validity` runs them in
turn (:data:`_CHECKS`) and collects the reasons:

* ``failed`` / ``not_converged`` — the best start did not return a finite, converged optimum;
* ``at_bound`` — a free parameter ended at or near one of its bounds (position in the bounds, in
  the transform's own scale, within ``bound_tol`` of 0 or 1): the optimum is cut by the bounds;
  an initial temperature there gets its own advice (narrow the bounds from physics); a parameter
  only *near* a bound (not at it) whose confidence interval excludes the bound is a warning;
* ``non_physical`` — a value outside broad physical limits (``limits``: non-positive or absurd
  resistances and capacities, negative apertures…); the upper limits of a node's capacity and
  of an aperture grow with the fitted building beyond :data:`~jaxbox.models.REFERENCE_HLC`
  (:func:`physical_limits`), as the naming convention's bounds do for a large building;
* ``time_constant`` — a time constant ``τ = −1/Re λ`` of the state matrix outside
  ``tau_range`` (seconds … years), an unstable eigenvalue, or a slowest time constant outside
  ``slowest_tau_range`` (10 min … 1 year: no building settles faster or slower); a too-fast
  mode that is the own time constant of a node whose capacity sits on its floor names that
  capacity (the node is merged, massless), and is a note once the capacity is fixed there;
* ``heat_loss`` — the heat-loss coefficient UA (:func:`heat_loss_coefficients`: steady-state
  heat flow per kelvin of zone temperature, from A, B, C) outside ``ua_range`` (1 W/K … 1e5 W/K).
  A heating power in kW instead of W gives UA and capacities 1000× too small, and this reason;
* ``capacity`` — the total heat capacity of the model's nodes outside ``capacity_range``
  (1e5 … 1e12 J/K);
* ``prediction`` — the validation RMSE of an output above ``max_rmse`` (5 K), above
  ``max_rmse_ratio`` (10) times its identification RMSE (when above ``rmse_floor``, 0.5 K),
  or not finite (needs ``validation=``);
* ``implausible_data`` — the identification or validation data of the model's columns fail
  :func:`jaxbox.data.check_plausibility` (spikes, kelvin, kW, stuck sensors, ranges…);
* ``not_identifiable`` / ``poorly_identifiable`` — a parameter combination the data do not
  determine (:func:`~jaxbox.validate.uncertainty`);
* ``wide_interval`` — a confidence interval wider than ``± max_rel_ci`` of the value.

Non-fatal observations (a time constant shorter than the sampling step, a global optimum
reached by a single start, non-white residuals, data that may be wrong) are returned as
``warnings``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable, Mapping

import numpy as np

from ..data import DataError, Dataset, Finding, find_implausible, signal_unit
from ..data._args import check_mapping
from ..data._plausible import _ALLOWED, STUCK_HOURS
from ..fit._transforms import make_transform
from ._args import (
    check_fit,
    check_flag,
    check_fraction,
    check_instance,
    check_positive,
    check_range,
)
from ._own import check_own
from ._residuals import ResidualAnalysis

__all__ = [
    "CAPACITY_RANGE",
    "MAX_RMSE",
    "MAX_RMSE_RATIO",
    "PHYSICAL_LIMITS",
    "physical_limits",
    "RMSE_FLOOR",
    "SLOWEST_TAU_RANGE",
    "UA_RANGE",
    "Flag",
    "Verdict",
    "check_validity",
    "heat_loss_coefficients",
    "sensor_offsets",
    "time_constants",
]

_YEAR = 365.25 * 86400.0

#: Largest plausible RMSE [K] of a temperature output, on identification or validation data.
MAX_RMSE = 5.0
#: Largest plausible ratio of the validation RMSE to the identification RMSE ...
MAX_RMSE_RATIO = 10.0
#: ... applied above this validation RMSE [K].
RMSE_FLOOR = 0.5
#: Widest acceptable 95 % confidence interval of a parameter, as a fraction of its value
#: (half-width): 1.0 asks that the interval exclude zero, i.e. that the parameter be
#: significantly different from zero at the 5 % level (the t-test of CTSM-R and pySIP). A
#: capacity or resistance whose interval reaches zero is not determined by the data; a
#: tighter rule (±50 %) rejects real but fast components at coarse sampling (a heater's
#: capacity in hourly data), and the validation error guards against over-fitting.
MAX_REL_CI = 1.0
#: An unmeasured state whose initial temperature the outputs forget (less than FORGOTTEN K per K
#: left) within this share of the identification span: that temperature pinned at a bound is
#: a warning, not a reason (a heater in weeks of data).
FAST_STATE_SHARE = 0.02
FORGOTTEN = 0.05
#: Plausible heat-loss coefficient UA [W/K] of a building (a room … a large block).
UA_RANGE = (1.0, 1e5)
#: Plausible total heat capacity [J/K] of the nodes of a building (a small room … a large block).
CAPACITY_RANGE = (1e5, 1e12)
#: Plausible slowest time constant [s] of a building: 10 minutes … 1 year.
SLOWEST_TAU_RANGE = (600.0, _YEAR)

#: Broad physical limits per parameter-name prefix (SI): values outside are absurd for a building
#: of up to :data:`~jaxbox.models.REFERENCE_HLC`; a larger one's capacities and apertures may be
#: as many times larger (:func:`physical_limits`).
PHYSICAL_LIMITS: dict[str, tuple[float, float]] = {
    "R_": (0.0, 100.0),  # K/W, exclusive at 0
    "C_": (1e3, 1e11),  # J/K
    "gA": (0.0, 500.0),  # m²
    "fra_": (0.0, 10.0),  # -
    "T_": (-50.0, 80.0),  # °C
}
#: The prefixes of :data:`PHYSICAL_LIMITS` whose upper limit grows with the building's size.
_SIZED = ("C_", "gA")


def physical_limits(model, params: Mapping[str, float]) -> tuple[dict, float]:
    """:data:`PHYSICAL_LIMITS` for the building a fit describes, and its size ``s``.

    ``s = max(1, UA / REFERENCE_HLC)``, ``UA`` [W/K] the fit's largest heat-loss coefficient
    (:func:`heat_loss_coefficients`; 1 without one, or where it is not finite and positive):
    the upper limits of capacities ``C_*`` and apertures ``gA*`` are ``s`` times their
    defaults, as :func:`~jaxbox.models.scaled_parameter` scales their bounds, so that a large
    building's own bounds never lie beyond what the verdict calls physical.
    """
    from ..models import REFERENCE_HLC

    ua = [v for v, _ in heat_loss_coefficients(model, params).values() if 0 < v < math.inf]
    s = max(1.0, max(ua, default=0.0) / REFERENCE_HLC)
    limits = {
        k: (lo, hi * s) if k in _SIZED else (lo, hi) for k, (lo, hi) in PHYSICAL_LIMITS.items()
    }
    return limits, s


@dataclasses.dataclass(frozen=True)
class Flag:
    """One finding of the verdict.

    Attributes:
        kind: ``failed``, ``not_converged``, ``at_bound``, ``non_physical``, ``time_constant``,
            ``heat_loss``, ``capacity``, ``prediction``, ``implausible_data``, ``not_identifiable``,
            ``poorly_identifiable``, ``wide_interval``, ``no_intervals`` (invalidating) or
            ``fast_dynamics``, ``multistart``, ``residuals``, ``control`` (warnings);
            ``at_bound`` and ``implausible_data`` can be warnings too.
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
        closed_loop: where the true building was at hand (``plant=``), the
            :class:`~jaxbox.control.ClosedLoopCheck` of the model's MPC against the true
            model's; else ``None``. A model not fit for control gets a warning (``control``),
            not a reason: its validity is judged on its fit.
    """

    valid: bool
    reasons: tuple[str, ...]
    warnings: tuple[str, ...]
    flags: tuple[Flag, ...]
    time_constants: np.ndarray
    closed_loop: object = None

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
            "closed_loop": None if self.closed_loop is None else self.closed_loop.to_dict(),
        }

    def summary(self) -> str:
        head = "VALID" if self.valid else "NOT VALID"
        lines = [head]
        lines += [f"  - {r}" for r in self.reasons]
        lines += [f"  (warning) {w}" for w in self.warnings]
        if self.closed_loop is not None and self.closed_loop.ok:
            lines.append(f"  (control) {self.closed_loop.line}")
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
    years = f"{seconds / _YEAR:.3g}"
    return f"{years} year{'' if years == '1' else 's'}"


def _fmt(value: float, unit: str) -> str:
    return f"{value:.4g} {unit}".rstrip()


def _state_space(model, params) -> tuple[np.ndarray, ...]:
    """(A, B, C, D) at ``params`` as numpy arrays (evaluated in numpy: nothing to compile)."""
    return model.state_space_numpy({k: float(np.asarray(v)) for k, v in params.items()})


def _state_matrix(model, params) -> np.ndarray:
    """The state matrix A [1/s] at ``params``."""
    return _state_space(model, params)[0]


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


def _heat_inputs(model) -> list[str]:
    """Inputs that are heat flows [W]: the heating ``Q_hea*`` if any, else every W input."""
    watts = [u for u in model.inputs if signal_unit(u) == "W"]
    heating = [u for u in watts if u.startswith("Q_hea")]
    return heating or watts


def heat_loss_coefficients(model, params: Mapping[str, float]) -> dict[str, tuple[float, str]]:
    """Heat-loss coefficient UA [W/K] seen by each heat input, from the state space.

    At steady state ``0 = A x + B u``, so the outputs move by ``G = C (−A)⁻¹ B + D`` per unit of
    input (nodes held at a constant temperature left out). For a heat input ``Q`` [W] (the
    heating ``Q_hea*``, or every input in W when there is none) entering the zone of output
    ``y``, ``G_yQ`` [K/W] is the zone's temperature rise per watt with every temperature input
    held: its inverse is the heat flow per kelvin from the zone to ambient and boundaries, UA.
    The output that the input warms most is used.

    Returns:
        ``{input: (UA [W/K], output)}``; empty when the model has no heat input or its state
        matrix is singular. UA is ``inf`` when the input does not warm any output and negative
        when it cools one.
    """
    inputs = _heat_inputs(model)
    if not inputs:
        return {}
    G = model.steady_state_gains(params)
    if G is None or not np.all(np.isfinite(G)):
        return {}
    out = {}
    for u in inputs:
        j = model.inputs.index(u)
        k = int(np.argmax(G[:, j]))
        gain = float(G[k, j])
        out[u] = (1.0 / gain if gain != 0 else math.inf, model.outputs[k])
    return out


def sensor_offsets(model, params: Mapping[str, float]) -> dict[str, float]:
    """The constant sensor offset [K] that each output's constant heat input stands for.

    A model with :func:`~jaxbox.models.components.sensor_offset` (``Off`` in a structure name)
    takes the constant heat ``Q_off`` [W] through the input ``"one"``; at steady state it moves
    the outputs by ``G = C (−A)⁻¹ b`` [K], ``b`` the column of that input: the offset of each
    measured temperature (``Q_off / UA`` for one state). See :meth:`RCModel.sensor_offsets`.

    Returns:
        ``{output: offset [K]}``; empty when the model has no constant input or its state matrix
        is singular.
    """
    return model.sensor_offsets(params)


@dataclasses.dataclass(frozen=True)
class _Judged:
    """What every check reads: the fit, what was derived from it once, and the options of
    :func:`check_validity`."""

    result: object
    specs: dict
    finite: bool
    failed: bool
    tau: np.ndarray
    A: np.ndarray | None
    uncertainty: object
    no_intervals: str | None
    # the options of check_validity
    max_rel_ci: float
    bound_tol: float
    tau_range: tuple[float, float]
    limits: dict
    own_limits: dict
    size: float
    residuals: object
    check_intervals: bool
    validation: object
    max_rmse: float
    max_rmse_ratio: float
    rmse_floor: float
    ua_range: tuple[float, float] | None
    capacity_range: tuple[float, float] | None
    slowest_tau_range: tuple[float, float] | None
    check_data: bool
    data_overrides: Mapping[str, tuple[float, float]] | None
    stuck_hours: float | None

    @property
    def model(self):
        return self.result.model


def _check_optimum(ctx: _Judged) -> list[Flag]:
    result = ctx.result
    status = result.starts.status[result.best]
    if status == "nonfinite" or not math.isfinite(result.cost) or not ctx.finite:
        return [
            Flag("failed", (), "the optimum is not finite: the fit failed; check data and bounds")
        ]
    if status.startswith("failed"):
        return [Flag("failed", (), f"the best start failed ({status}); the fit is not usable")]
    if not result.converged:
        steps = int(result.starts.steps[result.best])
        return [
            Flag(
                "not_converged",
                (),
                f"the best start stopped at the step cap ({steps} iterations) without "
                "converging: raise max_steps, add starts or check the bounds",
            )
        ]
    return []


def _excludes_bound(ctx: _Judged, name: str, bound: float) -> str | None:
    """The interval of ``name`` when it excludes ``bound`` (in words), else None."""
    unc = ctx.uncertainty
    if unc is None or name not in unc.names:
        return None
    lo, hi = unc.ci95[unc.names.index(name)]
    if np.isfinite(lo) and np.isfinite(hi) and not lo <= bound <= hi:
        return f"its {round(100 * unc.level)} % interval [{lo:.4g}, {hi:.4g}]"
    return None


def _span(result) -> float:
    """Duration [s] of the identification data of a fit (0 when unknown)."""
    t = np.asarray(getattr(result.data, "t", ()), dtype=float)
    return float(t[-1] - t[0]) if t.size > 1 else 0.0


def _forgets_its_start(ctx: _Judged, node: int | None, after: float) -> bool:
    """Whether the outputs forget an error in the initial temperature of state ``node``: less
    than :data:`FORGOTTEN` K per K left in every output ``after`` seconds (the response
    ``C·exp(A·after)·e_node`` of the state matrix at the optimum)."""
    if node is None or ctx.A is None or not after > 0 or not np.all(np.isfinite(ctx.A)):
        return False
    from scipy.linalg import expm

    nodes = list(ctx.model.network.nodes)
    outputs = [i for i, m in enumerate(nodes) if m.output is not None]
    if node >= ctx.A.shape[0] or not outputs:
        return False
    response = expm(ctx.A * after)[outputs, node]
    return bool(np.max(np.abs(response)) < FORGOTTEN)


def _check_bounds(ctx: _Judged) -> list[Flag]:
    result, specs = ctx.result, ctx.specs
    nodes = list(ctx.model.network.nodes)
    with np.errstate(invalid="ignore", divide="ignore"):  # a non-physical value: nan position
        pos = result.bound_position()
    flags = []
    for n in result.free:
        x = pos.get(n, float("nan"))
        if not np.isfinite(x) or ctx.bound_tol <= x <= 1 - ctx.bound_tol:
            continue
        side = "lower" if x < 0.5 else "upper"
        lo, hi = result.bounds[n]
        b = lo if side == "lower" else hi
        unit = specs[n].unit
        on = "at" if min(x, 1 - x) < 1e-3 else "near"
        if specs[n].is_initial_state:
            node = next((i for i, m in enumerate(nodes) if m.T0 == n), None)
            extra = ""
            if node is not None and ctx.A is not None and ctx.A[node, node] < 0:
                extra = f" (its own time constant is {_fmt_time(-1.0 / ctx.A[node, node])})"
            if _forgets_its_start(ctx, node, FAST_STATE_SHARE * _span(result)):
                flags.append(
                    Flag(
                        "at_bound",
                        (n,),
                        f"initial temperature {n} = {_fmt(result.params[n], unit)} is pinned "
                        f"{on} its {side} bound {_fmt(b, unit)}{extra}: the outputs forget "
                        f"that start within {100 * FAST_STATE_SHARE:g} % of the data (a fast "
                        "state), so the estimate stands",
                        severe=False,
                    )
                )
                continue
            flags.append(
                Flag(
                    "at_bound",
                    (n,),
                    f"initial temperature {n} = {_fmt(result.params[n], unit)} is pinned {on} "
                    f"its {side} bound {_fmt(b, unit)}{extra}: a slow state started at a limit "
                    "biases the energy balance; narrow its bounds from physical insight (e.g. "
                    "between the zone and ambient or boundary temperatures) or fix it",
                )
            )
            continue
        msg = (
            f"{n} = {_fmt(result.params[n], unit)} is {on} its {side} bound {_fmt(b, unit)}: the "
            "bounds cut the optimum; the model structure does not suit the data, or the bound "
            "is too tight"
        )
        # near (not at) a bound but significantly away from it: a warning, not a reason
        interval = _excludes_bound(ctx, n, b) if on == "near" and ctx.check_intervals else None
        if interval is not None:
            msg += f" ({interval} excludes the bound, so the estimate stands)"
        flags.append(Flag("at_bound", (n,), msg, severe=interval is None))
    return flags


def _check_physical(ctx: _Judged) -> list[Flag]:
    flags = []
    for n in ctx.model.param_names:
        v = ctx.result.params[n]
        rng = _limit(n, ctx.limits)
        if rng is None or not np.isfinite(v):
            continue
        lo, hi = rng
        unit = ctx.specs[n].unit
        open_low = n.startswith("R_") and lo == 0
        if (v <= lo if open_low else v < lo) or v > hi:
            size = ""
            if ctx.size > 1.0 and n.startswith(_SIZED) and _limit(n, ctx.own_limits) is None:
                size = f" for its heat-loss coefficient, {ctx.size:.3g} × the reference's"
            flags.append(
                Flag(
                    "non_physical",
                    (n,),
                    f"{n} = {_fmt(v, unit)} is not physical for a building{size} (expected "
                    f"{'>' if open_low else '≥'} {lo:g} and ≤ {hi:g} {unit})",
                )
            )
    return flags


def _check_time_constants(ctx: _Judged) -> list[Flag]:
    tmin, tmax = ctx.tau_range
    flags = []
    for t in ctx.tau:
        if not np.isfinite(t) or t <= 0:
            flags.append(
                Flag(
                    "time_constant",
                    (),
                    "the state matrix has a mode that does not decay (unstable or "
                    "integrating): the parameters are not physical",
                )
            )
        elif t < tmin and (floor := _floor_capacity(ctx, t)) is not None:
            name, fixed = floor
            flags.append(
                Flag(
                    "time_constant",
                    (name,),
                    f"time constant {_fmt_time(t)} is that of the node of {name}, whose capacity "
                    f"is {'fixed ' if fixed else ''}at its floor: the node is merged into its "
                    "neighbours (massless), and the mode stands for no physical lag",
                    severe=not fixed,
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
    return flags


def _floor_capacity(ctx: _Judged, tau: float) -> tuple[str, bool] | None:
    """The capacity whose node makes the fast mode ``tau`` [s] (the node's own time constant
    ``C/ΣG`` within a factor 2 of it) while the capacity sits at its lower bound, free (within
    ``bound_tol`` in the transform's scale) or fixed there (a reduction fixes it where it ended:
    within ``bound_tol`` of the floor in the scale the fit's transform gives its bounds):
    ``(name, fixed)``, else ``None``."""
    if ctx.A is None:
        return None
    result = ctx.result
    free = set(result.free)
    with np.errstate(invalid="ignore", divide="ignore"):
        pos = result.bound_position()
    for i, node in enumerate(ctx.model.network.nodes):
        name = getattr(node, "C", None)
        if name is None or name not in ctx.specs or getattr(node, "constant", False):
            continue
        if i >= ctx.A.shape[0] or not ctx.A[i, i] < 0:
            continue
        if not 0.5 <= (-1.0 / ctx.A[i, i]) / tau <= 2.0:
            continue
        if name in free:
            at_floor = pos.get(name, math.nan) < ctx.bound_tol
        else:  # fixed where it ended (a reduction): placed as the fit places a free one
            spec, value = ctx.specs[name], float(result.params[name])
            place = make_transform([name], [spec.lower], [spec.upper], [value])
            at_floor = place.relative_position(np.asarray([value]))[0] < ctx.bound_tol
        if at_floor:
            return name, name not in free
    return None


def _check_slowest_mode(ctx: _Judged) -> list[Flag]:
    tau = ctx.tau
    if ctx.slowest_tau_range is None or tau.size == 0 or not np.all(np.isfinite(tau) & (tau > 0)):
        return []  # no modes, or a non-decaying one (flagged above)
    slowest = float(np.max(tau))
    lo, hi = ctx.slowest_tau_range
    tmin, tmax = ctx.tau_range
    if lo <= slowest <= hi or not tmin <= slowest <= tmax:  # in range, or flagged above
        return []
    how = "fast" if slowest < lo else "slowly"
    return [
        Flag(
            "time_constant",
            (),
            f"the slowest time constant {_fmt_time(slowest)} lies outside {_fmt_time(lo)} … "
            f"{_fmt_time(hi)}: no building settles that {how}; check the units of the data "
            "(kW for W, °F for °C) and the bounds",
        )
    ]


def _check_fast_dynamics(ctx: _Judged) -> list[Flag]:
    step = float(ctx.result.data.step)
    tmin = ctx.tau_range[0]
    fast = [t for t in ctx.tau if np.isfinite(t) and 0 < t < step and tmin <= t]
    if not fast:
        return []
    return [
        Flag(
            "fast_dynamics",
            (),
            f"time constant {_fmt_time(min(fast))} is shorter than the sampling step "
            f"{_fmt_time(step)}: the data do not resolve it",
            severe=False,
        )
    ]


def _check_heat_loss(ctx: _Judged) -> list[Flag]:
    if ctx.ua_range is None or not ctx.finite:
        return []
    lo, hi = ctx.ua_range
    flags = []
    for u, (ua, y) in heat_loss_coefficients(ctx.model, ctx.result.params).items():
        if lo <= ua <= hi:
            continue
        what = f"heat-loss coefficient UA = {ua:.3g} W/K (steady-state {u} per K of {y})"
        if not ua > 0:
            msg = f"{what} is not positive: {u} cools the zone at steady state; not physical"
        elif ua < lo:
            msg = (
                f"{what} is below {lo:g} W/K, less than any building: with {u} in kW instead "
                f"of W, UA and the capacities come out 1000× too small; load it with "
                f"scale={{'{u}': 1000}} (--scale {u}=1000)"
            )
        else:
            msg = f"{what} is above {hi:g} W/K, more than any building: check the units of {u}"
        flags.append(Flag("heat_loss", (), msg))
    return flags


def _check_capacity(ctx: _Judged) -> list[Flag]:
    if ctx.capacity_range is None or not ctx.finite:
        return []
    names = [n.C for n in ctx.model.network.nodes if not getattr(n, "constant", False)]
    if not names:
        return []
    total = float(sum(ctx.result.params[n] for n in names))
    lo, hi = ctx.capacity_range
    if lo <= total <= hi:
        return []
    what = f"total heat capacity {total:.3g} J/K ({' + '.join(names)})"
    if total < lo:
        heat = _heat_inputs(ctx.model)
        kw = (
            f"; with {heat[0]} in kW instead of W the capacities come out 1000× too small "
            f"(scale={{'{heat[0]}': 1000}}, --scale {heat[0]}=1000)"
            if heat
            else ""
        )
        msg = f"{what} is below {lo:.3g} J/K, less than any building{kw}"
    else:
        msg = f"{what} is above {hi:.3g} J/K, more than any building: check the units of the data"
    return [Flag("capacity", tuple(names), msg)]


def _check_prediction(ctx: _Judged) -> list[Flag]:
    v = ctx.validation
    if v is None:
        return []
    flags = []
    for name, auto in v.rmse_auto.items():
        cross = None if v.rmse_cross is None else v.rmse_cross.get(name)
        for period, value in (("identification", auto), ("validation", cross)):
            if value is None:
                continue
            if not math.isfinite(value) or value > ctx.max_rmse:
                flags.append(
                    Flag(
                        "prediction",
                        (),
                        f"the {period} RMSE of {name} is {value:.4g} K (limit {ctx.max_rmse:g} "
                        "K): the model does not reproduce the data, or the data are corrupt "
                        "(spikes, units; see jaxbox.data.check_plausibility)",
                    )
                )
        if cross is None or not math.isfinite(cross) or cross > ctx.max_rmse:
            continue
        ratio = cross / auto if auto > 0 else math.inf
        if ratio > ctx.max_rmse_ratio and cross > ctx.rmse_floor:
            flags.append(
                Flag(
                    "prediction",
                    (),
                    f"the validation RMSE of {name} is {cross:.3g} K, {ratio:.3g}× its "
                    f"identification RMSE {auto:.3g} K (limit {ctx.max_rmse_ratio:g}×): the "
                    "model does not predict unseen data, or the validation data are corrupt",
                )
            )
    return flags


def _validation_dataset(validation):
    """The validation window (measured inputs and outputs) as a Dataset, or None."""
    if validation is None or validation.y_cross is None or validation.u_cross is None:
        return None
    signals = {n: validation.u_cross[:, j] for j, n in enumerate(validation.inputs)}
    signals.update({n: validation.y_cross[:, j] for j, n in enumerate(validation.outputs)})
    return Dataset.from_arrays(validation.index_cross, signals, check=False)


#: the findings of the data check by the data's content and the check's options: a search
#: judges dozens of candidates on the same identification and validation windows, and the
#: checks take some 25 ms a window (bounded; the oldest entry goes first)
_FOUND: dict[tuple, tuple[Finding, ...]] = {}
_FOUND_SIZE = 16


def _content_key(data: Dataset, columns: list[str]) -> tuple | None:
    """A key naming ``data``'s values exactly (its index, every column: a check may read
    another column than its own), or ``None`` where that cannot be told (a column not
    numeric, no time index)."""
    frame = getattr(data, "_frame", None)
    stamps = getattr(getattr(frame, "index", None), "asi8", None)
    if stamps is None:
        return None
    h = hashlib.blake2b(digest_size=20)
    h.update(np.ascontiguousarray(stamps).tobytes())
    for name in frame.columns:
        values = frame[name].to_numpy()
        if values.dtype.kind not in "fiub":
            return None
        h.update(str(name).encode() + b"\0" + str(values.dtype).encode())
        h.update(np.ascontiguousarray(values).tobytes())
    return (h.hexdigest(), tuple(columns))


def _implausible(data: Dataset, columns: list[str], ctx: _Judged) -> tuple[Finding, ...]:
    """:func:`~jaxbox.data.find_implausible` of ``columns``, once per content and options."""
    overrides = ctx.data_overrides
    key = _content_key(data, columns)
    if key is not None:
        key += (
            None if overrides is None else repr(sorted(overrides.items())),
            ctx.stuck_hours,
            tuple(sorted(map(repr, _ALLOWED.get()))),
        )
        if key in _FOUND:
            return _FOUND[key]
    try:
        found = find_implausible(
            data, columns=columns, overrides=overrides, stuck_hours=ctx.stuck_hours
        )
    except DataError as err:
        found = (Finding("", "data", str(err)),)
    if key is not None:
        while len(_FOUND) >= _FOUND_SIZE:
            del _FOUND[next(iter(_FOUND))]
        _FOUND[key] = found
    return found


def _check_data(ctx: _Judged) -> list[Flag]:
    if not ctx.check_data:
        return []
    model = ctx.model
    columns = list(dict.fromkeys([*model.inputs, *model.outputs]))
    flags = []
    for what, get in (
        ("identification data", lambda: ctx.result.data),
        ("validation data", lambda: _validation_dataset(ctx.validation)),
    ):
        try:
            data = get()
        except DataError as err:
            found: tuple[Finding, ...] = (Finding("", "data", str(err)),)
        else:
            if data is None:
                continue
            found = _implausible(data, [c for c in columns if c in data], ctx)
        errors = [f for f in found if f.severe]
        for f in errors[:1] + [f for f in found if not f.severe]:
            flags.append(
                Flag(
                    "implausible_data",
                    (),
                    f"{what}: {f.message}"
                    + (f" ({len(errors) - 1} more problem(s))" if f.severe and errors[1:] else ""),
                    severe=f.severe,
                )
            )
    return flags


def _check_intervals(ctx: _Judged) -> list[Flag]:
    if not ctx.check_intervals:
        return []
    if ctx.no_intervals is not None:
        return [Flag("no_intervals", (), f"no confidence intervals: {ctx.no_intervals}")]
    unc = ctx.uncertainty
    if unc is None:
        return []
    flags = []
    for c in unc.combinations:
        flags.append(
            Flag("not_identifiable" if c.singular else "poorly_identifiable", c.parameters, c.text)
        )
    pct = round(100 * unc.level)
    for i, n in enumerate(unc.names):
        r = unc.rel_ci[i]
        if np.isfinite(unc.std[i]) and r > ctx.max_rel_ci:
            flags.append(
                Flag(
                    "wide_interval",
                    (n,),
                    f"{n}: the {pct} % confidence interval is ±{100 * r:.3g} % of its value "
                    f"(more than ±{100 * ctx.max_rel_ci:.3g} %): the data hardly determine it",
                )
            )
    return flags


def _check_multistart(ctx: _Judged) -> list[Flag]:
    st = ctx.result.starts
    if st.n > 1 and st.n_at_best() == 1:
        return [
            Flag(
                "multistart",
                (),
                f"only 1 of {st.n} starts reached the best cost: the sample may be too small to "
                "trust the global optimum; add starts",
                severe=False,
            )
        ]
    return []


def _check_residuals(ctx: _Judged) -> list[Flag]:
    if ctx.residuals is None:
        return []
    return [
        Flag(
            "residuals",
            (),
            f"residuals of {o.name} are not white (Ljung–Box p = {o.ljung_box.p_value:.2g}, "
            f"cumulated periodogram p = {o.periodogram.p_value:.2g}): dynamics or inputs are "
            "missing, and the confidence intervals, which assume white residuals, are too narrow",
            severe=False,
        )
        for o in ctx.residuals
        if not o.white
    ]


#: The checks in the order their flags are reported.
_CHECKS: tuple[Callable[[_Judged], list[Flag]], ...] = (
    _check_optimum,
    _check_bounds,
    _check_physical,
    _check_time_constants,
    _check_slowest_mode,
    _check_fast_dynamics,
    _check_heat_loss,
    _check_capacity,
    _check_prediction,
    _check_data,
    _check_intervals,
    _check_multistart,
    _check_residuals,
)


def _judged(result, uncertainty, **options) -> _Judged:
    """The context of the checks: derived quantities computed once, uncertainty resolved."""
    model = result.model
    values = np.asarray([result.params[n] for n in model.param_names], dtype=float)
    finite = bool(np.all(np.isfinite(values)))
    status = result.starts.status[result.best]
    failed = (
        status == "nonfinite"
        or status.startswith("failed")
        or not math.isfinite(result.cost)
        or not finite
    )
    tau = np.asarray(time_constants(model, result.params)[0] if finite else [], dtype=float)
    A = _state_matrix(model, result.params) if finite else None
    own = options.pop("limits")
    sized, size = physical_limits(model, result.params) if finite else (PHYSICAL_LIMITS, 1.0)
    no_intervals = None
    if options["check_intervals"] and uncertainty is None and not failed:
        from ._uncertainty import uncertainty as _uncertainty

        try:
            uncertainty = _uncertainty(result)
        except ValueError as err:  # no degrees of freedom left
            no_intervals = str(err)
    return _Judged(
        result=result,
        specs={s.name: s for s in model.parameters},
        finite=finite,
        failed=failed,
        tau=tau,
        A=A,
        uncertainty=uncertainty if options["check_intervals"] else None,
        no_intervals=no_intervals,
        limits={**sized, **own},
        own_limits=own,
        size=size,
        **options,
    )


_VERDICT_NEEDS = ("problem", "model", "data", "params", "free", "cost", "starts", "best", "bounds")
"""What :func:`check_validity` reads of its result."""


def _limits(limits) -> dict[str, tuple[float, float]]:
    """``limits`` of :func:`check_validity` checked: parameter names or prefixes to ranges."""
    if limits is None:
        return {}
    out = {}
    for name, rng in check_mapping(limits, "limits", "{'R_': (0.0, 100.0)}").items():
        if not isinstance(name, str):
            raise TypeError(f"limits are keyed by parameter names or prefixes, got {name!r}")
        out[name] = check_range(rng, f"limits[{name!r}]")
    return out


def _optional_range(value, what: str, unit: str):
    """A plausible range ``(low, high)`` ≥ 0, or None (the check skipped)."""
    return None if value is None else check_range(value, what, unit, lower=0.0)


def check_validity(
    result,
    uncertainty=None,
    *,
    max_rel_ci: float | None = None,
    bound_tol: float = 0.01,
    tau_range: tuple[float, float] = (1.0, 10 * _YEAR),
    limits: Mapping[str, tuple[float, float]] | None = None,
    residuals=None,
    check_intervals: bool = True,
    validation=None,
    max_rmse: float = MAX_RMSE,
    max_rmse_ratio: float = MAX_RMSE_RATIO,
    rmse_floor: float = RMSE_FLOOR,
    ua_range: tuple[float, float] | None = UA_RANGE,
    capacity_range: tuple[float, float] | None = CAPACITY_RANGE,
    slowest_tau_range: tuple[float, float] | None = SLOWEST_TAU_RANGE,
    check_data: bool = True,
    data_overrides: Mapping[str, tuple[float, float]] | None = None,
    stuck_hours: float | None = STUCK_HOURS,
    plant=None,
) -> Verdict:
    """The validity verdict of a fit, with reasons.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        uncertainty: its :class:`~jaxbox.validate.Uncertainty` (computed when ``None`` and
            ``check_intervals``).
        max_rel_ci: widest acceptable confidence interval, as a fraction of the value
            (half-width; 0.5 accepts ``θ̂ ± 50 %``); default :data:`MAX_REL_CI` (1.0: the
            interval excludes zero).
        bound_tol: a free parameter within this fraction of its range (in the transform's
            scale: logarithmic for R and C) from a bound is *near* the bound.
        tau_range: acceptable time constants [s] (default 1 s … 10 years).
        limits: physical limits per parameter name or name prefix (SI), merged over
            :data:`PHYSICAL_LIMITS` as sized for the fitted building (:func:`physical_limits`);
            the lower limit of ``R_`` is exclusive.
        residuals: an optional :class:`~jaxbox.validate.ResidualAnalysis`; non-white residuals
            add a warning (never invalidate).
        check_intervals: skip the interval and identifiability checks when False.
        validation: the :class:`~jaxbox.validate.Validation` of ``result`` (from
            :func:`~jaxbox.validate.validate`); without it the prediction is not judged and
            only the identification data are checked for plausibility.
        max_rmse: largest plausible RMSE [K] of an output, on identification or validation
            data (default 5 K).
        max_rmse_ratio: largest validation RMSE as a multiple of the identification RMSE
            (default 10), applied when the validation RMSE is above ``rmse_floor`` [K]
            (default 0.5 K: a small error is fine whatever the ratio).
        ua_range: plausible heat-loss coefficient [W/K] (:func:`heat_loss_coefficients`;
            default 1 … 1e5 W/K); ``None`` skips the check.
        capacity_range: plausible total heat capacity [J/K] of the model's nodes (default
            1e5 … 1e12 J/K); ``None`` skips the check.
        slowest_tau_range: plausible slowest time constant [s] (default 10 min … 1 year);
            ``None`` skips the check.
        check_data: check the model's columns of the identification data (and of the
            validation data, with ``validation``) with :func:`jaxbox.data.find_implausible`.
        data_overrides: plausible ranges per column for that check (``{"T_zon": (lo, hi)}``).
        stuck_hours: for that check, a temperature that does not change for this many hours is
            a stuck sensor (default 24; ``None`` turns it off), as in
            :func:`jaxbox.data.check_plausibility`.
        plant: the true building, where it is at hand (a one-zone
            :class:`~jaxbox.datasets.ZooBuilding` whose data ``result`` was fitted on): the
            verdict gains a closed-loop line, :func:`jaxbox.control.closed_loop_check` (an MPC
            on the model against one on the truth, over the data after the fit's).

    Returns:
        :class:`Verdict` (truthy when valid).

    Raises:
        TypeError: ``result`` is not a FitResult, ``uncertainty``, ``validation`` or
            ``residuals`` not what its function returns, or an option of the wrong type.
        ValueError: an option out of range (limits > 0, ``inf`` switching one off; ranges
            ``(low, high)`` with low < high; ``bound_tol`` in [0, 0.5)), or an ``uncertainty``
            or ``validation`` of another fit.

    Example:
        ```python
        verdict = check_validity(result, validation=validate(result, valid))
        print(verdict.valid, verdict.reasons)
        ```
    """
    result = check_fit(result, needs=_VERDICT_NEEDS)
    uncertainty, validation = check_own(result, uncertainty, validation)
    ctx = _judged(
        result,
        uncertainty,
        max_rel_ci=check_positive(
            MAX_REL_CI if max_rel_ci is None else max_rel_ci, "max_rel_ci", allow_inf=True
        ),
        bound_tol=check_fraction(bound_tol, "bound_tol", upper=0.5),
        tau_range=check_range(tau_range, "tau_range", "s", lower=0.0),
        limits=_limits(limits),
        residuals=check_instance(
            residuals, ResidualAnalysis, "residuals", "jaxbox.validate.analyse_residuals"
        ),
        check_intervals=check_flag(check_intervals, "check_intervals"),
        validation=validation,
        max_rmse=check_positive(max_rmse, "max_rmse", "K", allow_inf=True),
        max_rmse_ratio=check_positive(max_rmse_ratio, "max_rmse_ratio", allow_inf=True),
        rmse_floor=check_fraction(rmse_floor, "rmse_floor [K]", upper=math.inf),
        ua_range=_optional_range(ua_range, "ua_range", "W/K"),
        capacity_range=_optional_range(capacity_range, "capacity_range", "J/K"),
        slowest_tau_range=_optional_range(slowest_tau_range, "slowest_tau_range", "s"),
        check_data=check_flag(check_data, "check_data"),
        data_overrides=check_mapping(data_overrides, "data_overrides", "{'T_zon': (-10, 90)}")
        or None,
        stuck_hours=None
        if stuck_hours is None
        else check_positive(stuck_hours, "stuck_hours", "h", allow_inf=True),
    )
    flags = [flag for check in _CHECKS for flag in check(ctx)]
    loop = None
    if plant is not None:
        from ..control import closed_loop_check

        loop = closed_loop_check(result, plant)
        if not loop.ok:
            flags.append(Flag("control", (), loop.line, severe=False))
    reasons = tuple(f.message for f in flags if f.severe)
    warnings = tuple(f.message for f in flags if not f.severe)
    return Verdict(
        valid=not reasons,
        reasons=reasons,
        warnings=warnings,
        flags=tuple(flags),
        time_constants=ctx.tau,
        closed_loop=loop,
    )


def verdict_of(result, validation, **data_checks) -> Verdict:
    """The validity verdict of a fit with its intervals (σ²(JᵀJ)⁻¹; the interval checks are
    left out where they cannot be computed) and its post-simulation; ``data_checks``: the
    options of its data check (``data_overrides``, ``stuck_hours``; a case's
    :attr:`~jaxbox.select.Case.data_checks`). The verdict a structure search gives each case."""
    from ._uncertainty import uncertainty

    try:
        unc = uncertainty(result)
    except ValueError:
        unc = None
    return check_validity(
        result, unc, check_intervals=unc is not None, validation=validation, **data_checks
    )
