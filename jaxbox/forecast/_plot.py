"""A forecast drawn: the measured history, the mean, the 50 % and 95 % bands, the measurements."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["plot_forecast"]


def plot_forecast(frame: pd.DataFrame, history=None, *, tail: str | pd.Timedelta = "2D"):
    """A :class:`matplotlib.figure.Figure` of a forecast (:func:`~jaxbox.forecast.forecast`):
    one panel per output with the mean, the 50 % and 95 % bands [°C], the measured values in
    the forecast's window where the frame holds them (a backtest), and the last ``tail`` of the
    measured ``history`` (a :class:`~jaxbox.data.Dataset` or DataFrame, optional) before it."""
    from matplotlib.figure import Figure

    if not isinstance(frame, pd.DataFrame) or "outputs" not in frame.attrs:
        raise TypeError(
            "plot_forecast takes the DataFrame of a forecast (result.forecast(...) or "
            f"jaxbox.forecast.forecast), got {type(frame).__name__}"
        )
    outputs = frame.attrs["outputs"]
    fig = Figure(figsize=(10.0, max(3.0, 2.8 * len(outputs))), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(outputs), 1, squeeze=False)[:, 0])
    t = frame.index.to_numpy()
    hist = None
    if history is not None:
        hist = history.frame if hasattr(history, "frame") else history
        hist = hist[hist.index > hist.index[-1] - pd.Timedelta(tail)]
    for ax, o in zip(axes, outputs, strict=True):
        if hist is not None and o in hist:
            ax.plot(hist.index.to_numpy(), hist[o].to_numpy(), color="0.15", lw=1, label="measured")
        ax.fill_between(
            t,
            frame[f"{o}_lo95"],
            frame[f"{o}_hi95"],
            color="tab:blue",
            alpha=0.18,
            lw=0,
            label="95 % band",
        )
        ax.fill_between(
            t,
            frame[f"{o}_lo50"],
            frame[f"{o}_hi50"],
            color="tab:blue",
            alpha=0.35,
            lw=0,
            label="50 % band",
        )
        ax.plot(t, frame[f"{o}_mean"], color="tab:blue", lw=1.5, label="forecast")
        if f"{o}_measured" in frame:
            ax.plot(
                t,
                frame[f"{o}_measured"],
                ".",
                color="0.15",
                ms=3,
                label="measured" if hist is None else None,
            )
        ax.axvline(
            pd.Timestamp(frame.attrs["origin"]).to_datetime64(), color="0.5", lw=0.8, ls="--"
        )
        ax.set_ylabel(f"{o} [°C]")
        ax.legend(loc="best", fontsize="small")
    axes[0].set_title(f"forecast of {frame.attrs['model']} from {frame.attrs['origin']}")
    return fig
