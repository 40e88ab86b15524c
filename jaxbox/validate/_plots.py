"""The plots a modeller reads to validate a fit, each a :class:`matplotlib.figure.Figure`.

Figures are created with ``matplotlib.figure.Figure`` (no pyplot global state), so they work
headless, in notebooks (a Figure displays itself) and in reports (``fig.savefig(path)``).

* :func:`plot_fit` — measured and simulated outputs on identification and validation data, the
  inputs below;
* :func:`plot_residuals` — residuals over time;
* :func:`plot_residuals_vs_inputs` — residuals against each input (scatter);
* :func:`plot_autocorrelation` — residual autocorrelation with its band and the cumulated
  periodogram with its Kolmogorov–Smirnov band;
* :func:`plot_cross_correlation` — residual–input cross-correlations with their band;
* :func:`plot_confidence_intervals` — normalised confidence intervals (bar chart);
* :func:`plot_multistart` — cost against parameter values of every start's local optimum;
* :func:`plot_prediction` — k-step-ahead prediction error against the horizon, with the
  simulation error.
"""

from __future__ import annotations

import numpy as np

from ._verdict import MAX_REL_CI

__all__ = [
    "plot_fit",
    "plot_residuals",
    "plot_residuals_vs_inputs",
    "plot_autocorrelation",
    "plot_cross_correlation",
    "plot_confidence_intervals",
    "plot_multistart",
    "plot_prediction",
]

_MEASURED = "0.15"
_AUTO = "tab:blue"
_CROSS = "tab:orange"
_BAD = "tab:red"

_UNIT_GROUPS = (
    ("T_", "temperature [°C]"),
    ("Q_", "power [W]"),
    ("P_", "power [W]"),
    ("I_", "irradiance [W/m²]"),
)


def _figure(rows: int, cols: int = 1, *, width: float = 10.0, height: float = 2.4, **kw):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, max(2.5, height * rows)), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False, **kw)
    return fig, axes


def _times(index) -> np.ndarray:
    return np.asarray(index.to_numpy() if hasattr(index, "to_numpy") else index)


def _group_inputs(names):
    groups: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        label = next((lab for p, lab in _UNIT_GROUPS if n.startswith(p)), "other")
        groups.setdefault(label, []).append(i)
    return list(groups.items())


def _required(obj, cls: type, what: str, first: str):
    """``obj`` when it is a ``cls``; a ``TypeError`` naming ``what`` and the call ``first`` that
    makes one otherwise."""
    if isinstance(obj, cls):
        return obj
    a = "an" if cls.__name__[0] in "AEIOU" else "a"
    raise TypeError(
        f"{what} must be {a} {cls.__name__}, got {type(obj).__name__}; use {first} first"
    )


def _validation(obj):
    """``obj`` when it is a :class:`~jaxbox.validate.Validation`; a ``TypeError`` otherwise."""
    from ._postsim import Validation

    return _required(obj, Validation, "validation", "validate(result, valid)")


def _shown_inputs(v, inputs) -> list[str]:
    """The inputs of ``v`` to draw: all by default, else ``inputs`` (one name or several),
    each checked to be an input of the model."""
    names = list(v.inputs)
    if inputs is None:
        return names
    wanted = [inputs] if isinstance(inputs, str) else list(inputs)
    unknown = [n for n in wanted if n not in names]
    if unknown:
        raise ValueError(
            f"inputs {', '.join(map(repr, unknown))} are not inputs of {v.model}; its inputs: "
            f"{', '.join(names)}"
        )
    return wanted


def _analysis(obj, which="auto"):
    """A ResidualAnalysis from itself or from a Validation."""
    if hasattr(obj, "outputs") and hasattr(obj, "alpha") and hasattr(obj, "white"):
        return obj
    if hasattr(obj, "residual_analysis"):
        return obj.residual_analysis(which)
    raise TypeError(
        f"expected a ResidualAnalysis or a Validation, got {type(obj).__name__}; "
        "use validate(result, valid) first"
    )


