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

from ..fit import (
    DEFAULT_CONCENTRATION,
    FitError,
    initial_guess,
    make_problem,
    sample_starts,
    state_guess,
    state_ranges,
)
from ..fit._problem import number
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


def naming_guess(model: RCModel, data) -> Guess:
    """Defaults per naming prefix (:func:`jaxbox.fit.initial_guess`), initial states from data."""
    values = initial_guess(model, data)
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
    for k, v in values.items():
        try:
            base[k] = number(v, f"manual guess: the value of {k}")
        except FitError as err:
            raise TypeError(str(err)) from None
        if not np.isfinite(base[k]):
            raise ValueError(f"manual guess: the value of {k} must be finite, got {v!r}")
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
    concentration: float = DEFAULT_CONCENTRATION,
) -> tuple[tuple[str, ...], np.ndarray]:
    """The guess plus ``n − 1`` Latin-hypercube starts [n, n_free] (physical values).

    The fit's own sampler (:func:`jaxbox.fit.sample_starts`), so that ``fit_model(starts=n)``
    and a case with ``n`` starts draw the same starts for the same seed and guess.

    Returns:
        (names of the free parameters, starts [n, p]).
    """
    problem = make_problem(model, data, free=free, fixed=fixed, bounds=bounds, guess=dict(guess))
    return problem.free, sample_starts(problem, data, n, seed, concentration)
