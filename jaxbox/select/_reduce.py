"""Reduce, don't reject: the one rule that turns an invalid candidate into a smaller one.

A candidate of a structure search is often made invalid only by parameters that sit where their
component vanishes: a solar aperture or a gain at zero, a fraction at 0 or 1, a resistance at its
upper bound (the heat path cut), a capacity at its lower bound (the node merged into its
neighbour), an offset, gain or aperture whose interval spans zero (undetermined), a heater or an
internal mass whose coupling to the zone the data do not determine (merged into it), a boundary
or neighbouring zone whose coupling they do not determine (the path cut). The data then
say "this component is not there"; that is a smaller model, not a wrong one. :func:`reduction`
finds such parameters, each by one small rule (:data:`RULES`), and says what they are to be fixed
at; the search identifies the candidate again with them fixed there and judges the reduced
structure in the same step.

Where the fixed parameters are all of a component's own (a facade's aperture, an offset, the
infiltration's resistance…), the reduced structure is the grammar's smaller structure, without
that component (:attr:`Reduction.structure`); otherwise the same structure with the parameters
fixed (the zone's own aperture ``gA``, which no token carries).

Initial temperatures are no reason either. An unmeasured state whose initial temperature ends on
a bound while the outputs forget that start within :data:`FORGOTTEN_SHARE` of the
identification window is fixed at its *steady start* (one linear solve: the unmeasured states in
equilibrium with the first inputs and the measured zones); one that the outputs remember gets
bounds from the temperatures around it (as the forward selection does), and, pinned on one of
those again, is fixed there: the start closest to the data's that its neighbours allow.

A rule is a function ``(case) -> list[Fix]``; :func:`reduction` applies the rules (in tiers:
a heater or mass the data do not resolve from the zone is merged, an undetermined boundary cut,
and a fast capacity fixed at its estimate, only once nothing else is to reduce) and reduces only
when every invalidating flag is explained: it names fixed parameters only, or it is an
interval that a flat direction through them blurs (re-judged on the reduced candidate).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..models._grammar import Grammar, Structure, is_boundary_token, parse_structure
from ..validate import MAX_REL_CI

__all__ = ["Fix", "Reduction", "reduction", "RULES", "FORGOTTEN_SHARE", "steady_start"]

#: An unmeasured state whose initial temperature the outputs forget (less than
#: :data:`FORGOTTEN` K per K left) within this share of the identification window: its
#: initial temperature on a bound is no reason; it is fixed at its steady start.
FORGOTTEN_SHARE = 0.25
FORGOTTEN = 0.05
#: verdict flags that a parameter on its bound (a flat direction) can cause in the others
BLURRED = ("wide_interval", "poorly_identifiable", "not_identifiable")
#: ... and that such a reduction may clear (intervals that could not be computed)
_CLEARED = (*BLURRED, "no_intervals")
#: parameter-name prefixes of gains: apertures, fractions, sensor offsets (vanish at 0)
_GAINS = ("gA", "fra_", "Q_off")
#: resistances of a node to the zone that, undetermined, merge the node into it (the heater's,
#: the internal mass's)
_LAGS = ("R_hea", "R_int")


@dataclasses.dataclass(frozen=True)
class Fix:
    """One parameter of a reduction.

    Attributes:
        name: the parameter.
        value: the value it is fixed at (SI; °C for an initial temperature), or ``None`` when
            it stays free within :attr:`bounds`.
        kind: ``"vanishes"`` (its component vanishes there), ``"undetermined"`` (an interval
            spanning zero), ``"settled"`` (a fast node's capacity fixed at its estimate),
            ``"forgotten"`` (an initial temperature the outputs forget), ``"narrowed"`` (an
            initial temperature's bounds taken from the data) or ``"edge"`` (an initial
            temperature on a bound of those again, fixed there).
        why: in words, e.g. ``"gA → 0"``, ``"R_inf cut (→ 10 K/W)"``.
        bounds: new bounds ``(lo, hi)`` of a ``"narrowed"`` fix.
    """

    name: str
    value: float | None
    kind: str
    why: str
    bounds: tuple[float, float] | None = None


@dataclasses.dataclass(frozen=True)
class Reduction:
    """What a candidate reduces to.

    Attributes:
        fixes: the parameters fixed (or narrowed), one :class:`Fix` each.
        structure: the reduced structure: the grammar's smaller one where whole components
            vanish, else the candidate's own.
        dropped: the components removed, in words (``"window S"``, ``"Off"``).
    """

    fixes: tuple[Fix, ...]
    structure: Structure
    dropped: tuple[str, ...] = ()

    @property
    def fixed(self) -> dict[str, float]:
        """Parameter -> fixed value, of the parameters the reduced structure still has."""
        return {f.name: float(f.value) for f in self.fixes if f.value is not None}

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        return {f.name: f.bounds for f in self.fixes if f.bounds is not None}

    def problem(self, case, grammar: Grammar) -> tuple:
        """``(model, fixed, bounds)`` of the reduced candidate of ``case``: the reduced
        structure's model, ``case``'s fixed values and bounds that it still has, and this
        reduction's (a zone that takes a merged node's capacity is free again, see
        :meth:`start`)."""
        model = self.structure.build(grammar)
        params = set(model.param_names)
        merged = set(self.start(case, model))
        fixed = {k: v for k, v in case.fixed.items() if k in params and k not in merged}
        fixed |= self.fixed
        bounds = {k: v for k, v in case.bounds.items() if k in params and k not in fixed}
        return model, fixed, bounds | self.bounds

    def start(self, case, model) -> dict[str, float]:
        """Where the reduced candidate's zone capacities start [J/K]: a zone that takes the node
        of a merged heater or mass (:func:`unseen_lags`) starts from the sum of both capacities
        at ``case``'s optimum (within its bounds); ``{}`` when nothing was merged."""
        params = case.result.params
        out: dict[str, float] = {}
        for f in self.fixes:
            if not (f.kind == "undetermined" and f.name.startswith(_LAGS)):
                continue
            node = "C" + f.name[1:]
            zone = "C_zon" + f.name[len(f.name.rstrip("0123456789")) :]
            if node in model.param_names or zone not in model.param_names or node not in params:
                continue
            spec = model.parameter(zone)
            total = out.get(zone, float(params[zone])) + float(params[node])
            out[zone] = float(np.clip(total, spec.lower, spec.upper))
        return out

    def text(self, source: str) -> str:
        """``"gA → 0: Zon+Wal+Int+Ae reduced to Zon+Wal+Int+Ae (gA = 0)"``."""
        why = ", ".join(f.why for f in self.fixes)
        kept = self.structure.name
        if self.fixed:
            kept += " (" + ", ".join(f"{n} = {v:.4g}" for n, v in self.fixed.items()) + ")"
        return f"{why}: {source} reduced to {kept}"


