"""The heat-demand form of a structure: the zone's measured temperature imposed, the heating
computed from the energy balance of the zone node.

Under a thermostat the zone temperature barely varies and the heating does: the information
is in the heating, not in the temperature. The heat-demand form inverts the same RC network
(:meth:`jaxbox.models.RCModel.rc_form`): the zone node is driven by its measured temperature
``T_zon`` (first-order hold between samples, like every input), the other nodes (envelope,
internal mass) are simulated exactly from it and the other inputs, and the heating over each
interval ``[t_k, t_k+1]`` is what the zone node's balance asks for::

    Q̄_k = C_zon (T_zon,k+1 − T_zon,k) / Δt  −  mean over the interval of the flows into the zone
          node other than the heating (conduction from the other nodes and the ambient, solar
          and internal gains, the offset Q_off)                                          [W]

compared with the measured interval mean ``(Q_k + Q_k+1)/2`` (first-order hold). The fit is a
least-squares fit of the heating [W] (:func:`scipy.optimize.least_squares`, a few starts), the
other nodes' initial temperatures estimated with the rest (from their steady state with the
first day's mean inputs; they judge nothing in the verdict). The 95 % intervals come
from the prewhitened Newey–West (HAC) covariance of :mod:`jaxbox.validate._hlc_hac` (the
residuals of hourly heating are autocorrelated; ``σ²(JᵀJ)⁻¹`` would understate them). The
heat-loss coefficient is the steady-state heat the zone node loses per kelvin
above the ambient (every other input at zero), with its interval by the delta method.

Only structures whose heating enters the zone node alone can be inverted this way (no heater
capacity ``Hea``, no radiative share ``Rad``); :func:`heat_demand_search` grows them from the
grammar's root, one component at a time, like the structure search: a child is kept when it is
valid and its validation RMSE of the heating is lower by the margin; a capacity, aperture or
offset that its interval does not determine is fixed where its component vanishes (the node
merged, the gain dropped) and the candidate identified again.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import linalg, optimize

from ..models._grammar import Grammar, Structure, extensions, parse_structure, roots
from ..models._network import RCModel
from ..validate import MAX_REL_CI
from ..validate._hlc import _excess_over_outdoor, _unmeasured_text
from ..validate._hlc_hac import HAC

__all__ = ["HeatDemandFit", "heat_demand_fit", "heat_demand_search", "held_zone", "Problem"]

#: 95 % two-sided normal quantile
Z95 = 1.959963984540054
#: a held zone: std of the zone temperature at most this [K] …
HELD_STD = 0.6
#: … and at most this fraction of the ambient temperature's std
HELD_RATIO = 0.15


def held_zone(data, zone: str = "T_zon", heating: str = "Q_hea") -> tuple[bool, str]:
    """Whether ``zone`` is held by its thermostat in ``data``: its temperature varies little
    (std at most :data:`HELD_STD` K and at most :data:`HELD_RATIO` of the ambient's) while the
    heating varies. Returns ``(held, why in words)``."""
    cols = data.columns
    if zone not in cols or "T_amb" not in cols or heating not in cols:
        return False, "no zone temperature, ambient temperature or heating column"
    tz, ta, q = (np.asarray(data[c], dtype=float) for c in (zone, "T_amb", heating))
    sz, sa, sq = (float(np.nanstd(x)) for x in (tz, ta, q))
    mq = float(np.nanmean(np.abs(q)))
    text = f"std of {zone} {sz:.3g} K, of T_amb {sa:.3g} K, of {heating} {sq:.4g} W"
    held = sz <= HELD_STD and sz <= HELD_RATIO * sa and sq > 0.05 * max(mq, 1e-9)
    return held, ("held by its thermostat: " if held else "not held: ") + text


# ---- the problem --------------------------------------------------------------------------------


class Problem:
    """The data of a heat-demand fit: the inputs on a regular grid, the measured interval mean
    heating, and which intervals identify and which validate.

    Args:
        data: a Dataset (regular step); short gaps of the inputs are interpolated, intervals
            whose heating is missing are left out.
        ident, valid: (start, end) timestamps of the identification and validation periods
            (``valid`` ``None``: the identification period serves as both).
        zone, heating: the zone temperature and heating columns.
    """

    def __init__(self, data, ident, valid=None, zone: str = "T_zon", heating: str = "Q_hea"):
        frame = data.frame
        self.zone, self.heating, self.dt = zone, heating, float(data.step)
        self.index = frame.index
        self.frame = frame.interpolate(limit_direction="both")
        q = np.asarray(frame[heating], dtype=float)
        self.q_mean = 0.5 * (q[:-1] + q[1:])  # measured interval mean [W] (first-order hold)
        t = frame.index[:-1]

        def mask(period):
            m = np.isfinite(self.q_mean) & (t >= period[0]) & (t < period[1])
            return np.asarray(m)

        self.ident = mask(ident)
        self.valid = mask(valid) if valid is not None else self.ident
        self.has_valid = valid is not None

    def column(self, name: str) -> np.ndarray:
        """A column of the data, gaps interpolated (``"one"``: ones)."""
        if name == "one":
            return np.ones(len(self.frame))
        return np.asarray(self.frame[name], dtype=float)


# ---- one structure ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class HeatDemandFit:
    """A structure identified in its heat-demand form.

    Attributes:
        structure: the structure name (``+reduced`` parts in ``fixed``).
        params: estimates (SI), the fixed ones included.
        fixed: parameters fixed where their component vanishes.
        intervals: 95 % interval of each free parameter (SI).
        hlc: heat-loss coefficient [W/K]; ``hlc_interval`` its 95 % interval.
        rmse_ident, rmse_valid: RMSE of the interval mean heating [W] on the identification and
            validation intervals; ``q_std`` the std of the measured heating on validation [W].
        valid: the verdict; ``reasons`` why not; ``undetermined`` the free parameters whose
            interval is too wide (half-width over :data:`~jaxbox.validate.MAX_REL_CI`).
        form: ``"heat demand"``.
        hlc_method: how the HLC's interval was made (the HAC covariance of the heating's
            residuals, by the delta method).
        zone_excess: the zone's mean excess over the outdoor air over the record [K], for a
            structure without an offset (``None`` otherwise): see :attr:`per_100_w`.
        validated: whether a validation period was held out (``False``: ``rmse_valid`` and
            ``q_std`` are the identification period's).
    """

    structure: str
    params: dict
    fixed: dict
    intervals: dict
    hlc: float
    hlc_interval: tuple
    rmse_ident: float
    rmse_valid: float
    q_std: float
    valid: bool
    reasons: tuple = ()
    undetermined: tuple = ()
    form: str = "heat demand"
    hlc_method: str = HAC
    zone_excess: float | None = None
    validated: bool = True

    @property
    def per_100_w(self) -> float | None:
        """What 100 W of mean heat input that the data do not measure (occupants, appliances)
        would add to the HLC [W/K], ``100 / zone_excess`` (as
        :attr:`jaxbox.validate.HlcInterval.per_100_w`)."""
        return None if self.zone_excess is None else 100.0 / self.zone_excess

    @property
    def relative(self) -> float:
        """Validation RMSE of the heating over its std (comparable with the temperature form's
        RMSE over the zone temperature's std)."""
        return self.rmse_valid / max(self.q_std, 1e-9)

    def summary(self) -> str:
        """The model, its HLC, errors and verdict, then one line per parameter."""
        lo, hi = self.hlc_interval
        lines = [
            f"{self.structure} in its heat-demand form: HLC {self.hlc:.4g} W/K "
            f"[{lo:.4g}, {hi:.4g}] ({self.hlc_method}), heating RMSE {self.rmse_valid:.4g} W on "
            + ("validation " if self.validated else "identification (no validation period) ")
            + f"({self.relative:.3g} of its std {self.q_std:.4g} W), "
            + ("valid" if self.valid else "not valid: " + "; ".join(self.reasons))
        ]
        if self.zone_excess is not None:
            lines.append("  " + _unmeasured_text(self.zone_excess))
        for n, v in self.params.items():
            if n in self.fixed:
                lines.append(f"  {n:<8} {v:12.5g}  fixed")
            else:
                a, b = self.intervals[n]
                lines.append(f"  {n:<8} {v:12.5g}  [{a:.5g}, {b:.5g}]")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready fields (SI units)."""
        d = dataclasses.asdict(self)
        d["relative"] = self.relative
        d["hlc_interval"] = list(self.hlc_interval)
        d["intervals"] = {k: list(v) for k, v in self.intervals.items()}
        d["reasons"], d["undetermined"] = list(self.reasons), list(self.undetermined)
        d["per_100_w"] = self.per_100_w
        return d


class _Network:
    """A structure's network in its heat-demand form: parameters -> heating per interval."""

    def __init__(self, structure: Structure, grammar: Grammar, problem: Problem, fixed: dict):
        import jax

        model = structure.build(grammar)
        self.model, self.problem = model, problem
        nodes = model.network.nodes
        self.z = next(i for i, n in enumerate(nodes) if n.output == problem.zone)
        self.o = [i for i in range(len(nodes)) if i != self.z]
        self.inputs = list(model.inputs)
        if problem.heating not in self.inputs:
            raise ValueError(f"{structure.name}: no heating input {problem.heating!r}")
        self.qi = self.inputs.index(problem.heating)
        self.rest = [j for j in range(len(self.inputs)) if j != self.qi]
        self.names = [n for n in model.param_names if not (n.startswith("T_") and n.endswith("0"))]
        self.fixed = {k: v for k, v in fixed.items() if k in self.names}
        # the other nodes' initial temperatures are estimated (linear, within the data's range)
        self.x0_names = [nodes[i].T0 for i in self.o]
        self.free = [n for n in self.names if n not in self.fixed] + self.x0_names
        self.log = [n not in self.x0_names and model.parameter(n).lower > 0 for n in self.free]
        names = self.names
        defaults = {n: model.parameter(n).default for n in model.param_names}

        def rc(v):
            theta = {**defaults, **dict(zip(names, v, strict=True))}
            A, B, caps, _ = model.rc_form(theta)
            return A, B, caps

        self._rc = jax.jit(rc)
        self.u = np.stack([problem.column(c) for c in self.inputs], axis=1)
        self.tz = problem.column(problem.zone)
        temps = np.concatenate([self.tz, problem.column("T_amb")])
        self.t_range = (float(np.nanmin(temps)) - 5.0, float(np.nanmax(temps)) + 5.0)

    def limits(self, name: str) -> tuple[float, float]:
        """Bounds of a parameter (SI): an initial temperature within the data's range."""
        if name in self.x0_names:
            return self.t_range
        return self.model.parameter(name).lower, self.model.parameter(name).upper

    # parameters <-> search coordinates
    def theta(self, p) -> dict:
        pairs = zip(self.free, p, self.log, strict=True)
        vals = {n: (math.exp(x) if lg else x) for n, x, lg in pairs}
        return {n: vals.get(n, self.fixed.get(n)) for n in self.names + self.x0_names}

    def coords(self, theta: dict) -> np.ndarray:
        out = []
        for n, lg in zip(self.free, self.log, strict=True):
            lo, hi = self.limits(n)
            v = float(np.clip(theta[n], lo, hi))
            out.append(math.log(v) if lg else v)
        return np.asarray(out)

    def bounds(self):
        lo, hi = [], []
        for n, lg in zip(self.free, self.log, strict=True):
            a, b = self.limits(n)
            lo.append(math.log(a) if lg else a)
            hi.append(math.log(b) if lg else b)
        return np.asarray(lo), np.asarray(hi)

    def matrices(self, theta: dict):
        A, B, caps = (
            np.asarray(x, dtype=float)
            for x in self._rc(np.asarray([theta[n] for n in self.names], dtype=float))
        )
        return A, B, caps

    def heating(self, theta: dict) -> np.ndarray:
        """Interval mean heating [W] the zone node's balance asks for, per interval."""
        A, B, caps = self.matrices(theta)
        z, o, dt = self.z, self.o, self.problem.dt
        cz = caps[z]
        bq = B[z, self.qi] * cz  # share of the heating into the zone node (1)
        tz, u = self.tz, self.u[:, self.rest]
        tbar = 0.5 * (tz[:-1] + tz[1:])
        ubar = 0.5 * (u[:-1] + u[1:])
        flow = cz * (A[z, z] * tbar + ubar @ B[z, self.rest])
        if o:
            if np.any(B[np.ix_(o, [self.qi])] != 0.0):
                raise ValueError("the heating enters a node other than the zone")
            x0 = np.asarray([theta[n] for n in self.x0_names], dtype=float)
            xbar = _node_means(A, B, z, o, self.rest, tz, u, dt, x0)
            flow = flow + cz * (xbar @ A[z, o])
        return (cz * np.diff(tz) / dt - flow) / bq

    def hlc(self, theta: dict) -> float:
        """Steady-state heat [W/K] the zone node loses per kelvin above the ambient."""
        return self.hlc_after(theta, None)

    def hlc_after(self, theta: dict, seconds: float | None) -> float:
        """Heat [W/K] the zone node takes per kelvin ``seconds`` after its temperature steps
        up by one kelvin from rest, every other input held: the conductance a record of that
        length shows. The other nodes are then at ``A_oo⁻¹ (e^{A_oo t} − I) A_oz`` and still
        taking heat, so it lies above :meth:`hlc`, its limit as ``t`` grows (``None``: that
        steady state, the other nodes at ``−A_oo⁻¹ A_oz``)."""
        A, _, caps = self.matrices(theta)
        z, o = self.z, self.o
        row = A[z, z]
        if o:
            Aoo = A[np.ix_(o, o)]
            lag = (
                -np.eye(len(o)) if seconds is None else linalg.expm(Aoo * seconds) - np.eye(len(o))
            )
            row = row + A[z, o] @ np.linalg.solve(Aoo, lag @ A[o, z])
        return float(-caps[z] * row)


def _steady_nodes(A, B, z, o, rest, tz, u, dt) -> np.ndarray:
    """Temperatures [°C] of the nodes ``o`` in steady state with the first day's mean zone
    temperature ``tz`` and inputs ``u``."""
    first = max(1, min(len(tz), int(round(86400.0 / dt))))
    w = np.concatenate([[np.mean(tz[:first])], np.mean(u[:first], axis=0)])
    Bo = np.concatenate([A[np.ix_(o, [z])], B[np.ix_(o, rest)]], axis=1)
    return np.linalg.solve(A[np.ix_(o, o)], -Bo @ w)


def _node_means(A, B, z, o, rest, tz, u, dt, x0=None) -> np.ndarray:
    """Mean temperature of the nodes ``o`` over each interval, driven by the zone's imposed
    temperature ``tz`` and the inputs ``u`` (first-order hold), exact (one matrix exponential),
    from ``x0`` (``None``: in steady state with the first day's mean inputs)."""
    n = len(o)
    Ao = A[np.ix_(o, o)]
    Bo = np.concatenate([A[np.ix_(o, [z])], B[np.ix_(o, rest)]], axis=1)
    w = np.concatenate([tz[:, None], u], axis=1)
    m = w.shape[1]
    M = np.zeros((2 * n + 2 * m, 2 * n + 2 * m))
    M[:n, n : 2 * n] = np.eye(n)
    M[n : 2 * n, n : 2 * n] = Ao
    M[n : 2 * n, 2 * n : 2 * n + m] = Bo
    M[2 * n : 2 * n + m, 2 * n + m :] = np.eye(m)
    E = linalg.expm(M * dt)
    Ix, Iw, Iv = E[:n, n : 2 * n], E[:n, 2 * n : 2 * n + m], E[:n, 2 * n + m :]
    Xx, Xw, Xv = E[n : 2 * n, n : 2 * n], E[n : 2 * n, 2 * n : 2 * n + m], E[n : 2 * n, 2 * n + m :]
    if x0 is None:
        x = _steady_nodes(A, B, z, o, rest, tz, u, dt)
    else:
        x = np.asarray(x0, dtype=float)
    v = np.diff(w, axis=0) / dt
    # x_{k+1} = Xx x_k + c_k with c_k known: a linear recurrence
    c = w[:-1] @ Xw.T + v @ Xv.T
    d = w[:-1] @ Iw.T + v @ Iv.T
    K = len(w) - 1
    xs = np.empty((K, n))
    for k in range(K):
        xs[k] = x
        x = Xx @ x + c[k]
    return (xs @ Ix.T + d) / dt


def heat_demand_fit(
    structure: Structure | str,
    grammar: Grammar,
    problem: Problem,
    *,
    guess: dict | None = None,
    fixed: dict | None = None,
    starts: int = 4,
    seed: int = 0,
) -> HeatDemandFit:
    """Identify ``structure`` in its heat-demand form (see the module).

    Args:
        structure: a grammar structure (or its name) whose heating enters the zone node only.
        grammar: the grammar it is built from.
        problem: the data (:class:`Problem`).
        guess: starting values (SI) by name (the rest: the parameters' defaults).
        fixed: parameters held at a value (SI).
        starts: starts (the guess, then log-normal perturbations of it, a factor of about 5).
        seed: seed of the perturbations.

    Returns:
        :class:`HeatDemandFit`.

    Raises:
        ValueError: the heating enters a node other than the zone.
    """
    if isinstance(structure, str):
        structure = parse_structure(structure)
    net = _Network(structure, grammar, problem, dict(fixed or {}))
    base = {n: net.model.parameter(n).default for n in net.names}
    base.update({k: v for k, v in (guess or {}).items() if k in base})
    base.update(net.fixed)
    if net.o:  # initial temperatures: in steady state with the first day's mean inputs
        A, B, _ = net.matrices(base)
        x = _steady_nodes(A, B, net.z, net.o, net.rest, net.tz, net.u[:, net.rest], problem.dt)
        for n, v in zip(net.x0_names, x, strict=True):
            base[n] = (guess or {}).get(n, float(v))
    lo, hi = net.bounds()
    scale = float(np.nanstd(problem.q_mean[problem.ident])) or 1.0
    y, mi = problem.q_mean, problem.ident

    def resid(p):
        r = (net.heating(net.theta(p)) - y)[mi] / scale
        return np.where(np.isfinite(r), r, 1e3)

    rng = np.random.default_rng(seed)
    p0 = np.clip(net.coords(base), lo + 1e-9, hi - 1e-9)
    best = None
    for s in range(max(starts, 1)):
        p = p0 if s == 0 else p0 + np.where(net.log, rng.normal(0.0, 1.6, p0.size), 0.0)
        p = np.clip(p, lo + 1e-9, hi - 1e-9)
        if not np.isfinite(resid(p)).all():
            continue
        try:
            sol = optimize.least_squares(resid, p, bounds=(lo, hi), x_scale="jac", max_nfev=400)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        raise ValueError(f"{structure.name}: no start could be fitted in its heat-demand form")
    return _judged(net, best, scale)


def _judged(net: _Network, sol, scale: float) -> HeatDemandFit:
    """Estimates, intervals (autocorrelation-inflated), HLC and verdict of a fit."""
    problem = net.problem
    p = sol.x
    theta = net.theta(p)
    q = net.heating(theta)
    e_id = (q - problem.q_mean)[problem.ident]
    e_va = (q - problem.q_mean)[problem.valid]
    k = p.size
    J = np.asarray(sol.jac, dtype=float) * scale
    lo, hi = net.bounds()
    width = hi - lo
    on_bound = [  # (an initial temperature the fit leaves at a bound judges nothing)
        n_
        for n_, x, a, b, w in zip(net.free, p, lo, hi, width, strict=True)
        if ((x - a) < 1e-4 * w or (b - x) < 1e-4 * w) and n_ not in net.x0_names
    ]
    try:
        cov = _hac(J, e_id)
    except np.linalg.LinAlgError:
        cov = np.full((k, k), np.inf)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    intervals, undetermined = {}, []
    for i, (name, lg) in enumerate(zip(net.free, net.log, strict=True)):
        v = theta[name]
        half = Z95 * sd[i] * (abs(v) if lg else 1.0)  # delta method in value space
        intervals[name] = (v - half, v + half)
        if name not in net.x0_names and (not np.isfinite(half) or half > MAX_REL_CI * abs(v)):
            undetermined.append(name)
    hlc = net.hlc(theta)
    g = np.zeros(k)
    for i in range(k):
        dp = np.zeros(k)
        dp[i] = 1e-5 * max(1.0, abs(p[i]))
        g[i] = (net.hlc(net.theta(p + dp)) - net.hlc(net.theta(p - dp))) / (2 * dp[i])
    hlc_sd = float(math.sqrt(max(g @ cov @ g, 0.0)))
    # up to the conductance the identification record shows (validate/_hlc.py, the record's
    # length): the steady state beyond it is the model's extrapolation
    lo_hlc, hi_hlc, method = hlc - Z95 * hlc_sd, hlc + Z95 * hlc_sd, HAC
    span = float(np.count_nonzero(problem.ident)) * problem.dt
    record = net.hlc_after(theta, span) if span > 0 else math.nan
    if np.isfinite(record) and record > hi_hlc:
        hi_hlc = record
        method += (
            f" + up to the conductance the record shows ({record:.3g} W/K after "
            f"{span / 3600:.3g} h)"
        )
    reasons = [f"{n_} on a bound" for n_ in on_bound]
    reasons += [
        f"{n_} undetermined (95 % interval {intervals[n_][0]:.3g} to {intervals[n_][1]:.3g})"
        for n_ in undetermined
        if n_ not in on_bound
    ]
    if not np.isfinite(hlc) or hlc <= 0:
        reasons.append(f"HLC {hlc:.3g} W/K not positive")
    return HeatDemandFit(
        structure=net.model.name,
        params={n_: float(theta[n_]) for n_ in net.names + net.x0_names},
        fixed={k_: float(v) for k_, v in net.fixed.items()},
        intervals=intervals,
        hlc=hlc,
        hlc_interval=(lo_hlc, hi_hlc),
        hlc_method=method,
        rmse_ident=float(np.sqrt(np.mean(e_id**2))),
        rmse_valid=float(np.sqrt(np.mean(e_va**2))),
        q_std=float(np.std(problem.q_mean[problem.valid])),
        valid=not reasons,
        reasons=tuple(reasons),
        undetermined=tuple(undetermined),
        zone_excess=_excess_over_outdoor(problem.frame, problem.zone, net.names),
        validated=bool(problem.has_valid),
    )


def _hac(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The prewhitened Newey–West (HAC) covariance ``B Ω B · N/(N − p)`` of the parameters of a
    least-squares fit with sensitivities ``J`` [N, p] and residuals ``e`` [N], ``B = (JᵀJ)⁺``:
    the sandwich of :mod:`jaxbox.validate._hlc_hac` (hourly residuals of the heating are
    autocorrelated; the white covariance would understate the intervals), never narrower than
    the white one."""
    from ..validate._hlc_hac import MAX_RHO, _sandwich

    n, k = J.shape
    bread = np.linalg.pinv(J.T @ J)
    sandwich, _, _ = _sandwich(J * e[:, None], bread, MAX_RHO)
    cov = sandwich * n / max(n - k, 1)
    cov = 0.5 * (cov + cov.T)
    # never narrower than the white covariance σ²(JᵀJ)⁺, parameter by parameter
    white = bread * float(e @ e) / max(n - k, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        widen = np.sqrt(np.maximum(np.diag(white) / np.diag(cov), 1.0))
    widen = np.where(np.isfinite(widen), widen, 1.0)
    return cov * widen[:, None] * widen[None, :]


# ---- the search ---------------------------------------------------------------------------------


def _invertible(structure: Structure) -> bool:
    """Whether the heating of ``structure`` enters the zone node only (no heater capacity, no
    radiative share), on one zone."""
    tokens = structure.name.split("+")
    return not any(
        t in ("Hea", "Rad") or t.startswith("Zon2") or t.startswith("Cpl") for t in tokens
    )


def _vanishing(fit: HeatDemandFit, model: RCModel) -> dict:
    """The parameters of an invalid fit that vanish where their component does, with the value
    that removes it: a capacity at its lower bound in ``model`` (the node merged), an aperture,
    gain or offset at 0 (dropped). Empty when anything else makes it invalid."""
    bad = set(fit.undetermined) | {r.split(" ")[0] for r in fit.reasons if "bound" in r}
    out = {}
    for name in bad:
        if name.startswith("C_"):
            out[name] = model.parameter(name).lower
        elif name.startswith(("gA", "Q_off", "fra_ele")):
            out[name] = 0.0
        else:
            return {}
    return out


@dataclasses.dataclass(frozen=True)
class HeatDemandSearch:
    """The candidates of :func:`heat_demand_search` and the one it keeps.

    Attributes:
        best: the best valid candidate (``None``: none valid).
        tree: ``(structure, parent, fit or error text, status)`` per candidate, in order.
    """

    best: HeatDemandFit | None
    tree: tuple = ()

    def tree_text(self, accepted: bool = True) -> str:
        """One line per candidate; ``*`` marks the best when ``accepted`` (the form chosen)."""
        lines = []
        for name, parent, fit, status in self.tree:
            mark = "*" if accepted and self.best is not None and fit is self.best else " "
            where = "" if parent is None else f" (from {parent})"
            if isinstance(fit, HeatDemandFit):
                extra = "" if fit.valid else f": {fit.reasons[0]}"
                fixed = (
                    " with " + ", ".join(f"{k}={v:.3g}" for k, v in fit.fixed.items())
                    if fit.fixed
                    else ""
                )
                lines.append(
                    f"{mark} {name}{fixed}{where}  [heating RMSE {fit.rmse_valid:.4g} W, "
                    f"{fit.relative:.3g} of std; HLC {fit.hlc:.4g} W/K] {status}{extra}"
                )
            else:
                lines.append(f"  {name}{where}  {status}: {fit}")
        return "\n".join(lines)


def heat_demand_search(
    grammar: Grammar,
    problem: Problem,
    *,
    margin: float = 0.02,
    max_depth: int = 3,
    starts: int = 4,
    seed: int = 0,
    say=None,
) -> HeatDemandSearch:
    """Grow the invertible structures of ``grammar`` in their heat-demand form from its root:
    each step fits every one-component extension of the current best (from its optimum); a
    child is kept when it is valid and its validation RMSE of the heating is lower by
    ``margin`` (relative). An invalid candidate whose undetermined parameters all vanish with
    their component (:func:`_vanishing`) is fitted again with them fixed there. The root is
    grown even when not valid."""
    say = say or (lambda _t: None)
    tree: list = []
    seen: set[str] = set()

    def fit(structure, parent_fit, parent_name):
        guess = dict(parent_fit.params) if parent_fit is not None else None
        try:
            f = heat_demand_fit(structure, grammar, problem, guess=guess, starts=starts, seed=seed)
        except (ValueError, np.linalg.LinAlgError) as err:
            tree.append((structure.name, parent_name, str(err), "failed"))
            return None
        cut = {} if f.valid else _vanishing(f, structure.build(grammar))
        if cut:
            tree.append((structure.name, parent_name, f, "reduced"))
            try:
                f = heat_demand_fit(
                    structure,
                    grammar,
                    problem,
                    guess=f.params,
                    fixed=cut,
                    starts=max(2, starts // 2),
                    seed=seed,
                )
            except (ValueError, np.linalg.LinAlgError) as err:
                tree.append((structure.name, parent_name, str(err), "failed"))
                return None
        say(
            f"  heat-demand form {structure.name}: heating RMSE {f.rmse_valid:.4g} W, HLC "
            f"{f.hlc:.4g} W/K, " + ("valid" if f.valid else f"not valid ({f.reasons[0]})")
        )
        return f

    root = next((s for s in roots(grammar) if _invertible(s)), None)
    if root is None:
        return HeatDemandSearch(None, ())
    seen.add(root.name)
    current = fit(root, None, None)
    if current is None:
        return HeatDemandSearch(None, tuple(tree))
    tree.append((root.name, None, current, "root"))
    best = current if current.valid else None
    cur_struct = root
    for _ in range(max_depth):
        children = []
        for _added, child in extensions(cur_struct, grammar):
            if child.name in seen or not _invertible(child):
                continue
            seen.add(child.name)
            f = fit(child, current, cur_struct.name)
            if f is not None:
                children.append((child, f))
        improving = []
        for child, f in children:
            ref = best.rmse_valid if best is not None else current.rmse_valid
            better = f.valid and f.rmse_valid < (1.0 - margin) * ref
            tree.append(
                (
                    child.name,
                    cur_struct.name,
                    f,
                    "improves" if better else ("no improvement" if f.valid else "not valid"),
                )
            )
            if better:
                improving.append((child, f))
        if not improving:
            break
        cur_struct, current = min(improving, key=lambda cf: cf[1].rmse_valid)
        best = current
    return HeatDemandSearch(best, tuple(tree))
