"""The heat-loss coefficient of a selection with an interval that carries the model's error.

Two corrections of the white delta-method interval of :func:`~jaxbox.validate.kpis`:

**Coloured residuals.** Each model's interval rests on the HAC covariance of
:func:`~jaxbox.validate.robust_covariance` (``kpis(..., interval="hac")``).

**Structure.** A structure search ends with one accepted model, but others often fit the
validation data as well, within the search's margin, and may disagree about the HLC more than
either's interval says. :func:`hlc_interval` takes the candidates of a
:class:`~jaxbox.select.Selection` that are valid, predict the same zones, and come within
``margin`` of the accepted model's criterion (:func:`near_best`), and reports the union of
their HAC intervals around the accepted model's value.

**Offsets.** A constant heat input ``Q_off`` fits the same data as a conductance to a boundary
whose temperature changes little (a cellar, the ground behind a heavy floor); where the data
measure such a boundary and the accepted model leaves it out, a warning names it with the
conductance the offset would be, which the HLC then misses; a loss with no such column, as
one to an unmeasured boundary such as the ground, at the outdoor air's mean temperature (a
lower bound of that conductance: see :func:`_offset_readings`). The interval reaches up to the
accepted model's own moved up by that conductance: both readings of the offset fit the data.

**The record's length.** The HLC is a steady state; the data show the building's response
only over the identification record. An RC network's zone warms monotonically under a step of
heat (every node's capacity and conductance positive), so the conductance it shows after the
record's length ``T``, ``H(T) = 1 / θ(T)`` (``θ`` the zone's rise per watt after ``T``, every
other input held), bounds its steady state from above; below ``H(T)``, how much more the zone
would warm after ``T`` is the model's extrapolation, which its own interval takes on trust.
The interval reaches up to the accepted model's ``H(T)`` (:func:`record_conductance`), an
allowance that matters where the slowest time constant is not short against the record.

**Unmeasured heat.** A model without an offset explains the warmth of heat the data do not
measure (occupants, appliances) by a lower HLC: over the record the balance ``HLC · ΔT̄ =`` the
mean heat input holds, so a mean unmeasured input ``G`` [W] takes ``G / ΔT̄`` off the HLC, ``ΔT̄``
the zone's mean excess over the outdoor air. :attr:`HlcInterval.per_100_w` says how much, per
100 W, so that a user who knows the building's occupancy can move the HLC by it.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from typing import TYPE_CHECKING

import numpy as np

from . import _verdict
from ._hlc_hac import HAC

if TYPE_CHECKING:
    from ._hlc_outdoor import OutdoorHLC

__all__ = ["HlcInterval", "hlc_interval", "near_best", "record_conductance", "NEAR_BEST"]

#: what the HLC's line says where its interval is wider than the verdicts allow a parameter's
NOT_DETERMINED = "; not determined by these data: quote the interval, not the value"
#: relative criterion margin of the near-best candidates (the structure search's default margin)
NEAR_BEST = 0.02
#: criteria closer than this (relative) are of the same model (a component that vanished)
SAME = 1e-4
#: the most candidates left unjudged by the search that one call judges
MAX_JUDGED = 3
#: verdicts judged here, per case (weakly: they go with their cases)
_VERDICTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclasses.dataclass(frozen=True)
class HlcInterval:
    """The heat-loss coefficient of a selection with an interval that carries the model's error.

    Attributes:
        value: the accepted model's HLC [W/K].
        ci95: (lower, upper) [W/K] at ``level``: the union of the near-best models' intervals,
            and of the accepted model's moved up by the conductance its offset may be; from 0
            where that union reaches below 0 (with a warning: the data do not bound the HLC
            from below).
        level: confidence level.
        method: how the interval was made, in words.
        models: per near-best model (the accepted one first): ``{"model", "value", "ci95",
            "criterion"}``.
        warnings: what the interval cannot vouch for (one where the interval is wider than
            ±100 % of the value: :attr:`determined` false).
        outdoor: the accepted model's HLC referenced to the outdoor air, its measured boundaries
            as they behave in the data (:func:`~jaxbox.validate.outdoor_hlc`; ``None`` where it
            does not apply).
        zone_excess: the zone's mean excess over the outdoor air over the record, ``ΔT̄`` [K],
            where the accepted model has one zone, no offset, and the zone sits at least
            :data:`OFFSET_MIN_DIFFERENCE` above the outdoor air on average (``None`` otherwise):
            see :attr:`per_100_w`.
    """

    value: float
    ci95: tuple[float, float]
    level: float
    method: str
    models: tuple[dict, ...]
    warnings: tuple[str, ...] = ()
    outdoor: OutdoorHLC | None = None
    zone_excess: float | None = None

    @property
    def per_100_w(self) -> float | None:
        """What 100 W of mean heat input that the data do not measure (occupants, appliances)
        would add to the HLC [W/K]: ``100 / ΔT̄`` (:attr:`zone_excess`). The model explains the
        warmth of such heat by a lower HLC; ``None`` where :attr:`zone_excess` is."""
        return None if self.zone_excess is None else 100.0 / self.zone_excess

    @property
    def half_width(self) -> float:
        """Half the interval's width relative to the value (``inf`` where either is not
        finite or the value is 0)."""
        lo, hi = self.ci95
        if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(self.value)):
            return math.inf
        return 0.5 * (hi - lo) / abs(self.value) if self.value else math.inf

    @property
    def determined(self) -> bool:
        """Whether the data determine the HLC: its interval no wider than ±``MAX_REL_CI``
        (100 %) of its value, the rule the verdicts apply to every parameter."""
        return self.half_width <= _verdict.MAX_REL_CI

    def to_dict(self) -> dict:
        fin = all(math.isfinite(v) for v in self.ci95)
        return {
            "value": self.value if math.isfinite(self.value) else None,
            "unit": "W/K",
            "ci95": [float(v) for v in self.ci95] if fin else None,
            "determined": self.determined,
            "level": self.level,
            "method": self.method,
            "models": [dict(m) for m in self.models],
            "warnings": list(self.warnings),
            "outdoor": None if self.outdoor is None else self.outdoor.to_dict(),
            "zone_excess": self.zone_excess,
            "per_100_w": self.per_100_w,
        }

    def text(self) -> str:
        """One line: value, interval, method (and the warnings on lines of their own)."""
        pct = round(100 * self.level)
        lo, hi = self.ci95
        ci = f"[{lo:.4g}, {hi:.4g}]" if math.isfinite(lo) and math.isfinite(hi) else "[-]"
        lines = [
            f"heat-loss coefficient {self.value:.4g} W/K, {pct} % interval {ci} ({self.method})"
        ]
        if not self.determined:
            lines[0] += NOT_DETERMINED
        if self.outdoor is not None:
            lines.append("  " + _outdoor_text(self.outdoor.to_dict(), pct))
        if self.zone_excess is not None:
            lines.append("  " + _unmeasured_text(self.zone_excess))
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _outdoor_text(out: dict, pct: int) -> str:
    """One line of the outdoor-referenced HLC (a ``to_dict`` of :class:`OutdoorHLC`)."""
    ci = out["ci95"]
    shown = "[-]" if None in ci else f"[{ci[0]:.4g}, {ci[1]:.4g}]"
    how = ", ".join(
        f"{b} follows the zone by {v['alpha']:.2f}" for b, v in out["boundaries"].items()
    )
    return f"referenced to the outdoor air {out['value']:.4g} W/K, {pct} % interval {shown}" + (
        f" ({how})" if how else ""
    )


def _unmeasured_text(excess: float) -> str:
    """One line: what 100 W of unmeasured heat would add to the HLC (see :attr:`HlcInterval.
    per_100_w`), the zone ``excess`` [K] above the outdoor air on average."""
    return (
        f"every 100 W of heat the data do not measure (occupants, appliances) would add "
        f"{100.0 / excess:.3g} W/K: the model takes its warmth for a lower HLC (the zone "
        f"{excess:.3g} K above the outdoor air on average)"
    )


def _zone_excess(selection, case) -> float | None:
    """The zone's mean excess over the outdoor air over the selection's whole record [K] (see
    :attr:`HlcInterval.per_100_w`), for a model whose one output is a zone temperature
    (:func:`_excess_over_outdoor`; ``None`` for several outputs)."""
    outputs = case.model.outputs
    if len(outputs) != 1 or not outputs[0].startswith("T_"):
        return None
    frame = _whole_record(selection, case).frame
    return _excess_over_outdoor(frame, outputs[0], case.result.params)


def _excess_over_outdoor(frame, zone: str, names) -> float | None:
    """How far ``zone`` sits above the outdoor air on average in ``frame`` [K], for a model
    whose parameters are ``names``: ``None`` where one is an offset (which takes a constant
    unmeasured input itself), without the zone's or ``T_amb``'s column, or with the zone less
    than :data:`OFFSET_MIN_DIFFERENCE` above the outdoor air on average. The temperature form's
    :attr:`HlcInterval.zone_excess` and the heat-demand form's."""
    if any(n.startswith("Q_off") for n in names):
        return None
    if zone not in frame.columns or "T_amb" not in frame.columns:
        return None
    diff = _mean_difference(frame, zone, "T_amb")
    return diff if diff is not None and diff >= OFFSET_MIN_DIFFERENCE else None