def plot_fit(validation, *, inputs=None, title: str | None = None):
    """Measured vs simulated outputs (identification and validation data), inputs below.

    Args:
        validation: a :class:`~jaxbox.validate.Validation`.
        inputs: input names to show (default: every model input), grouped by unit.
        title: figure title (default: model name and errors).
    """
    v = _validation(validation)
    names_in = list(v.inputs)
    show = [names_in.index(n) for n in _shown_inputs(v, inputs)]
    groups = _group_inputs([names_in[i] for i in show]) if v.u_auto is not None else []
    groups = [(label, [show[i] for i in idx]) for label, idx in groups]
    rows = len(v.outputs) + len(groups)
    fig, axes = _figure(rows, 1, height=2.3, sharex=True)
    axes = axes[:, 0]
    ta = _times(v.index_auto)
    tc = _times(v.index_cross) if v.y_cross is not None else None
    for j, name in enumerate(v.outputs):
        ax = axes[j]
        ax.plot(ta, v.y_auto[:, j], color=_MEASURED, lw=0.9, label=f"{name} measured")
        ax.plot(ta, v.sim_auto[:, j], color=_AUTO, lw=1.1, label="simulated (identification)")
        if tc is not None:
            ax.plot(tc, v.y_cross[:, j], color=_MEASURED, lw=0.9)
            ax.plot(tc, v.sim_cross[:, j], color=_CROSS, lw=1.1, label="simulated (validation)")
            ax.axvspan(tc[0], tc[-1], color=_CROSS, alpha=0.06, lw=0)
        ax.set_ylabel(f"{name} [°C]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small", ncols=3)
    for ax, (label, idx) in zip(axes[len(v.outputs) :], groups, strict=True):
        for i in idx:
            series = v.u_auto[:, i]
            t = ta
            if tc is not None and v.u_cross is not None:
                series = np.concatenate([series, v.u_cross[:, i]])
                t = np.concatenate([ta, tc])
            ax.plot(t, series, lw=0.8, label=names_in[i])
        if tc is not None:
            ax.axvspan(tc[0], tc[-1], color=_CROSS, alpha=0.06, lw=0)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small", ncols=min(4, len(idx)))
    axes[-1].set_xlabel("time")
    if title is None:
        title = f"{v.model}: SE identification {v.se_auto:.3g} K"
        if v.se_cross is not None:
            title += f", validation {v.se_cross:.3g} K"
    fig.suptitle(title)
    return fig


def plot_residuals(validation, *, title: str | None = None):
    """Residuals (measured − simulated) over time, identification and validation data (the
    dashed band ±2 σ of the measured identification residuals; output gaps left out)."""
    v = _validation(validation)
    fig, axes = _figure(len(v.outputs), 1, height=2.4, sharex=True)
    axes = axes[:, 0]
    ta = _times(v.index_auto)
    ea = v.residuals_auto
    ec = v.residuals_cross
    for j, name in enumerate(v.outputs):
        ax = axes[j]
        ax.plot(ta, ea[:, j], color=_AUTO, lw=0.8, label="identification")
        if ec is not None:
            ax.plot(_times(v.index_cross), ec[:, j], color=_CROSS, lw=0.8, label="validation")
        seen = np.isfinite(ea[:, j])
        s = float(np.std(ea[seen, j])) if seen.any() else 0.0
        for level in (-2 * s, 2 * s):
            ax.axhline(level, color="0.5", lw=0.6, ls="--")
        ax.axhline(0.0, color="0.2", lw=0.6)
        ax.set_ylabel(f"{name} residual [K]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small", ncols=2)
    axes[-1].set_xlabel("time")
    fig.suptitle(title or f"{v.model}: residuals (dashed: ±2 σ on identification data)")
    return fig


def plot_residuals_vs_inputs(validation, *, which: str = "both", title: str | None = None):
    """Residuals against each input (one panel per output and input).

    Args:
        validation: a :class:`~jaxbox.validate.Validation`.
        which: ``"auto"``, ``"cross"`` or ``"both"`` periods.
    """
    v = _validation(validation)
    if which not in ("auto", "cross", "both"):
        raise ValueError(f"which must be 'auto', 'cross' or 'both', got {which!r}")
    if which == "cross" and v.residuals_cross is None:
        raise ValueError(
            "no data for which='cross': this Validation holds no validation data; call "
            "validate(result, valid) with validation data"
        )
    if v.u_auto is None or not v.inputs:
        raise ValueError("this Validation holds no inputs; recompute it with validate()")
    periods = []
    if which in ("auto", "both"):
        periods.append(("identification", v.residuals_auto, v.u_auto, _AUTO))
    if which in ("cross", "both") and v.residuals_cross is not None:
        periods.append(("validation", v.residuals_cross, v.u_cross, _CROSS))
    if not periods:
        raise ValueError(f"no data for which={which!r}")
    m = len(v.inputs)
    fig, axes = _figure(len(v.outputs), m, width=min(3.6 * m, 16.0), height=3.0)
    for j, out in enumerate(v.outputs):
        for i, name in enumerate(v.inputs):
            ax = axes[j, i]
            for label, e, u, color in periods:
                ax.scatter(u[:, i], e[:, j], s=4, alpha=0.5, color=color, label=label)
            ax.axhline(0.0, color="0.2", lw=0.6)
            ax.set_xlabel(name)
            if i == 0:
                ax.set_ylabel(f"{out} residual [K]")
            ax.grid(True, alpha=0.3)
    axes[0, -1].legend(loc="upper right", fontsize="small", markerscale=3)
    fig.suptitle(title or f"{v.model}: residuals against inputs")
    return fig