# ---- the rules ----------------------------------------------------------------------------------


def _severe(case, kind: str | None = None) -> set[str]:
    return set(case.verdict.flagged(kind))


def _blurred(case) -> set[str]:
    """The parameters an interval flag of the verdict names (:data:`BLURRED`)."""
    return {n for kind in BLURRED for n in _severe(case, kind)}


def _step(case) -> float:
    """The identification data's sampling step [s] (the median spacing)."""
    return float(np.median(np.diff(np.asarray(case.ident.t, dtype=float))))


def vanishing(case) -> list[Fix]:
    """Parameters on the bound where their component vanishes: a gain (aperture, fraction,
    offset) at 0, a fraction at 1, a resistance at its upper bound (the path cut), a capacity at
    its lower bound (the node merged; fixed at its estimate)."""
    pos = case.result.bound_position()
    out = []
    for n in sorted(_severe(case, "at_bound")):
        spec = case.model.parameter(n)
        if spec.is_initial_state:
            continue
        lo, hi = case.result.bounds[n]
        x = pos.get(n, math.nan)
        if n.startswith(_GAINS) and x < 0.5 and lo == 0.0:
            out.append(Fix(n, 0.0, "vanishes", f"{n} → 0"))
        elif n.startswith("fra_") and x > 0.5 and hi == 1.0:
            out.append(Fix(n, 1.0, "vanishes", f"{n} → 1"))
        elif n.startswith("R_") and x > 0.5:
            out.append(Fix(n, float(hi), "vanishes", f"{n} cut (→ {hi:.4g} K/W)"))
        elif n.startswith("C_") and x < 0.5:
            v = float(case.result.params[n])
            out.append(Fix(n, v, "vanishes", f"{n} merged (→ {v:.3g} J/K)"))
    return out