def _criterion(selection, case) -> float:
    """The selection's criterion of ``case`` (its tree's value, else the validation SE)."""
    for node in getattr(selection, "tree", ()):
        if node.case == case.name:
            return float(node.criterion)
    return float(case.score)


def near_best(selection, margin: float = NEAR_BEST) -> list:
    """The accepted case of ``selection`` and the valid candidates of the same zones whose
    criterion is within ``margin`` of it (relative for the validation SE, ``2·margin/0.02``
    units for AIC/BIC), the accepted one first. A search judges validity lazily; a close
    candidate it left unjudged is judged here (:func:`~jaxbox.validate.check_validity`, without
    storing the verdict in the case; at most :data:`MAX_JUDGED` per call, closest first). A
    candidate whose criterion equals (within :data:`SAME`) that of one already taken is the
    same model with a component that vanished and is left out."""
    gb = selection.greybox
    acc = selection.case
    if acc is None:
        return []
    crit = getattr(selection, "criterion", "cv")
    c0 = _criterion(selection, acc)
    close = []
    for name in selection.order:
        case = gb.cases.get(name)
        if case is None or case is acc or not case.done:
            continue
        if tuple(case.model.outputs) != tuple(acc.model.outputs):
            continue
        c = _criterion(selection, case)
        if not (math.isfinite(c) and math.isfinite(c0)):
            continue
        if crit == "cv" and c <= (1.0 + margin) * c0:
            close.append((c, case))
        elif crit in ("aic", "bic") and c <= c0 + 2.0 * margin / NEAR_BEST:
            close.append((c, case))
    out = [acc]
    seen = [c0]
    judged = 0
    for c, case in sorted(close, key=lambda item: abs(item[0] - c0)):
        if any(abs(c - v) <= SAME * abs(v) for v in seen):
            continue  # a component that vanished: the same model as one already taken
        fresh = (
            getattr(case, "verdict", None) is None
            and getattr(case, "validation", None) is not None
            and case not in _VERDICTS
        )
        if fresh and judged >= MAX_JUDGED:
            continue
        judged += fresh
        if _valid(case):
            out.append(case)
            seen.append(c)
    return out


