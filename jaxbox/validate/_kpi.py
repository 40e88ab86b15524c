"""Physical key performance indicators of any RC model, with intervals by the delta method.

For a linear RC model ``dx/dt = A x + B u``, ``y = C x + D u`` (nodes held at a constant
temperature left out), the steady state ``0 = A x + B u`` gives the static gain

    ``G = C (−A)⁻¹ B + D``        [output unit per input unit],

the change of the outputs per unit of each input once every transient has died out. Three
numbers are read from the model's matrices, whatever its structure (no formula per model):

* **Heat-loss coefficient** HLC [W/K]. With the heat inputs ``h`` (the heating ``Q_hea*``, or
  every input in W when there is none) and the zone outputs ``y``, ``G_yh`` [K/W] is the zone
  temperature rise per watt of heating with every temperature input held. The HLC is the total
  heating power that keeps the zones at a *uniform* 1 K above their surroundings at steady
  state: ``HLC = 1ᵀ q`` with ``G_yh q = 1``. With one heat input and one zone this is
  ``1 / G_yh``; with as many heat inputs as zones it is ``1ᵀ G_yh⁻¹ 1`` (the whole building's
  loss per kelvin); with one heat input and several outputs the output it warms most is used
  (as :func:`~jaxbox.validate.heat_loss_coefficients`); otherwise the least-norm solution
  (pseudo-inverse).
* **Effective solar aperture** ``gA_eff`` [m²] of each irradiance input ``s`` (W/m²): the
  heating power equivalent to 1 W/m² of that irradiance, i.e. the same zone temperatures at
  steady state, ``1ᵀ q_s`` with ``G_yh q_s = G_ys`` (same solution rule as the HLC). With one
  zone it is ``G_ys / G_yh``. The total aperture is the sum over the irradiance inputs.
* **Time constants** τ [h] ``= −1/λ`` over the eigenvalues λ of A, ascending. A is similar to
  the symmetric ``−K^{-1/2} H K^{-1/2}`` (K the heat capacities, H the conductance matrix) for
  any network of resistances, so its eigenvalues are real and taken with a symmetric
  eigensolver (differentiable while they are distinct); a non-symmetric network falls back to
  the real parts of a general eigensolver.

**Uncertainty.** With ``g(θ)`` the KPIs as functions of the free parameters, ``∇g`` by
forward-mode autodiff at θ̂ and ``Σ`` the parameter covariance of
:func:`~jaxbox.validate.uncertainty` (``σ̂² (JᵀJ)⁻¹``, initial states included), the delta
method gives ``var g = ∇g Σ ∇gᵀ`` and the interval ``ĝ ± t_{N−p} · std`` (the quantile of the
parameter intervals). A KPI that depends on a parameter without a standard error has none
either (``nan``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import jax.numpy as jnp
import numpy as np

from .._compiled import cached, jit
from .._derivatives import value_and_jacfwd
from .._exported import compile_program
from .._x64 import require_x64
from ..data import signal_unit
from ._hlc_hac import HAC, MAX_RHO, WHITE

__all__ = ["KPI", "Kpis", "kpis", "kpi_values", "kpi_inputs"]


@dataclasses.dataclass(frozen=True)
class KPI:
    """One indicator with its delta-method interval.

    Attributes:
        name: ``hlc``, ``solar_aperture``, ``gA_eff:<input>`` or ``tau<k>`` (k = 1 fastest).
        unit: ``W/K``, ``m²`` or ``h``.
        value: estimate.
        std: standard error (``nan`` when a parameter it depends on has none).
        ci95: (lower, upper) of the interval at the :class:`Kpis`' level.
        method: how the interval was made (:data:`~jaxbox.validate._hlc_hac.WHITE` or
            :data:`~jaxbox.validate._hlc_hac.HAC`).
    """

    name: str
    unit: str
    value: float
    std: float
    ci95: tuple[float, float]
    method: str = WHITE

    def to_dict(self) -> dict:
        fin = [float(v) for v in self.ci95]
        ok = all(math.isfinite(v) for v in fin)
        return {
            "value": _num(self.value),
            "unit": self.unit,
            "std": _num(self.std),
            "ci95": fin if ok else None,
            "method": self.method,
        }


def _num(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _residual_entry(key: str, value):
    """One entry of :attr:`Kpis.residuals` for JSON: the verdict ``white`` as it is, the
    blocking level ``block`` [samples] as an integer, the statistics as finite floats or
    ``None``."""
    if key == "white":
        return value
    if key == "block" and value is not None:
        return int(value)
    return _num(value)


@dataclasses.dataclass(frozen=True, eq=False)
class Kpis:
    """The physical indicators of a fit.

    Attributes:
        hlc: heat-loss coefficient [W/K] (``None`` for a model without a heat input).
        solar_aperture: total effective solar aperture [m²] (``None`` without irradiance input).
        apertures: effective aperture per irradiance input [m²].
        time_constants: τ [h] per mode, fastest first.
        heat_inputs: the heat inputs the HLC refers to.
        outputs: the zone outputs it refers to.
        level: confidence level of the intervals.
        gradient: ∂g/∂θ [KPIs, free] (rows in :meth:`all` order, columns ``free``).
        free: the free parameters (columns of ``gradient``).
        method: how the intervals were made (the covariance they rest on).
        residuals: ``{"lag1", "ljung_box_p", "white", "bandwidth", "inflation", "block"}`` of
            the identification residuals (``block``: the samples summed per block at the HAC's
            blocking level; ``bandwidth`` [samples] and ``inflation`` (HAC over
            white standard errors, median over the parameters) of the HAC covariance).
        warnings: what the intervals cannot vouch for: white residuals assumed where they
            are not; a slowest time constant longer than the identification record (the HLC
            then extrapolates to a steady state the data never came near).
    """

    hlc: KPI | None
    solar_aperture: KPI | None
    apertures: dict[str, KPI]
    time_constants: tuple[KPI, ...]
    heat_inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    level: float
    gradient: np.ndarray
    free: tuple[str, ...]
    method: str = WHITE
    residuals: dict = dataclasses.field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def all(self) -> list[KPI]:
        """Every indicator: HLC, apertures per input, total aperture, time constants."""
        out = [] if self.hlc is None else [self.hlc]
        out += list(self.apertures.values())
        out += [] if self.solar_aperture is None else [self.solar_aperture]
        return out + list(self.time_constants)

    def to_dict(self) -> dict:
        """JSON-ready (``nan`` as ``None``)."""
        return {
            "hlc": None if self.hlc is None else self.hlc.to_dict(),
            "solar_aperture": None
            if self.solar_aperture is None
            else self.solar_aperture.to_dict(),
            "apertures": {k: v.to_dict() for k, v in self.apertures.items()},
            "time_constants": [t.to_dict() for t in self.time_constants],
            "heat_inputs": list(self.heat_inputs),
            "outputs": list(self.outputs),
            "level": self.level,
            "method": self.method,
            "residuals": {k: _residual_entry(k, v) for k, v in self.residuals.items()},
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        pct = round(100 * self.level)
        lines = [f"{'indicator':<16} {'value':>11} {'std':>10} {f'{pct}% interval':>24}  unit"]
        for k in self.all():
            ci = f"[{k.ci95[0]:.4g}, {k.ci95[1]:.4g}]" if all(map(math.isfinite, k.ci95)) else "-"
            lines.append(f"{k.name:<16} {k.value:>11.5g} {k.std:>10.3g} {ci:>24}  {k.unit}")
        lines.append(f"intervals: {self.method}")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def kpi_inputs(model) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(heat inputs, irradiance inputs) of ``model``: the heating ``Q_hea*`` (else every input
    in W) and every input in W/m²."""
    watts = [u for u in model.inputs if signal_unit(u) == "W"]
    heating = [u for u in watts if u.startswith("Q_hea")] or watts
    solar = [u for u in model.inputs if signal_unit(u) == "W/m²"]
    return tuple(heating), tuple(solar)