def undetermined(case) -> list[Fix]:
    """Gains, apertures and offsets whose interval spans zero (an interval flag: wider than its
    value, or a combination the data do not determine): dropped, fixed at 0."""
    return [
        Fix(n, 0.0, "undetermined", f"{n} undetermined (→ 0)")
        for n in sorted(_blurred(case))
        if n.startswith(_GAINS) and not case.model.parameter(n).is_initial_state
    ]


def unseen_lags(case) -> list[Fix]:
    """A heater or an internal mass whose resistance to the zone the data do not determine and
    whose node they do not resolve from it (see :func:`_unseen_lags`): merged into the zone, the
    structure without ``Hea`` or ``Int`` (where the grammar has none, the resistance is fixed at
    its estimate)."""
    return [
        Fix(n, float(case.result.params[n]), "undetermined", f"{n} undetermined (lag unseen)")
        for n in _unseen_lags(case, _blurred(case))
    ]


def _unseen_lags(case, blurred: set[str]) -> list[str]:
    """The blurred resistances of :data:`_LAGS` whose node the data do not resolve from the zone:
    a node faster than two sampling steps whose capacity is determined (the node holds the
    zone's mass, coupled tighter than the data resolve), or a slower one whose time constant's
    interval is wider than :data:`~jaxbox.validate.MAX_REL_CI`. (A fast node whose capacity is
    blurred, or a lag the data see with R·C split aside, is :func:`settled`.)"""
    lags = sorted(n for n in blurred if n.startswith(_LAGS) and n in case.result.params)
    if not lags:
        return []
    params = {k: float(v) for k, v in case.result.params.items()}
    caps = [n.C for n in case.model.network.nodes]
    tau = own_time_constants(case.model, params)
    dt = _step(case)
    out = []
    for r in lags:
        c = "C" + r[1:]
        if c not in caps:
            continue
        node = caps.index(c)
        if tau[node] < 2.0 * dt:
            if c not in blurred:
                out.append(r)
        elif time_constant_intervals(case, params, [node]).get(node, np.inf) > MAX_REL_CI:
            out.append(r)
    return out


def uncoupled(case) -> list[Fix]:
    """Couplings to a boundary (a measured temperature such as ``T_bou``, a neighbouring zone)
    whose resistance the data do not determine: the boundary's influence is not resolved, so the
    path is cut (the resistance at its upper bound): the structure without that boundary, or,
    where the grammar has none (a held zone ``Bz``), the same structure with the path cut. The
    reduced candidate is judged on its own: where the boundary did matter, it loses."""
    names = _coupling_resistances(case.model.name)
    out = []
    for n in sorted(_blurred(case) & names):
        if n not in case.result.params or case.model.parameter(n).is_initial_state:
            continue
        hi = float(case.result.bounds[n][1])
        out.append(Fix(n, hi, "undetermined", f"{n} undetermined (coupling cut → {hi:.4g} K/W)"))
    return out


def _coupling_resistances(name: str) -> set[str]:
    """The resistances of a structure's boundaries and zone couplings (``R_bou``, ``R_adj2``…);
    empty for a model that is not a grammar structure."""
    try:
        structure = parse_structure(name)
    except ValueError:
        return set()
    out = {"R_bou"} if structure.bound_zones else set()
    for zone, word in structure.tokens:
        if word in ("Cpl", "CplC"):
            out.add("R_bou")
        elif is_boundary_token(word):
            base = word[:-1] if word.endswith("C") else word
            out.add(f"R_{base.lower()}{'' if zone <= 0 else zone}")
    return out