def plot_autocorrelation(analysis, *, title: str | None = None):
    """Residual autocorrelation with its white-noise band, and the cumulated periodogram.

    Args:
        analysis: a :class:`~jaxbox.validate.ResidualAnalysis`, or a
            :class:`~jaxbox.validate.Validation` (its identification residuals).
    """
    a = _analysis(analysis)
    fig, axes = _figure(len(a.outputs), 2, width=11.0, height=3.0)
    pct = round(100 * (1 - a.alpha))
    for j, o in enumerate(a.outputs):
        ax = axes[j, 0]
        lags = o.lags[1:]
        r = o.acf[1:]
        outside = np.abs(r) > o.band
        ax.vlines(lags, 0, r, color=np.where(outside, _BAD, _AUTO), lw=1.5)
        ax.plot(lags, r, "o", ms=2.5, color=_AUTO)
        ax.axhspan(-o.band, o.band, color="0.5", alpha=0.2, lw=0, label=f"{pct} % band")
        ax.axhline(0.0, color="0.2", lw=0.6)
        ax.set_xlabel("lag [samples]")
        ax.set_ylabel(f"{o.name}: autocorrelation")
        ax.set_title(
            f"Ljung–Box ({o.ljung_box.lags} lags) p = {o.ljung_box.p_value:.2g}"
            + (" — white" if o.ljung_box.white else " — not white"),
            fontsize="medium",
        )
        ax.legend(loc="upper right", fontsize="small")
        ax.grid(True, alpha=0.3)
        ax = axes[j, 1]
        p = o.periodogram
        f = p.frequency
        ax.plot(f, p.cumulated, color=_AUTO, lw=1.2, label="cumulated periodogram")
        line = p.expected
        ax.plot(f, line, color="0.2", lw=0.8, label="white noise")
        if np.isfinite(p.critical):
            ax.fill_between(
                f,
                line - p.critical,
                line + p.critical,
                color="0.5",
                alpha=0.2,
                lw=0,
                label=f"{pct} % band",
            )
        ax.set_xlim(0, 0.5)
        ax.set_ylim(-0.05, 1.05)
        ax.set_xlabel("frequency [cycles per sample]")
        ax.set_title(
            f"cumulated periodogram p = {p.p_value:.2g}"
            + (" — white" if p.white else " — not white"),
            fontsize="medium",
        )
        ax.legend(loc="lower right", fontsize="small")
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig


def plot_cross_correlation(analysis, *, title: str | None = None):
    """Cross-correlation of the residuals with each input, with the white-noise band."""
    a = _analysis(analysis)
    if not a.inputs:
        raise ValueError("the residual analysis has no inputs; pass inputs to analyse_residuals")
    m = len(a.inputs)
    fig, axes = _figure(len(a.outputs), m, width=min(3.6 * m, 16.0), height=2.8)
    for j, o in enumerate(a.outputs):
        for i, name in enumerate(a.inputs):
            ax = axes[j, i]
            r = o.ccf[name]
            outside = np.abs(r) > o.band
            ax.vlines(o.ccf_lags, 0, r, color=np.where(outside, _BAD, _AUTO), lw=1.2)
            ax.axhspan(-o.band, o.band, color="0.5", alpha=0.2, lw=0)
            ax.axhline(0.0, color="0.2", lw=0.6)
            ax.set_xlabel(f"lag [samples] ({name} leads →)")
            if i == 0:
                ax.set_ylabel(f"{o.name} residual")
            ax.set_title(name, fontsize="medium")
            ax.grid(True, alpha=0.3)
    fig.suptitle(title or "cross-correlation of residuals with inputs")
    return fig