def _symmetric(model, theta) -> bool:
    """Whether the conductance matrix of ``model`` at ``theta`` is symmetric (reciprocal)."""
    # in NumPy: no JAX dispatch (a compilation per operation) for a new structure
    A, _, caps = model.rc_numpy({k: float(np.asarray(v)) for k, v in theta.items()})
    dyn = [i for i, node in enumerate(model.network.nodes) if not node.constant]
    H = (A * caps[:, None])[np.ix_(dyn, dyn)]
    return bool(np.allclose(H, H.T, rtol=1e-10, atol=1e-14 * np.max(np.abs(H), initial=1.0)))


def _steady_state(model, theta):
    """``(G = C (−A)⁻¹ B + D, A, caps)`` of ``model`` at ``theta`` (traceable), over the nodes
    that are not held at a constant temperature: the static gain of the outputs on each input,
    and the state matrix and capacities of those nodes."""
    A, B, caps, held = model.rc_form(theta)
    _, _, C, D = model.state_space(theta)
    dyn = np.asarray([i for i, h in enumerate(held) if not h])
    A_ = A[np.ix_(dyn, dyn)]
    return C[:, dyn] @ jnp.linalg.solve(-A_, B[dyn]) + D, A_, caps[dyn]


def _kpi_function(model, symmetric: bool):
    """theta (mapping) -> [HLC, gA_eff per irradiance input, total gA_eff, τ_1 … τ_n [h]]."""
    heat, solar = kpi_inputs(model)
    jh = [model.inputs.index(u) for u in heat]
    js = [model.inputs.index(u) for u in solar]
    n_out = len(model.outputs)

    def g(theta):
        gain, A_, caps = _steady_state(model, theta)
        out = []
        if jh:
            Gh = gain[:, jh]
            if len(jh) == 1 and n_out > 1:
                k = jnp.argmax(Gh[:, 0])
                solve = lambda rhs: rhs[k] / Gh[k, 0]  # noqa: E731
            elif len(jh) == n_out:
                solve = lambda rhs: jnp.sum(jnp.linalg.solve(Gh, rhs))  # noqa: E731
            else:
                pinv = jnp.linalg.pinv(Gh)
                solve = lambda rhs: jnp.sum(pinv @ rhs)  # noqa: E731
            out.append(solve(jnp.ones(n_out)))
            apertures = [solve(gain[:, j]) for j in js]
            out += apertures
            if apertures:
                out.append(sum(apertures))
        if symmetric:
            H = A_ * caps[:, None]
            s = jnp.sqrt(caps)
            lam = jnp.linalg.eigh(H / s[:, None] / s[None, :])[0]
        else:
            lam = jnp.sort(jnp.real(jnp.linalg.eigvals(A_)))
        out += list(-1.0 / lam / 3600.0)
        return jnp.stack([jnp.asarray(v, dtype=float) for v in out])

    return g


