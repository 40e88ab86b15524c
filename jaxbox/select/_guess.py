"""Initial guesses for a case: naming convention, parent case, manual, Latin hypercube.

Every strategy returns a :class:`Guess`: a value for every model parameter (SI) and where it came
from. Initial temperatures always come from the data (:func:`state_guess`): a measured state starts
at its measurement at the start of the identification slice, an unmeasured one (wall, internal
mass, boundary capacity) between the temperatures it is connected to. :func:`state_ranges` gives
the span of those temperatures, which the Latin hypercube samples initial states from (instead of
the wide default bounds of ``T_*0``) and which a retry uses to narrow the bounds of an initial
state that ended on its bound.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from ..fit import initial_guess, latin_hypercube, make_problem
from ..models import RCModel

__all__ = [
    "Guess",
    "naming_guess",
    "parent_guess",
    "manual_guess",
    "state_guess",
    "state_ranges",
    "lhs_starts",
]

#: Half-width [K] of the sampling range around a measured initial temperature.
MEASURED_MARGIN = 1.0
#: Margin [K] added on both sides of the span of the temperatures around an unmeasured state.
UNMEASURED_MARGIN = 2.0


@dataclasses.dataclass(frozen=True)
class Guess:
    """An initial guess for every model parameter.

    Attributes:
        values: parameter name -> value (SI: K/W, J/K, m², -, °C).
        source: ``"naming"``, ``"parent"``, ``"manual"`` or ``"lhs"``.
        parent: name of the parent case for ``"parent"``.
        inherited: parameters whose value came from the parent.
    """

    values: dict
    source: str
    parent: str | None = None
    inherited: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {
            "values": dict(self.values),
            "source": self.source,
            "parent": self.parent,
            "inherited": list(self.inherited),
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> Guess:
        return cls(
            values={k: float(v) for k, v in d["values"].items()},
            source=str(d["source"]),
            parent=d.get("parent"),
            inherited=tuple(d.get("inherited", ())),
        )


def _first_values(model: RCModel, data) -> dict[str, float]:
    """First sample of every measured temperature the model touches (outputs, T_* inputs)."""
    out = {}
    for name in (*model.outputs, *(i for i in model.inputs if i.startswith("T_"))):
        if name in data.columns:
            out[name] = float(data.array([name])[0, 0])
    return out


def _neighbours(model: RCModel, node: str) -> list[str]:
    out = []
    for e in model.network.edges:
        if e.a == node:
            out.append(e.b)
        elif e.b == node:
            out.append(e.a)
    return out


def state_ranges(model: RCModel, data) -> dict[str, tuple[float, float, float]]:
    """Data-derived (low, guess, high) [°C] per initial-state parameter ``T_*0``.

    A measured state: its first measurement ± :data:`MEASURED_MARGIN`. An unmeasured state: the
    span of the temperatures around it (measured neighbouring states and boundary inputs such as
    ``T_amb``, ``T_bou``, followed through unmeasured neighbours) at the start of ``data``,
    widened by :data:`UNMEASURED_MARGIN`; its guess is their mean. Clipped to the parameter's
    default bounds.
    """
    first = _first_values(model, data)
    nodes = {n.name: n for n in model.network.nodes}
    measured = {n.name: first[n.output] for n in nodes.values() if n.output in first}
    out = {}
    for node in nodes.values():
        spec = model.parameter(node.T0)
        if node.name in measured:
            v = measured[node.name]
            lo, g, hi = v - MEASURED_MARGIN, v, v + MEASURED_MARGIN
        else:
            around, seen, todo = [], {node.name}, [node.name]
            while todo:  # breadth-first through unmeasured neighbours
                for b in _neighbours(model, todo.pop(0)):
                    if b in seen:
                        continue
                    seen.add(b)
                    if b in measured:
                        around.append(measured[b])
                    elif b in first:
                        around.append(first[b])
                    elif b in nodes:
                        todo.append(b)
            if not around:
                around = list(measured.values()) or [spec.default]
            g = float(np.mean(around))
            lo, hi = min(around) - UNMEASURED_MARGIN, max(around) + UNMEASURED_MARGIN
        lo, hi = max(lo, spec.lower), min(hi, spec.upper)
        if not lo < hi:
            lo, hi = spec.lower, spec.upper
        out[node.T0] = (float(lo), float(np.clip(g, lo, hi)), float(hi))
    return out


def state_guess(model: RCModel, data) -> dict[str, float]:
    """Initial temperatures [°C] from the data (the middle of :func:`state_ranges`)."""
    return {k: g for k, (_, g, _) in state_ranges(model, data).items()}


def naming_guess(model: RCModel, data) -> Guess:
    """Defaults per naming prefix (:func:`jaxbox.fit.initial_guess`), initial states from data."""
    values = initial_guess(model, data)
    values.update(state_guess(model, data))
    return Guess({n: float(values[n]) for n in model.param_names}, "naming")


def parent_guess(model: RCModel, data, parent_params: Mapping[str, float], parent: str) -> Guess:
    """Same-named parameters take the parent's optimum, new ones their naming defaults.

    Initial temperatures of states the parent also has are inherited too; values outside the
    child's bounds are clipped into them.
    """
    base = naming_guess(model, data).values
    inherited = []
    for n in model.param_names:
        if n in parent_params and np.isfinite(parent_params[n]):
            spec = model.parameter(n)
            base[n] = float(np.clip(float(parent_params[n]), spec.lower, spec.upper))
            inherited.append(n)
    return Guess(base, "parent", parent=parent, inherited=tuple(inherited))


def manual_guess(model: RCModel, data, values: Mapping[str, float]) -> Guess:
    """Given values over the naming guess; unknown names raise ``ValueError``."""
    bad = [k for k in values if k not in model.param_names]
    if bad:
        raise ValueError(
            f"manual guess: model {model.name} has no parameter(s) {', '.join(bad)}; its "
            f"parameters are {', '.join(model.param_names)}"
        )
    base = naming_guess(model, data).values
    base.update({k: float(v) for k, v in values.items()})
    return Guess(base, "manual")


def lhs_starts(
    model: RCModel,
    data,
    guess: Mapping[str, float],
    n: int,
    *,
    free=None,
    fixed=None,
    bounds=None,
    seed: int | None = 0,
    concentration: float = 4.0,
) -> tuple[tuple[str, ...], np.ndarray]:
    """The guess plus ``n − 1`` Latin-hypercube starts [n, n_free] (physical values).

    Beta distributions around the guess within the bounds (:func:`jaxbox.fit.latin_hypercube`:
    stratified per parameter, combined at random, reproducible for a seed). Initial temperatures
    are sampled within their data-derived range (:func:`state_ranges`), intersected with their
    bounds, not over the wide default bounds.

    Returns:
        (names of the free parameters, starts [n, p]).
    """
    problem = make_problem(model, data, free=free, fixed=fixed, bounds=bounds, guess=dict(guess))
    tr = problem.transform
    g = np.asarray([problem.guess_dict[k] for k in problem.free])
    if n <= 1:
        return problem.free, g[None, :]
    ranges = state_ranges(model, data)
    lo, hi = np.array(tr.lower, dtype=float), np.array(tr.upper, dtype=float)
    for i, name in enumerate(problem.free):
        if name in ranges:
            a, _, b = ranges[name]
            a, b = max(a, lo[i]), min(b, hi[i])
            if a < g[i] < b:
                lo[i], hi[i] = a, b
    sampling = dataclasses.replace(tr, lower=lo, upper=hi)
    lhs = latin_hypercube(sampling, g, n - 1, seed, concentration)
    return problem.free, np.concatenate([g[None, :], lhs], axis=0)