def plot_confidence_intervals(uncertainty, *, max_rel_ci: float | None = MAX_REL_CI, title=None):
    """Normalised confidence intervals: ± half-width as a percentage of each value, with the
    verdict's limit ``max_rel_ci`` (dashed; ``None``: none).

    Parameters that are not identifiable are marked in red without a bar; those on a poorly
    identifiable direction are drawn in red.
    """
    from ._args import check_positive
    from ._uncertainty import Uncertainty

    _required(uncertainty, Uncertainty, "uncertainty", "uncertainty(result)")
    if max_rel_ci is not None:
        max_rel_ci = check_positive(max_rel_ci, "max_rel_ci")
    u = uncertainty
    n = len(u.names)
    fig, axes = _figure(1, 1, width=8.0, height=0.45 * n + 1.6)
    ax = axes[0, 0]
    y = np.arange(n)[::-1]
    rel = 100 * np.asarray(u.rel_ci, dtype=float)
    finite = np.isfinite(rel)
    top = float(np.max(rel[finite])) if finite.any() else 1.0
    if max_rel_ci is not None:
        top = max(top, 100 * max_rel_ci)
    for k in range(n):
        color = _AUTO if u.identifiable[k] else _BAD
        if max_rel_ci is not None and finite[k] and rel[k] > 100 * max_rel_ci:
            color = _BAD
        if finite[k]:
            ax.barh(y[k], 2 * rel[k], left=-rel[k], height=0.5, color=color, alpha=0.8)
            ax.text(rel[k], y[k], f" ±{rel[k]:.3g} %", va="center", fontsize="small")
        else:
            ax.text(0, y[k], "not identifiable", va="center", ha="center", color=_BAD)
    if max_rel_ci is not None:
        for s in (-1, 1):
            ax.axvline(s * 100 * max_rel_ci, color="0.4", ls="--", lw=0.8)
    ax.axvline(0.0, color="0.2", lw=0.6)
    labels = [f"{nm} = {v:.3g} {un}" for nm, v, un in zip(u.names, u.values, u.units, strict=True)]
    ax.set_yticks(y, labels)
    ax.set_xlim(-1.25 * top, 1.25 * top)
    ax.set_xlabel(f"{round(100 * u.level)} % confidence interval [% of the value]")
    ax.grid(True, axis="x", alpha=0.3)
    fig.suptitle(title or "normalised confidence intervals")
    return fig


def _spans_decades(x, ratio: float = 20.0) -> bool:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return bool(x.size and np.all(x > 0) and x.max() / x.min() >= ratio)


def plot_multistart(view, *, title: str | None = None):
    """Final cost of every start against its parameter values, one panel per parameter.

    Args:
        view: a :class:`~jaxbox.validate.MultistartView` or a :class:`~jaxbox.fit.FitResult`.
    """
    from ._multistart import multistart_view

    if not hasattr(view, "optima"):
        view = multistart_view(view)
    p = len(view.free)
    cols = min(3, p + 1)
    rows = int(np.ceil((p + 1) / cols))
    fig, axes = _figure(rows, cols, width=4.0 * cols, height=3.0)
    flat = axes.ravel()
    best = set(view.optima[0].starts) if view.optima else set()
    at_best = np.asarray([i in best for i in range(view.n_starts)])
    ok = view.usable
    cost = view.cost
    for i, name in enumerate(view.free):
        ax = flat[i]
        x = view.final[:, i]
        ax.scatter(x[ok & ~at_best], cost[ok & ~at_best], s=14, color="0.5", label="other optima")
        ax.scatter(x[at_best], cost[at_best], s=22, color=_BAD, label="best cost", zorder=3)
        ax.set_xlabel(name)
        if view.log_scale[i] and _spans_decades(x[ok]):
            ax.set_xscale("log")
        if _spans_decades(cost[ok]):
            ax.set_yscale("log")
        ax.set_ylabel("cost [K²]")
        ax.grid(True, alpha=0.3)
    ax = flat[p]
    c = np.sort(cost[ok])
    ax.plot(np.arange(1, c.size + 1), c, "o-", ms=3, color=_AUTO)
    if _spans_decades(c):
        ax.set_yscale("log")
    ax.set_xlabel("start (sorted by cost)")
    ax.set_ylabel("cost [K²]")
    ax.set_title(f"{view.n_at_best} of {view.n_starts} at the best cost", fontsize="medium")
    ax.grid(True, alpha=0.3)
    flat[0].legend(loc="best", fontsize="small")
    for ax in flat[p + 1 :]:
        ax.set_visible(False)
    fig.suptitle(title or "local optima of the multistart")
    return fig


def plot_prediction(performance, *, title: str | None = None):
    """k-step-ahead prediction error against the horizon, with the simulation error."""
    from ._prediction import PredictionPerformance

    _required(
        performance, PredictionPerformance, "performance", "prediction_performance(result, valid)"
    )
    pf = performance
    fig, axes = _figure(1, 1, width=7.0, height=3.6)
    ax = axes[0, 0]
    hours = pf.horizons * pf.step / 3600.0
    ax.plot(hours, pf.se_auto, "o-", color=_AUTO, label="k-step, identification")
    ax.axhline(pf.sim_se_auto, color=_AUTO, ls="--", lw=1, label="simulation, identification")
    if pf.se_cross is not None:
        ax.plot(hours, pf.se_cross, "s-", color=_CROSS, label="k-step, validation")
        ax.axhline(pf.sim_se_cross, color=_CROSS, ls="--", lw=1, label="simulation, validation")
    ax.set_xlabel("prediction horizon [h]")
    ax.set_ylabel("SE = Σ q RMSE [K]")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.suptitle(title or "k-step-ahead prediction vs simulation")
    return fig