def _compiled(model, free: tuple[str, ...], fixed: tuple[str, ...], symmetric: bool):
    """Compiled (p_free [len(free)], fixed_values [len(fixed)]) -> (g, ∂g/∂p), float64 arrays
    of those sizes, kept in the ``"kpi"`` room and, as an exported program, for later processes
    (:func:`jaxbox._exported.compile_program`: a warm select traced three of them, 0.8 s)."""

    def build():
        g = _kpi_function(model, symmetric)

        def f(p, fv):
            theta = {n: p[i] for i, n in enumerate(free)}
            theta.update({n: fv[i] for i, n in enumerate(fixed)})
            return g(theta)

        key = ("kpi", model.structure, free, fixed, symmetric)
        return _value_and_jacobian_program(key, f, len(free), len(fixed))

    return cached(("kpi", model, free, fixed, symmetric), build)[0]


def _value_and_jacobian_program(key: tuple, f, *sizes: int):
    """``f``'s value and its Jacobian in the first argument, compiled for float64 vectors of
    ``sizes`` and kept as an exported program for later processes
    (:func:`jaxbox._exported.compile_program`, in the ``"kpi"`` room; ``key``, with the model's
    structure, names the program): the KPIs' and the outdoor-referenced HLC's."""
    import jax

    args = tuple(jax.ShapeDtypeStruct((n,), jnp.float64) for n in sizes)
    return compile_program("kpi", key, jit(value_and_jacfwd(f), once=True), args)


