"""Quick-look plot of a dataset: one stacked axes per unit (°C, W, W/m², other)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pandas as pd

from ._signals import signal_unit

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_dataset"]

_GROUPS = (("°C", "temperature [°C]"), ("W", "power [W]"), ("W/m²", "irradiance [W/m²]"))


def plot_dataset(frame: pd.DataFrame, names: list[str], ax: Axes | None = None) -> Figure:
    """Plot columns ``names`` of ``frame`` against its time index.

    Without ``ax`` a new :class:`matplotlib.figure.Figure` (no pyplot state) holds one axes per
    unit group; with ``ax`` all columns go on that axes and its figure is returned.
    """
    from matplotlib.figure import Figure

    if ax is not None:
        for name in names:
            ax.plot(frame.index, frame[name].to_numpy(), label=name, lw=0.8)
        ax.legend(loc="upper right", fontsize="small")
        ax.set_xlabel("time")
        return ax.figure  # type: ignore[return-value]

    groups: list[tuple[str, list[str]]] = []
    for unit, label in _GROUPS:
        members = [name for name in names if signal_unit(name) == unit]
        if members:
            groups.append((label, members))
    rest = [name for name in names if signal_unit(name) not in {unit for unit, _ in _GROUPS}]
    if rest:
        groups.append(("other", rest))
    if not groups:
        groups.append(("", []))

    figure = Figure(figsize=(10, 2.6 * len(groups)), layout="constrained")
    axes = figure.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    for axis, (label, members) in zip(axes, groups, strict=True):
        for name in members:
            axis.plot(frame.index, frame[name].to_numpy(), label=name, lw=0.8)
        axis.set_ylabel(label)
        if members:
            axis.legend(loc="upper right", fontsize="small", ncols=min(len(members), 4))
        axis.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time")
    return figure