def settled(case) -> list[Fix]:
    """Capacities that only intervals make the case invalid for, of nodes whose lag the data see
    but not the capacity: a fast node (own time constant ``C/ΣG`` under two sampling steps), or
    a node whose time constant is determined (its 95 % interval within
    :data:`~jaxbox.validate.MAX_REL_CI`) while ``C`` is not: fixed at the estimate. None where
    every heat input is idle (:func:`~jaxbox.select._cases.idle_heat_inputs`): there every
    time constant is determined and no capacity, resistance or aperture is (only their
    ratios), and a capacity fixed at its estimate would set a scale the data leave free."""
    from ._cases import idle_heat_inputs

    blurred = _blurred(case)
    caps = sorted(n for n in blurred if n.startswith("C_"))
    if not caps or idle_heat_inputs([case]):
        return []
    params = {k: float(v) for k, v in case.result.params.items()}
    tau = own_time_constants(case.model, params)
    dt = _step(case)
    nodes = [n.C for n in case.model.network.nodes]
    fast = [c for c in caps if c in nodes and tau[nodes.index(c)] < 2.0 * dt]
    rest = [nodes.index(c) for c in caps if c in nodes and c not in fast]
    if rest:
        rel = time_constant_intervals(case, params, rest)
        fast += [nodes[i] for i in rest if rel.get(i, np.inf) <= MAX_REL_CI]
    return [
        Fix(c, params[c], "settled", f"{c} settled at {params[c]:.3g} J/K (only its lag shows)")
        for c in sorted(fast)
    ]


def initial_states(case) -> list[Fix]:
    """Initial temperatures of unmeasured states on a bound: forgotten by the outputs within
    :data:`FORGOTTEN_SHARE` of the window: fixed at the steady start; else bounds from the
    temperatures around the state; on a bound of those again: fixed on it, the start closest to
    the data's within what the neighbouring temperatures allow (the constrained optimum, judged
    without that parameter)."""
    from ..fit._guess import state_ranges

    model = case.model
    measured = {n.T0 for n in model.network.nodes if n.output is not None}
    pinned = [
        n
        for n in _severe(case, "at_bound")
        if model.parameter(n).is_initial_state and n not in measured
    ]
    if not pinned:
        return []
    params = {k: float(v) for k, v in case.result.params.items()}
    span = float(np.ptp(np.asarray(case.ident.t, dtype=float)))
    steady = steady_start(model, params, case.ident)
    ranges = state_ranges(model, case.ident)
    out = []
    for n in sorted(pinned):
        node = next((i for i, m in enumerate(model.network.nodes) if m.T0 == n), None)
        narrowed = n in ranges and tuple(case.bounds.get(n, ())) == ranges[n][::2]
        forgets = forgets_its_start(model, params, node, FORGOTTEN_SHARE * span)
        if forgets and n in steady:
            why = f"{n} forgotten (→ steady {steady[n]:.2f} °C)"
            out.append(Fix(n, steady[n], "forgotten", why))
        elif narrowed:  # the data's start within what the temperatures around it allow
            lo, hi = case.bounds[n]
            edge = lo if abs(params[n] - lo) <= abs(params[n] - hi) else hi
            out.append(Fix(n, edge, "edge", f"{n} pinned again (→ {edge:.2f} °C, its edge)"))
        elif n in ranges:
            lo, _, hi = ranges[n]
            out.append(Fix(n, None, "narrowed", f"{n} in [{lo:.2f}, {hi:.2f}] °C", bounds=(lo, hi)))
    return out


#: the rules in tiers: a reduction applies the first tier that names any parameter (a heater
#: or a mass is merged, and a capacity settled at its estimate, only once what vanishes is gone: the
#: intervals then stand); within a tier, a parameter named by an earlier rule is not named again
RULES: tuple[tuple[Callable, ...], ...] = (
    (vanishing, undetermined, initial_states),
    (unseen_lags, uncoupled),
    (settled,),
)


# ---- the reduction ------------------------------------------------------------------------------


def reduction(case, structure: Structure, grammar: Grammar) -> Reduction | None:
    """What an invalid, judged ``case`` of ``structure`` reduces to, or ``None`` when something
    else than parameters where their component vanishes makes it invalid (see the module)."""
    verdict = case.verdict
    if verdict is None or verdict.valid or case.result is None:
        return None
    fixes: dict[str, Fix] = {}
    for tier in RULES:
        for rule in tier:
            for fix in rule(case):
                fixes.setdefault(fix.name, fix)
        if fixes:
            break
    if not fixes or not _explained(verdict, set(fixes)):
        return None
    smaller, dropped = _smaller(structure, grammar, case.model, fixes)
    if smaller is not None:
        kept = set(smaller.build(grammar).param_names)
        return Reduction(
            tuple(f for f in fixes.values() if f.name in kept) + _gone(fixes, kept),
            smaller,
            dropped,
        )
    return Reduction(tuple(fixes.values()), structure)


