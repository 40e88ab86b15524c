"""The one rule for initial temperatures: from the data at the start of the window.

A measured state starts at its measurement; an unmeasured one (wall, internal mass, boundary
capacity) at the mean of the measured temperatures around it (measured neighbouring states and
boundary inputs such as ``T_amb``, ``T_bou``, followed through unmeasured neighbours).
:func:`state_ranges` gives the span of those temperatures, which the Latin hypercube samples
initial states from (instead of the wide default bounds of ``T_*0``). :func:`initial_guess`
(the fit's default guess) and the selection's naming guess both use it.
"""

from __future__ import annotations

import numpy as np

from ..models import RCModel

__all__ = ["initial_guess", "state_ranges", "state_guess", "MEASURED_MARGIN", "UNMEASURED_MARGIN"]

#: Half-width [K] of the sampling range around a measured initial temperature.
MEASURED_MARGIN = 1.0
#: Margin [K] added on both sides of the span of the temperatures around an unmeasured state.
UNMEASURED_MARGIN = 2.0


def _first_values(model: RCModel, data) -> dict[str, float]:
    """First measured sample of every temperature the model touches (outputs, T_* inputs);
    a measurement missing at the start (a gap) is taken from its first sample."""
    return data.first_values([*model.outputs, *(i for i in model.inputs if i.startswith("T_"))])


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
    default bounds. A model for data in segments (:meth:`~jaxbox.models.RCModel.segmented`)
    gets the ranges of each segment's initial states ``T_*0_s<k>`` from that segment's start.
    """
    if model.segments > 1:
        pieces = data.segments
        out = {}
        for k in range(1, model.segments + 1):
            a, b = pieces[min(k, len(pieces)) - 1]
            part = type(data)._new(data._frame.iloc[a:b], data.step)
            first = _state_ranges(model, part)
            names = model.segment_names(k)
            for node, name in zip(model.network.nodes, names, strict=True):
                if k == 1 or not node.constant:
                    out[name] = first[node.T0]
        return out
    return _state_ranges(model, data)


def _state_ranges(model: RCModel, data) -> dict[str, tuple[float, float, float]]:
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


def initial_guess(model: RCModel, data) -> dict[str, float]:
    """Default guess: naming-convention defaults, initial states from the data
    (:func:`state_guess`)."""
    guess = model.defaults()
    guess.update(state_guess(model, data))
    return guess
