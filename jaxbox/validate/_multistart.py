"""The multistart view: how the Latin-hypercube starts spread over local optima.

The estimation problem is not convex; multistart is what makes the global optimum likely. Whether
the sample was large enough shows in how many starts reached the best cost and how many
distinct local optima the others ended in. Starts whose final costs agree within a relative
tolerance are grouped into one *optimum*; the best optimum's share of the usable starts estimates
the probability that one start finds it, from which the chance that a sample of the same size
would miss it follows.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["MultistartView", "Optimum", "multistart_view"]


@dataclasses.dataclass(frozen=True, eq=False)
class Optimum:
    """A group of starts that ended at the same cost (within the tolerance).

    Attributes:
        cost: lowest cost in the group [K²].
        count: number of starts in it.
        starts: their indices.
        params: parameters [SI] of the group's lowest-cost start, in ``free`` order.
    """

    cost: float
    count: int
    starts: tuple[int, ...]
    params: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class MultistartView:
    """Outcome of every start of a multistart fit, grouped into local optima.

    Attributes:
        free: free parameter names (columns of ``initial`` and ``final``).
        initial, final: start and end values [SI], shape [S, p].
        cost: final cost per start [K²] (``nan`` for unusable starts).
        status: status per start.
        usable: starts with a usable result.
        best: index of the best start.
        rtol: relative cost tolerance of the grouping.
        optima: local optima, best first.
        log_scale: per parameter, whether its natural scale is logarithmic (R, C).
    """

    free: tuple[str, ...]
    initial: np.ndarray
    final: np.ndarray
    cost: np.ndarray
    status: tuple[str, ...]
    usable: np.ndarray
    best: int
    rtol: float
    optima: tuple[Optimum, ...]
    log_scale: tuple[bool, ...]

    @property
    def n_starts(self) -> int:
        return len(self.status)

    @property
    def n_usable(self) -> int:
        return int(np.sum(self.usable))

    @property
    def n_at_best(self) -> int:
        """Starts that reached the best cost within ``rtol``."""
        return self.optima[0].count if self.optima else 0

    @property
    def fraction_at_best(self) -> float:
        return self.n_at_best / self.n_usable if self.n_usable else 0.0

    @property
    def miss_probability(self) -> float:
        """Chance that the same number of starts would all miss the best optimum, with the
        observed share of starts reaching it as the per-start probability. Indicative only."""
        f = self.fraction_at_best
        return float((1.0 - f) ** self.n_starts)

    def spread_at_best(self) -> dict[str, float]:
        """Per parameter: relative range (max − min)/|median| over the starts at the best cost."""
        if not self.optima:
            return {}
        idx = list(self.optima[0].starts)
        P = self.final[idx]
        med = np.median(P, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = (P.max(axis=0) - P.min(axis=0)) / np.abs(med)
        return {n: float(r) for n, r in zip(self.free, rel, strict=True)}

    def text(self) -> str:
        """One-paragraph judgement of the sample size."""
        if not self.optima:
            return "no start produced a usable result"
        n, k = self.n_starts, self.n_at_best
        parts = [
            f"{k} of {n} starts ({self.n_usable} usable) reached the best cost "
            f"{self.optima[0].cost:.6g} K² within {self.rtol:.0e} relative; "
            f"{len(self.optima)} distinct optima"
        ]
        if n == 1:
            parts.append("a single start cannot show whether the optimum is global; add starts")
        elif k == 1:
            parts.append(
                "only one start found it: the sample is too small to trust the global optimum"
            )
        elif self.miss_probability > 0.01:
            parts.append(
                f"a sample this size would miss it with probability ≈ "
                f"{self.miss_probability:.2g}: consider more starts"
            )
        else:
            parts.append("the sample is large enough to trust the global optimum")
        return "; ".join(parts)

    def to_dict(self) -> dict:
        return {
            "n_starts": self.n_starts,
            "n_usable": self.n_usable,
            "n_at_best": self.n_at_best,
            "fraction_at_best": self.fraction_at_best,
            "miss_probability": self.miss_probability,
            "optima": [
                {
                    "cost": float(o.cost),
                    "count": o.count,
                    "params": {n: float(v) for n, v in zip(self.free, o.params, strict=True)},
                }
                for o in self.optima
            ],
            "text": self.text(),
        }


def multistart_view(result, *, rtol: float = 1e-4, atol: float = 1e-12) -> MultistartView:
    """Group a fit's starts into local optima by final cost.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        rtol, atol: costs within ``max(rtol · cost, atol)`` [K²] of a group's lowest cost join it.

    Returns:
        :class:`MultistartView`.
    """
    from ._args import check_fraction

    if not hasattr(result, "starts"):
        raise TypeError(
            f"result must be a fit (the result of jaxbox.fit_model), got {type(result).__name__}"
        )
    rtol = check_fraction(rtol, "rtol (relative cost tolerance)", upper=float("inf"))
    atol = check_fraction(atol, "atol (absolute cost tolerance) [K²]", upper=float("inf"))
    st = result.starts
    cost = np.asarray(st.cost, dtype=float)
    usable = np.asarray(st.usable, dtype=bool)
    cost = np.where(usable, cost, np.nan)
    order = [int(i) for i in np.argsort(np.where(usable, cost, np.inf)) if usable[i]]
    optima: list[Optimum] = []
    group: list[int] = []
    for i in order:
        if group and cost[i] <= cost[group[0]] + max(rtol * cost[group[0]], atol):
            group.append(i)
            continue
        if group:
            optima.append(_optimum(group, cost, st.params))
        group = [i]
    if group:
        optima.append(_optimum(group, cost, st.params))
    kinds = result.problem.transform.kind_names()
    return MultistartView(
        free=tuple(result.free),
        initial=np.asarray(st.initial, dtype=float),
        final=np.asarray(st.params, dtype=float),
        cost=cost,
        status=tuple(st.status),
        usable=usable,
        best=int(result.best),
        rtol=rtol,
        optima=tuple(optima),
        log_scale=tuple(k == "log" for k in kinds),
    )


def _optimum(group, cost, params) -> Optimum:
    return Optimum(
        cost=float(cost[group[0]]),
        count=len(group),
        starts=tuple(group),
        params=np.asarray(params[group[0]], dtype=float),
    )