def _gone(fixes: dict[str, Fix], kept: set[str]) -> tuple[Fix, ...]:
    """The fixes of parameters the smaller structure no longer has, as words only."""
    return tuple(
        dataclasses.replace(f, value=None, bounds=None) for n, f in fixes.items() if n not in kept
    )


def _explained(verdict, fixed: set[str]) -> bool:
    """Every invalidating flag names fixed parameters only, or is an interval (blurred by a
    flat direction through them, judged again on the reduced candidate)."""
    for flag in verdict.flags:
        if not flag.severe or flag.kind in _CLEARED:
            continue
        if not flag.parameters or not set(flag.parameters) <= fixed:
            return False
    return True


#: per component word: which vanishing kinds of its own parameters remove it
_REMOVED_BY = {
    "Ae": ("gain",),
    "Sol": ("gain",),
    "Rad": ("gain",),
    "Ele": ("gain",),
    "Off": ("gain",),
    "Inf": ("cut",),
    "Int": ("cut", "merged"),
    "Hea": ("merged",),
}


def _how(fix: Fix) -> str | None:
    """How a fix removes its component: ``gain`` (at 0), ``cut``, ``merged``, or ``None``."""
    if fix.kind not in ("vanishes", "undetermined"):
        return None
    if fix.name.startswith(_GAINS):
        return "gain" if fix.value == 0.0 else None
    if fix.name.startswith(_LAGS) and fix.kind == "undetermined":
        return "merged"
    if fix.name.startswith("R_"):
        return "cut"
    if fix.name.startswith("C_"):
        return "merged"
    return None


def _smaller(
    structure: Structure, grammar: Grammar, model, fixes: dict[str, Fix]
) -> tuple[Structure | None, tuple[str, ...]]:
    """The grammar's structure without the components whose parameters vanish, when it is one
    (it reads and builds, and has no parameter the candidate lacks); ``(None, ())`` else."""
    params = set(model.param_names)
    how = {n: h for n, f in fixes.items() if (h := _how(f)) is not None}
    if not how:
        return None, ()
    tokens, dropped = set(structure.tokens), []
    for zone, word in sorted(structure.tokens):
        owned = _owned(structure, grammar, params, zone, word)
        if owned is None:
            continue
        kinds = {how[n] for n in owned if n in how}
        where = "" if zone <= 0 else str(zone)
        if word.startswith("Win"):
            dead = [x for x in word[3:] if f"gA_{x.lower()}{where}" in how]
            if dead:
                keep = "".join(x for x in word[3:] if x not in dead)
                tokens.discard((zone, word))
                if keep:
                    tokens.add((zone, "Win" + keep))
                dropped += [f"window {x}{where}" for x in dead]
        elif is_boundary_token(word) or word in ("Cpl", "CplC"):
            if "cut" in kinds:
                tokens.discard((zone, word))
                dropped.append(word + where)
            elif "merged" in kinds and word.endswith("C"):
                tokens.discard((zone, word))
                tokens.add((zone, word[:-1]))
                dropped.append(f"capacity of {word}{where}")
        elif kinds & set(_REMOVED_BY.get(word, ())):
            tokens.discard((zone, word))
            dropped.append(word + where)
    if not dropped:
        return None, ()
    try:
        smaller = parse_structure(dataclasses.replace(structure, tokens=frozenset(tokens)).name)
        kept = set(smaller.build(grammar).param_names)
    except ValueError:  # (ModelError) the needs of the grammar: a component still needs it
        return None, ()
    if not kept <= params:
        return None, ()
    return smaller, tuple(dropped)


def _owned(structure, grammar, params: set[str], zone: int, word: str) -> set[str] | None:
    """The parameters a component brings: the structure's less those of the structure
    without it (``None`` when the grammar has no structure without it)."""
    try:
        less = dataclasses.replace(structure, tokens=structure.tokens - {(zone, word)})
        return params - set(less.build(grammar).param_names)
    except ValueError:
        return None