def _valid(case) -> bool:
    """Whether a candidate is valid: its verdict, or one judged now when it has none (kept
    for the next call, not in the case)."""
    if getattr(case, "verdict", None) is not None or getattr(case, "validation", None) is None:
        return bool(case.is_valid)
    if case not in _VERDICTS:
        _VERDICTS[case] = _judge(case)
    return _VERDICTS[case]


def _judge(case) -> bool:
    from ._verdict import verdict_of

    try:
        verdict = verdict_of(case.result, case.validation, **getattr(case, "data_checks", {}))
    except (ValueError, np.linalg.LinAlgError):
        return False
    return bool(verdict.valid)


def hlc_interval(
    selection, *, margin: float | None = None, level: float = 0.95
) -> HlcInterval | None:
    """The accepted model's HLC with an interval for coloured residuals and near-best structures.

    Each near-best model (:func:`near_best`) gets its HAC delta-method interval
    (:func:`~jaxbox.validate.kpis` with ``interval="hac"``); the reported interval is their
    union, around the accepted model's value, and where the accepted model's offset may be a
    conductance it leaves out (:func:`_offset_readings`: a loss, or a gain from a warmer
    measured column), the accepted model's interval moved up by the largest such conductance
    joins it (named in ``method``, and a warning).

    Args:
        selection: a :class:`~jaxbox.select.Selection` (or :class:`~jaxbox.select.Search`).
        margin: relative criterion margin of the near-best models (default: the search's own
            ``margin``, else :data:`NEAR_BEST`).
        level: confidence level.

    Returns:
        :class:`HlcInterval`, or ``None`` without an accepted model or without a heat input.
    """
    from ._kpi import kpis
    from ._uncertainty import uncertainty

    if margin is None:
        margin = float(getattr(selection, "margin", NEAR_BEST))
    cases = near_best(selection, margin)
    models = []
    warns: list[str] = []
    first_method = first_uncertainty = None
    for case in cases:
        try:
            unc = uncertainty(case.result)
            k = kpis(case.result, unc, interval="hac", level=level)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if k.hlc is None:
            continue
        if first_method is None:
            if case is not cases[0]:
                break
            first_method, first_uncertainty = k.hlc.method, unc
            warns += list(k.warnings)
        models.append(
            {
                "model": case.name,
                "value": float(k.hlc.value),
                "ci95": [float(v) for v in k.hlc.ci95],
                "criterion": _criterion(selection, case),
            }
        )
    if not models:
        return None
    los = [m["ci95"][0] for m in models]
    his = [m["ci95"][1] for m in models]
    vals = [m["value"] for m in models]
    lo = min(min(los), min(vals))
    hi = max(max(his), max(vals))
    method = first_method or HAC
    if len(models) > 1:
        method += f" + structure spread over {len(models)} near-best models"
        spread = max(vals) - min(vals)
        named = ", ".join(f"{m['model']} {m['value']:.3g}" for m in models)
        if spread > 0.2 * abs(models[0]["value"]):
            warns.append(
                f"the near-best models disagree on the HLC by {spread:.3g} W/K "
                f"({named}); the data do not settle it"
            )
    # the offset read as a conductance the model leaves out: the accepted model's interval
    # moved up by it is as consistent with the data as the interval itself
    readings = _offset_readings(selection, cases[0])
    warns += [text for _, text in readings]
    if readings:
        extra = max(h for h, _ in readings)
        hi = max(hi, models[0]["ci95"][1] + extra)
        method += f" + the offset read as a conductance the model leaves out (+{extra:.3g} W/K)"
    # the record shows the building's response up to its length: the steady state the model
    # extrapolates from it may lie anywhere up to the conductance the record itself shows
    record = record_conductance(cases[0])
    if record is not None and record[0] > hi:
        hi = record[0]
        method += (
            f" + up to the conductance the record shows ({record[0]:.3g} W/K after "
            f"{record[1] / 3600:.3g} h)"
        )
    if lo < 0:  # a heat-loss coefficient is not negative: the data leave it unbounded below
        warns.append(
            f"the interval reaches {lo:.3g} W/K, below 0: the data do not bound the HLC from "
            "below; reported from 0"
        )
        lo = 0.0
    out = HlcInterval(
        value=float(models[0]["value"]),
        ci95=(float(lo), float(hi)),
        level=float(level),
        method=method,
        models=tuple(models),
        warnings=tuple(warns),
        outdoor=_outdoor(selection, cases[0], level, first_uncertainty),
        zone_excess=_zone_excess(selection, cases[0]),
    )
    if out.determined:
        return out
    undetermined = (
        f"the interval is ±{100 * out.half_width:.0f} % of the HLC (more than "
        f"±{100 * _verdict.MAX_REL_CI:.0f} %): the data hardly determine it"
    )
    return dataclasses.replace(out, warnings=(*out.warnings, undetermined))


