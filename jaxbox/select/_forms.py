"""Which form of the model the data determine: the temperature form (the zone temperature
predicted from the heating), the heat-demand form (the heating from the zone temperature) or
the steady state.

Free-floating or excited data (PRBS, setbacks) determine the temperature form, and the
structure search judges nothing else. A zone held by its thermostat (:func:`held_zone`) gives
the temperature form nothing to predict: its information is in the heating. There the search
also grows the heat-demand form (:func:`~jaxbox.select._heat_demand.heat_demand_search`), and
the form accepted is the one whose validation RMSE is the smaller part of its output's spread
(the heating's std, the zone temperature's std), among valid models. When neither determines
its dynamics (a co-heating test: the zone constant for weeks), the steady state is what the data
determine (:func:`~jaxbox.select._steady.steady_fit`): a valid model of the HLC and the solar
aperture, its dynamics reported as undetermined.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._heat_demand import HeatDemandSearch, Problem, heat_demand_search, held_zone
from ._steady import steady_fit

__all__ = ["FormChoice", "choose_form", "FORMS"]

#: the forms a search may accept
FORMS = ("temperature", "heat demand", "steady state")


@dataclasses.dataclass(frozen=True)
class FormChoice:
    """The form accepted and why.

    Attributes:
        form: one of :data:`FORMS`.
        why: the reason in words.
        held: the held-zone test in words ("" when not run).
        model: the accepted :class:`~jaxbox.select._heat_demand.HeatDemandFit` or
            :class:`~jaxbox.select._steady.SteadyFit` (``None`` for the temperature form).
        heat_demand: the heat-demand candidates (``None`` when not grown).
        steady: the steady-state fit of a held zone (``None`` when not held), whichever form
            is accepted: a check on the HLC.
    """

    form: str = "temperature"
    why: str = ""
    held: str = ""
    model: object = None
    heat_demand: HeatDemandSearch | None = None
    steady: object = None

    def to_dict(self) -> dict:
        """JSON-ready: ``form``, ``form_why``, ``held``, ``form_model``, ``steady``."""
        return {
            "form": self.form,
            "form_why": self.why,
            "held": self.held,
            "form_model": None if self.model is None else self.model.to_dict(),
            "steady": None if self.steady is None else self.steady.to_dict(),
        }


def _dynamic(fit) -> bool:
    """Whether a heat-demand fit determines a capacity (one not fixed where it vanishes)."""
    return any(n.startswith("C_") and n not in fit.fixed for n in fit.params)


def choose_form(
    gb, grammar, accepted, relative_rmse, *, starts: int = 4, seed=0, max_depth=3, say=None
):
    """The form of the model the data in ``gb`` determine (see the module).

    Args:
        gb: the GreyBox searched.
        grammar: its grammar (one zone with a heating column: else the temperature form).
        accepted: the temperature form's accepted case, or ``None``.
        relative_rmse: the accepted case's validation RMSE over the zone temperature's std.
        starts, seed: of the heat-demand fits.
        max_depth: most components the heat-demand form adds to its root.
        say: progress.

    Returns:
        :class:`FormChoice`.
    """
    say = say or (lambda _t: None)
    if len(grammar.zones) != 1 or not grammar.heating:
        return FormChoice()
    zone = "T_zon" if "T_zon" in gb.data.columns else f"T_zon{grammar.zones[0]}"
    heating = grammar.heating[0][1]
    held, text = held_zone(gb.ident, zone, heating)
    if not held:
        return FormChoice(held=text)
    say(f"the zone is {text}: the heat-demand form too")
    try:  # another form that cannot be posed is a note, never the end of the search
        problem = Problem(gb.data, gb.train, gb.valid_period, zone, heating)
        hd = heat_demand_search(
            grammar,
            problem,
            starts=min(int(starts), 4),
            seed=seed or 0,
            max_depth=max_depth,
            say=say,
        )
        steady = steady_fit(gb.data, zone, heating)  # cheap: always, as a check on the HLC
    except (ValueError, KeyError, np.linalg.LinAlgError, FloatingPointError) as err:
        say(f"  the heat-demand and steady-state forms could not be posed: {err}")
        return FormChoice(held=f"{text}; the other forms could not be posed: {err}")
    best = hd.best
    rel_t = relative_rmse if accepted is not None else math.inf
    temp = (
        f"the temperature form's {accepted.model.name}: RMSE {rel_t:.3g} of the zone "
        "temperature's std"
        if accepted is not None
        else "no temperature form is valid"
    )
    if best is not None and _dynamic(best) and best.relative < rel_t:
        why = (
            f"zone {text}; the heat-demand form's {best.structure}: heating RMSE "
            f"{best.relative:.3g} of its std, against {temp}"
        )
        return FormChoice("heat demand", why, text, best, hd, steady)
    if accepted is not None:
        extra = (
            f"the heat-demand form's {best.structure}: heating RMSE {best.relative:.3g} of its std"
            if best is not None
            else "no heat-demand form is valid"
        )
        why = f"zone {text}; {temp}, against {extra}"
        return FormChoice("temperature", why, text, None, hd, steady)
    if steady.valid:
        why = (
            f"zone {text}; neither the temperature form nor the heat-demand form determines "
            f"the dynamics: the steady state on {steady.days} daily means"
        )
        return FormChoice("steady state", why, text, steady, hd, steady)
    if best is not None:
        why = f"zone {text}; the heat-demand form's {best.structure} (the steady state: " + (
            "; ".join(steady.reasons) + ")"
        )
        return FormChoice("heat demand", why, text, best, hd, steady)
    return FormChoice("temperature", f"zone {text}; no form is valid", text, None, hd, steady)
