"""The building's size from its data, for the scale of the search's parameters.

The naming convention's defaults and bounds (:mod:`jaxbox.models`) suit a building whose
heat-loss coefficient is up to :data:`~jaxbox.models.REFERENCE_HLC`: an office block or a school
of ten times that has capacities beyond their bounds and is searched from guesses a decade off.
:func:`building_scale` sizes the building by its measured heat input per kelvin of zone-ambient
difference (the ratio of their means: an HLC that leaves out the sun and the unmeasured gains,
close enough for a scale), and the structure search builds every structure for a building that
many times the reference (:attr:`jaxbox.models.Grammar.scale`). Since resistances, capacities,
constant heat inputs and apertures scale together, the same temperatures with every heat input
``k`` times as large give the same search in the fit's own coordinates, and the parameters ``k``
times (resistances divided), as long as both buildings are above the reference.
:func:`sized_model` sizes any model the same way (a library model named on the command line).
"""

from __future__ import annotations

import numpy as np

from ..models import REFERENCE_HLC, Grammar, ModelError, RCModel

__all__ = ["building_scale", "data_scale", "sized_model", "MIN_EXCESS"]

#: The least mean zone-ambient difference [K] that sizes a building; below it (a record near
#: the outdoor temperature) the scale stays 1.
MIN_EXCESS = 1.0


def building_scale(data, grammar: Grammar) -> float:
    """The building's size against :data:`~jaxbox.models.REFERENCE_HLC`, at least 1.

    ``max(1, H / REFERENCE_HLC)`` with ``H`` [W/K] the mean measured heat input (the
    grammar's heating columns, and ``P_ele`` where it has one) over the mean difference of the
    zones' mean temperature and ``T_amb``, over the samples where every one of those columns
    is measured. 1 where the record has no heat input, the zones are within
    :data:`MIN_EXCESS` of the outdoor air on average, or heat and difference differ in sign.
    """
    heat = [col for _, col in grammar.heating] + (["P_ele"] if grammar.electric else [])
    zones = ["T_zon" if z == 0 else f"T_zon{z}" for z in grammar.zones]
    cols = [c for c in (*heat, *zones, "T_amb") if c in data.columns]
    if not heat or len(cols) != len(heat) + len(zones) + 1:
        return 1.0
    x = data.array(cols)
    x = x[np.all(np.isfinite(x), axis=1)]
    if not len(x):
        return 1.0
    q = float(np.mean(x[:, : len(heat)].sum(axis=1)))
    excess = float(np.mean(x[:, len(heat) : -1].mean(axis=1) - x[:, -1]))
    if abs(excess) < MIN_EXCESS or q * excess <= 0.0:
        return 1.0
    return max(1.0, q / excess / REFERENCE_HLC)


def data_scale(data) -> float:
    """:func:`building_scale` of ``data`` with the grammar its columns give (1 where they give
    none: no ``T_amb`` or zone temperature)."""
    try:
        grammar = Grammar.from_columns([str(c) for c in data.columns])
    except ModelError:
        return 1.0
    return building_scale(data, grammar)


def sized_model(model: RCModel, data) -> RCModel:
    """``model`` built for the building of the identification data ``data`` as the structure
    search builds its structures: :meth:`~jaxbox.models.RCModel.scaled` by
    :func:`data_scale` where the building is larger than the reference, else ``model``."""
    s = data_scale(data)
    return model if s <= 1.0 else model.scaled(s)