def kpi_values(model, params: Mapping[str, float]) -> dict[str, float | list[float]]:
    """The KPIs of ``model`` at ``params`` (SI, every parameter), without uncertainty.

    Returns:
        ``{"hlc": W/K, "apertures": {input: m²}, "solar_aperture": m², "time_constants": [h]}``
        (``hlc``/``solar_aperture`` ``None`` when the model has no heat/irradiance input).
    """
    require_x64()
    from ..models import get_model

    model = get_model(model)
    names = tuple(model.param_names)
    theta = {n: float(params[n]) for n in names}
    fn = _compiled(model, names, (), _symmetric(model, theta))
    values, _ = fn(np.asarray([theta[n] for n in names], dtype=float), np.zeros(0))
    return _unpack(model, np.asarray(values))


def _unpack(model, v: np.ndarray) -> dict:
    heat, solar = kpi_inputs(model)
    out: dict = {"hlc": None, "apertures": {}, "solar_aperture": None}
    i = 0
    if heat:
        out["hlc"] = float(v[0])
        i = 1
        out["apertures"] = {s: float(v[i + k]) for k, s in enumerate(solar)}
        i += len(solar)
        if solar:
            out["solar_aperture"] = float(v[i])
            i += 1
    out["time_constants"] = [float(x) for x in v[i:]]
    return out


def kpis(result, uncertainty=None, *, level: float | None = None, interval: str = "white") -> Kpis:
    """HLC, effective solar apertures and time constants of a fit, with delta-method intervals.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        uncertainty: its :class:`~jaxbox.validate.Uncertainty` (computed when ``None``).
        level: confidence level (default: that of ``uncertainty``, 0.95).
        interval: the parameter covariance the intervals rest on: ``"white"`` (default,
            ``σ̂² (JᵀJ)⁻¹``: white output errors; a warning when the residuals are not white)
            or ``"hac"`` (the prewhitened Newey–West sandwich of
            :func:`~jaxbox.validate.robust_covariance`, for autocorrelated errors, and never
            narrower than the white interval: what the fit report shows).

    Returns:
        :class:`Kpis` (definitions in :mod:`jaxbox.validate._kpi`).

    Raises:
        TypeError: ``result`` is not a FitResult or ``uncertainty`` not an Uncertainty.
        ValueError: the fit has no finite optimum, no degrees of freedom are left for the
            covariance, ``level`` is not in (0, 1), ``interval`` is neither ``"white"`` nor
            ``"hac"``, or ``uncertainty`` is of another fit.

    Example:
        ```python
        k = kpis(result)
        print(k.hlc)                         # heat-loss coefficient [W/K] with its 95 % interval
        ```
    """
    from ._hlc_hac import robust_covariance

    fit = _prepared(result, uncertainty, level, interval)
    problem, uncertainty, free, fixed, p, fv = fit.problem, fit.uncertainty, *fit.arrays
    model = problem.model
    symmetric = _symmetric(model, result.params)
    values, grad = _compiled(model, free, fixed, symmetric)(
        np.asarray(p, dtype=float), np.asarray(fv, dtype=float)
    )
    values, grad = np.asarray(values), np.asarray(grad)
    robust = robust_covariance(result, uncertainty)
    if interval == "hac":
        cov, method = np.asarray(robust.cov_free, dtype=float), HAC
    else:
        cov, method = np.asarray(uncertainty.cov_free, dtype=float), WHITE
    warnings = _warnings(robust, interval)
    level, tq = fit.level, fit.t_quantile
    std = _delta_std(grad, cov, uncertainty, interval)

    def make(i: int, name: str, unit: str) -> KPI:
        v, s = float(values[i]), float(std[i])
        return KPI(name, unit, v, s, (v - tq * s, v + tq * s), method)

    heat, solar = kpi_inputs(model)
    hlc = sol = None
    apertures: dict[str, KPI] = {}
    i = 0
    if heat:
        hlc = make(0, "hlc", "W/K")
        i = 1
        for s in solar:
            apertures[s] = make(i, f"gA_eff:{s}", "m²")
            i += 1
        if solar:
            sol = make(i, "solar_aperture", "m²")
            i += 1
    taus = tuple(make(j, f"tau{j - i + 1}", "h") for j in range(i, len(values)))
    record_h = len(result.data) * float(result.data.step) / 3600.0
    slowest = max((t.value for t in taus), default=0.0)
    if hlc is not None and slowest > record_h:
        warnings += (
            f"the slowest time constant ({slowest:.3g} h) is longer than the identification "
            f"record ({record_h:.3g} h): the HLC is a steady state the data never came near, "
            "and its interval holds only if the structure is right",
        )
    return Kpis(
        hlc=hlc,
        solar_aperture=sol,
        apertures=apertures,
        time_constants=taus,
        heat_inputs=heat,
        outputs=tuple(model.outputs),
        level=float(level),
        gradient=grad,
        free=free,
        method=method,
        residuals={
            "lag1": robust.lag1,
            "ljung_box_p": robust.ljung_box_p,
            "white": robust.white,
            "bandwidth": robust.bandwidth,
            "inflation": robust.inflation,
            "block": robust.block,
        },
        warnings=warnings,
    )


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """A checked fit and what a delta-method indicator reads from it."""

    problem: object
    uncertainty: object
    arrays: tuple  # (free names, fixed names, free values [p], fixed values [f])
    level: float
    t_quantile: float