def record_conductance(case) -> tuple[float, float] | None:
    """``(H(T) [W/K], T [s])``: the conductance a case's model shows after the length ``T`` of
    the longest segment of its identification data, ``1 / θ(T)`` with ``θ(T)`` [K/W] the rise
    of the zone its heat input warms most, ``T`` after a step of one watt with every other input
    held: ``θ(T) = c (A⁻¹ (e^{AT} − I) b)`` over the nodes not held constant. It tends to the
    HLC as ``T`` grows and lies above it, by how far the model's response was still rising at
    the record's end. ``None`` for a model with no heat input or several, or a response that
    is not a finite rise."""
    from scipy.linalg import expm

    result = case.result
    model = result.model
    heat = _verdict._heat_inputs(model)
    if len(heat) != 1:
        return None
    params = {k: float(v) for k, v in result.params.items()}
    j = model.inputs.index(heat[0])
    G = model.steady_state_gains(params)
    if G is None:
        return None
    k = int(np.argmax(G[:, j]))  # the zone it warms most, as the HLC's own
    A, B, C, _ = model.state_space_numpy(params)
    dyn = [i for i, n in enumerate(model.network.nodes) if not n.constant]
    A, b, C = A[np.ix_(dyn, dyn)], B[dyn, j], C[:, dyn]
    t = np.asarray(result.data.t, dtype=float)
    span = max((t[stop - 1] - t[start] for start, stop in result.data.segments), default=0.0)
    if not span > 0:
        return None
    try:
        rise = C @ np.linalg.solve(A, (expm(A * span) - np.eye(len(A))) @ b)
    except np.linalg.LinAlgError:
        return None
    if not (np.isfinite(rise[k]) and rise[k] > 0):
        return None
    return 1.0 / float(rise[k]), float(span)