# ---- time constants and steady starts -----------------------------------------------------------


def own_time_constants(model, params: dict) -> np.ndarray:
    """``C_i / Σ_j G_ij`` [s] per node (``inf`` for a node with no conductance)."""
    d = -np.diagonal(model.rc_numpy(params)[0])
    with np.errstate(divide="ignore"):
        return np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), np.inf)


def time_constant_intervals(case, params: dict, nodes: list[int]) -> dict[int, float]:
    """Half-width of the 95 % interval of each node's own time constant, relative to it (delta
    method through the covariance of the free parameters, derivatives by central differences
    in the logarithm of the positive ones)."""
    from ..validate import uncertainty

    try:
        unc = uncertainty(case.result)
    except ValueError:
        return {}
    free = list(unc.free)
    cov = np.asarray(unc.cov_free, dtype=float)
    tau0 = own_time_constants(case.model, params)
    grad = np.zeros((len(nodes), len(free)))
    for k, name in enumerate(free):
        v = params[name]
        if not v > 0 or name.startswith("T_"):
            continue
        h = 1e-5
        up = own_time_constants(case.model, {**params, name: v * math.exp(h)})
        dn = own_time_constants(case.model, {**params, name: v * math.exp(-h)})
        grad[:, k] = (up[nodes] - dn[nodes]) / (2 * h * v)  # ∂τ/∂θ_k
    out = {}
    for j, i in enumerate(nodes):
        g = grad[j]
        used = g != 0
        if not np.isfinite(tau0[i]) or not used.any():
            continue
        sub = cov[np.ix_(used, used)]
        if not np.all(np.isfinite(sub)):
            continue
        std = math.sqrt(max(float(g[used] @ sub @ g[used]), 0.0))
        out[i] = unc.t_quantile * std / tau0[i]
    return out


def forgets_its_start(model, params: dict, node: int | None, after: float) -> bool:
    """Whether every output keeps less than :data:`FORGOTTEN` K per K of an error in the
    initial temperature of state ``node`` after ``after`` seconds (``C·exp(A·after)·e_node``)."""
    from scipy.linalg import expm

    if node is None or not after > 0:
        return False
    A, _, C, _ = model.state_space_numpy(params)
    if not np.all(np.isfinite(A)) or not C.shape[0]:
        return False
    return bool(np.max(np.abs((C @ expm(A * after))[:, node])) < FORGOTTEN)


def steady_start(model, params: dict, data) -> dict[str, float]:
    """Initial temperatures [°C] of the unmeasured states in equilibrium with the first inputs
    and the first measured zone temperatures: ``A_uu x_u + A_um y_0 + B_u u_0 = 0`` solved for
    ``x_u`` (one linear solve). Empty where that system is singular or a value is missing."""
    A, B, _, _ = model.state_space_numpy(params)
    nodes = list(model.network.nodes)
    meas = [i for i, n in enumerate(nodes) if n.output is not None]
    free = [i for i, n in enumerate(nodes) if n.output is None]
    if not free:
        return {}
    u0 = _first_finite(data.array(list(model.inputs)))
    y0 = _first_finite(data.array([nodes[i].output for i in meas])) if meas else np.zeros(0)
    rhs = A[np.ix_(free, meas)] @ y0 + B[free] @ u0
    try:
        x = np.linalg.solve(A[np.ix_(free, free)], -rhs)
    except np.linalg.LinAlgError:
        return {}
    if not np.all(np.isfinite(x)):
        return {}
    out = {}
    for i, v in zip(free, x, strict=True):
        spec = model.parameter(nodes[i].T0)
        out[nodes[i].T0] = float(np.clip(v, spec.lower, spec.upper))
    return out


def _first_finite(values: np.ndarray) -> np.ndarray:
    """Per column, the first finite value (0 where a column has none)."""
    values = np.asarray(values, dtype=float)
    out = np.zeros(values.shape[1])
    for j in range(values.shape[1]):
        ok = np.flatnonzero(np.isfinite(values[:, j]))
        if ok.size:
            out[j] = values[ok[0], j]
    return out