def _prepared(result, uncertainty, level, interval: str) -> _Prepared:
    """Check a fit for a delta-method indicator (its kind, a finite optimum, the uncertainty
    its own, the level and the interval's name), computing its uncertainty where not given."""
    from scipy import stats

    from ._args import check_fit, check_interval, check_level
    from ._own import check_own
    from ._uncertainty import uncertainty as _uncertainty

    require_x64()
    check_interval(interval)
    problem = check_fit(result).problem
    uncertainty = check_own(result, uncertainty, None)[0]
    level = None if level is None else check_level(level)
    if uncertainty is None:
        uncertainty = _uncertainty(result)
    free = tuple(problem.free)
    fixed = tuple(n for n, _ in problem.fixed)
    p = np.asarray([result.params[n] for n in free], dtype=float)
    fv = np.asarray([v for _, v in problem.fixed], dtype=float)
    if not np.all(np.isfinite(p)):
        raise ValueError("the fit has no finite optimum; there are no indicators to compute")
    if level is None:
        level, tq = float(uncertainty.level), float(uncertainty.t_quantile)
    else:
        tq = float(stats.t.ppf(0.5 + level / 2, uncertainty.dof))
    return _Prepared(problem, uncertainty, (free, fixed, p, fv), float(level), tq)


def _delta_std(grad: np.ndarray, cov: np.ndarray, uncertainty, interval: str) -> np.ndarray:
    """:func:`_delta` over ``cov``; for ``"hac"`` never below the white standard error (of
    ``uncertainty``): a HAC estimate below it (residuals that alternate) is mostly the sampling
    error of the long-run variance of a short record."""
    std = _delta(grad, cov)
    if interval == "hac":
        white = _delta(grad, np.asarray(uncertainty.cov_free, dtype=float))
        std = np.where(np.isfinite(std) & np.isfinite(white), np.maximum(std, white), std)
    return std


def _delta(grad: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Standard errors ``√(∇g Σ ∇gᵀ)`` per KPI (rows of ``grad``); ``nan`` where a parameter it
    depends on has no covariance."""
    std = np.full(len(grad), np.nan)
    for k in range(len(grad)):
        row = grad[k]
        used = np.abs(row) > 0
        if not np.all(np.isfinite(row)):
            continue
        sub = cov[np.ix_(used, used)]
        if np.all(np.isfinite(sub)):
            var = float(row[used] @ sub @ row[used])
            std[k] = math.sqrt(var) if var >= 0 else math.nan
    return std


def _warnings(robust, interval: str) -> tuple[str, ...]:
    """What the intervals cannot vouch for, in words."""
    said = f"Ljung–Box p = {robust.ljung_box_p:.2g}, lag-1 autocorrelation {robust.lag1:.2f}"
    if interval == "white":
        if robust.white:
            return ()
        if robust.inflation > 1.2:
            how = f"too narrow, by about {robust.inflation:.2g}× going by the HAC covariance"
        else:
            how = "the HAC covariance gives intervals about as wide here"
        return (
            f"the intervals assume white residuals but these are not ({said}): {how} "
            "(interval='hac')",
        )
    if np.any(np.abs(robust.rho) >= 0.999 * MAX_RHO) and robust.lag1 > MAX_RHO:
        return (
            f"the residuals are so persistent ({said}) that even the HAC interval may be too "
            "narrow; a longer record or a better structure would settle it",
        )
    return ()