#: the least mean difference [K] between the zone and a boundary for which an offset is read as
#: a conductance to it (closer, the conductance is not told by the data)
OFFSET_MIN_DIFFERENCE = 1.0


def _offset_readings(selection, case) -> list[tuple[float, str]]:
    """An offset may be heat exchanged with a boundary that is measured but not in the model.

    A constant heat input ``Q_off`` and a conductance ``H`` to a boundary whose temperature
    changes little fit the same data: over the record, ``H (T_b − T_zon)`` is nearly constant
    too. Where the accepted single-zone model has an offset and the data carry a temperature
    column it does not use (a cellar, the ground, a neighbour), each such boundary on the side
    the offset's sign points to (colder for a loss, warmer for a gain, by at least
    :data:`OFFSET_MIN_DIFFERENCE` on average) is named with the conductance the offset would
    be, ``|Q_off| / |mean(T_zon − T_b)|``, which the HLC would then miss. A loss with no such
    column is named as one to an unmeasured boundary (the ground), with the conductance it
    would be at the outdoor air's mean temperature: unmeasured gains are never negative, so a
    net loss is at least that much heat lost to something the model leaves out, and a boundary
    between the outdoor air and the zone takes at least that conductance to lose it.

    Returns ``(conductance [W/K], warning)`` per reading."""
    model = case.model
    offsets = [v for n, v in case.result.params.items() if n.startswith("Q_off")]
    if not offsets or len(model.outputs) != 1:
        return []
    q = float(sum(offsets))
    frame = _whole_record(selection, case).frame
    zone = model.outputs[0]
    if zone not in frame.columns or not np.isfinite(q) or q == 0.0:
        return []
    out = []
    for col in frame.columns:
        if not col.startswith("T_") or col in model.inputs or col in (zone, "T_amb"):
            continue
        diff = _mean_difference(frame, zone, col)
        if diff is None or abs(diff) < OFFSET_MIN_DIFFERENCE or (q < 0) != (diff > 0):
            continue
        side = "below" if diff > 0 else "above"
        what = "lost to" if q < 0 else "received from"
        out.append(
            (
                abs(q / diff),
                f"the offset Q_off = {q:+.0f} W may be heat {what} {col}, measured but not in "
                f"the model ({abs(diff):.1f} K {side} the zone on average): as a conductance it "
                f"would add {abs(q / diff):.3g} W/K to the HLC; a model with {col} as a boundary "
                "tells them apart where the data do",
            )
        )
    if not out and q < 0 and "T_amb" in frame.columns:
        diff = _mean_difference(frame, zone, "T_amb")
        if diff is not None and diff >= OFFSET_MIN_DIFFERENCE:
            out.append(
                (
                    -q / diff,
                    f"the offset Q_off = {q:+.0f} W is a constant loss the model does not "
                    "explain: if it is heat lost to an unmeasured boundary that changes little "
                    f"(the ground), it would add about {-q / diff:.3g} W/K to the HLC with that "
                    "boundary at the outdoor air's mean temperature, more with it warmer",
                )
            )
    return out


def _mean_difference(frame, zone: str, col: str) -> float | None:
    """How far the zone sits above column ``col`` on average over the rows that have both
    [K] (``None`` with fewer than two such rows)."""
    both = frame[[zone, col]].dropna()
    return float((both[zone] - both[col]).mean()) if len(both) > 1 else None


def _whole_record(selection, case):
    """The selection's whole record (identification and validation data) where it has one,
    else the data the case was fitted to."""
    whole = getattr(getattr(selection, "greybox", None), "data", None)
    return whole if whole is not None and hasattr(whole, "frame") else case.result.data


def _outdoor(selection, case, level: float, unc):
    """The accepted case's outdoor-referenced HLC (``unc`` its uncertainty, computed once for
    both HLCs), the boundaries read from the whole record (identification and validation data)
    where the selection has both."""
    from ._hlc_outdoor import outdoor_hlc

    data = _whole_record(selection, case)
    try:
        return outdoor_hlc(case.result, unc, data=data, interval="hac", level=level)
    except (ValueError, KeyError, TypeError, np.linalg.LinAlgError):  # an extra, never the end
        return None
