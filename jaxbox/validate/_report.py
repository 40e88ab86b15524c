"""Everything about a fit in one JSON-ready dict, and every validation plot written to files.

:func:`fit_report` gathers the estimate, the parameter uncertainty and identifiability, the
residual analysis, the validity verdict, the multistart view, the post-simulation errors and the
k-step-ahead prediction errors; :func:`save_plots` writes the figures of
:mod:`jaxbox.validate._plots`. Values that are not finite (a parameter without a standard error)
are written as ``None`` so that the dict serialises to strict JSON.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from .._io import atomic_write_bytes, remove_stale_temporaries, to_jsonable

__all__ = ["fit_report", "save_plots", "jsonable"]


def jsonable(obj):
    """A copy of ``obj`` with numpy scalars/arrays as Python values and nan/inf as ``None``."""
    return to_jsonable(obj)


def _valid_dataset(validation):
    """The validation period of a Validation as a Dataset (its inputs and outputs)."""
    if validation is None or validation.y_cross is None or validation.u_cross is None:
        return None
    from ..data import Dataset

    cols = {n: validation.u_cross[:, i] for i, n in enumerate(validation.inputs)}
    cols.update({n: validation.y_cross[:, j] for j, n in enumerate(validation.outputs)})
    return Dataset.from_arrays(validation.index_cross, cols)


def _image_format(fmt) -> str:
    """``fmt`` checked to be an image format that matplotlib writes (``png``, ``pdf``…)."""
    from matplotlib.figure import Figure

    formats = Figure().canvas.get_supported_filetypes()
    if not isinstance(fmt, str) or fmt.lower().lstrip(".") not in formats:
        raise ValueError(
            f"fmt must be an image format such as 'png', 'pdf' or 'svg' (one of "
            f"{', '.join(sorted(formats))}), got {fmt!r}"
        )
    return fmt.lower().lstrip(".")


def _plot_folder(directory) -> Path:
    """``directory`` as the folder to write the plots into: a folder (existing or not) whose
    nearest existing ancestor is a folder too. A file in the way is refused before anything is
    computed or written (``mkdir`` raised ``FileExistsError`` naming no argument)."""
    if isinstance(directory, bool) or not isinstance(directory, str | os.PathLike):
        raise TypeError(f"directory must be a folder path such as 'plots', got {directory!r}")
    out = Path(directory)
    for folder in (out, *out.parents):
        if folder.exists() or folder.is_symlink():
            if not folder.is_dir():
                where = "is" if folder == out else f"lies under {str(folder)!r}, which is"
                raise NotADirectoryError(
                    f"directory {str(out)!r} {where} a file, not a folder; give a folder for "
                    "the plots (written into it as fit.png, residuals.png…)"
                )
            break
    return out


def _write_figures(out: Path, figures: dict, fmt: str, dpi: float) -> list[Path]:
    """Each figure written to ``out/<name>.<fmt>`` atomically (rendered in memory, written to a
    temporary file, then renamed over an earlier plot of the same name)."""
    paths = [out / f"{name}.{fmt}" for name in figures]
    taken = [p.name for p in paths if p.is_dir()]
    if taken:
        raise IsADirectoryError(
            f"directory {str(out)!r} holds folders named {', '.join(taken)} where the plots go; "
            "remove them or give another folder"
        )
    out.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out)
    for path, fig in zip(paths, figures.values(), strict=True):
        buffer = io.BytesIO()
        fig.savefig(buffer, format=fmt, dpi=dpi)
        atomic_write_bytes(path, buffer.getvalue())
    return paths


def fit_report(
    result,
    valid=None,
    *,
    validation=None,
    uncertainty=None,
    include_initial_states: bool = False,
    max_rel_ci: float | None = None,
    horizons=None,
    verdict_options: dict | None = None,
) -> dict:
    """A JSON-ready report of a fit: estimate, uncertainty, residuals, verdict, errors.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        valid: validation :class:`~jaxbox.data.Dataset` directly following the identification
            data (optional; gives the cross-validation errors).
        validation: a :class:`~jaxbox.validate.Validation` already computed for ``result`` and
            ``valid`` (skips the post-simulation).
        uncertainty: an :class:`~jaxbox.validate.Uncertainty` already computed.
        include_initial_states: intervals for the initial states too.
        max_rel_ci: widest acceptable confidence interval (fraction of the value; default
            :data:`~jaxbox.validate.MAX_REL_CI`).
        horizons: k-step-ahead prediction horizons [samples] (default 1, 2, 3, 6, 12, 24).
        verdict_options: more keyword arguments of :func:`~jaxbox.validate.check_validity`.

    Returns:
        dict with ``model``, ``n_samples``, ``free``, ``cost``, ``converged``, ``params`` (per
        name: value, unit, lower, upper, free, at_bound, std, ci95, rel_ci), ``correlation``,
        ``identifiability``, ``sigma``, ``dof``, ``residuals`` (``auto`` and ``cross``
        summaries per output), ``valid``, ``reasons``, ``warnings``, ``time_constants_h``,
        ``rmse_auto``, ``rmse_cross``, ``se_auto``, ``se_cross``, ``multistart``,
        ``prediction`` and ``kpis`` (HLC, solar aperture and time constants with intervals
        for autocorrelated residuals, the HAC covariance: see :func:`~jaxbox.validate.kpis`
        with ``interval="hac"``; ``None`` without a covariance).
    """
    from ..data._args import check_mapping
    from ._args import check_dataset, check_fit
    from ._kpi import kpis
    from ._multistart import multistart_view
    from ._own import check_own
    from ._postsim import validate
    from ._prediction import prediction_performance
    from ._uncertainty import uncertainty as _uncertainty
    from ._verdict import check_validity

    result = check_fit(result)
    uncertainty, validation = check_own(result, uncertainty, validation)
    if valid is not None:
        check_dataset(valid, "valid (the validation data)")
    verdict_options = check_mapping(verdict_options, "verdict_options", "{'max_rmse': 3.0}")
    if validation is None:
        validation = validate(result, valid)
    if uncertainty is None:
        try:
            uncertainty = _uncertainty(result, include_initial_states=include_initial_states)
        except ValueError:  # no degrees of freedom: the verdict says so
            uncertainty = None
    res_auto = validation.residual_analysis("auto")
    res_cross = (
        validation.residual_analysis("cross") if validation.residuals_cross is not None else None
    )
    verdict = check_validity(
        result,
        uncertainty,
        max_rel_ci=max_rel_ci,
        residuals=res_auto,
        **{"validation": validation, **(verdict_options or {})},
    )
    ms = multistart_view(result)
    if valid is None:
        valid = _valid_dataset(validation)
    try:
        prediction = prediction_performance(result, valid, horizons=horizons).to_dict()
    except ValueError as err:  # data too short for any horizon
        prediction = {"error": str(err)}

    try:
        indicators = (
            None if uncertainty is None else kpis(result, uncertainty, interval="hac").to_dict()
        )
    except (ValueError, np.linalg.LinAlgError):  # no finite optimum, a singular model
        indicators = None
    table = result.params_table()
    unc = {} if uncertainty is None else uncertainty.table()
    params = {}
    for n, row in table.items():
        u = unc.get(n)
        params[n] = {
            "value": row["value"],
            "unit": row["unit"],
            "lower": row["lower"],
            "upper": row["upper"],
            "free": row["free"],
            "at_bound": row["at_bound"],
            "std": None if u is None else u["std"],
            "ci95": None
            if u is None or not all(map(math.isfinite, u["ci95"]))
            else list(u["ci95"]),
            "rel_ci": None if u is None else u["rel_ci"],
        }
    report = {
        "model": result.model.name,
        "n_samples": result.n_samples,
        "free": list(result.free),
        "cost": result.cost,
        "rms_error": math.sqrt(result.cost) if result.cost >= 0 else None,
        "converged": result.converged,
        "params": params,
        "correlation": {} if uncertainty is None else uncertainty.correlation_dict(),
        "identifiability": None
        if uncertainty is None
        else {
            "condition": uncertainty.condition,
            "collinearity": uncertainty.collinearity,
            "non_identifiable": [c.to_dict() for c in uncertainty.combinations],
        },
        "sigma": None if uncertainty is None else math.sqrt(uncertainty.sigma2),
        "dof": None if uncertainty is None else uncertainty.dof,
        "residuals": {
            "auto": res_auto.to_dict(),
            "cross": None if res_cross is None else res_cross.to_dict(),
        },
        "valid": verdict.valid,
        "reasons": list(verdict.reasons),
        "warnings": list(verdict.warnings),
        "time_constants_h": [float(t) / 3600.0 for t in verdict.time_constants],
        "rmse_auto": dict(validation.rmse_auto),
        "rmse_cross": None if validation.rmse_cross is None else dict(validation.rmse_cross),
        "se_auto": validation.se_auto,
        "se_cross": validation.se_cross,
        "multistart": ms.to_dict(),
        "prediction": prediction,
        "kpis": indicators,
    }
    return jsonable(report)


def save_plots(
    result,
    validation,
    directory,
    *,
    uncertainty=None,
    valid=None,
    fmt: str = "png",
    dpi: int = 110,
) -> list[Path]:
    """Write every validation plot of a fit into ``directory`` (created if needed).

    Plots of an earlier call in the same folder are replaced, each atomically (the new image or
    the old one, never half of one); other files there are left alone.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        validation: its :class:`~jaxbox.validate.Validation` (``None``: auto-validation only).
        directory: output folder.
        uncertainty: an :class:`~jaxbox.validate.Uncertainty` already computed.
        valid: the validation dataset (default: rebuilt from ``validation``), for the
            k-step-ahead prediction plot on validation data.
        fmt: image format (``png``, ``pdf``, ``svg``).
        dpi: resolution of raster formats.

    Returns:
        The paths written: ``fit``, ``residuals``, ``residuals_vs_inputs``, ``autocorrelation``,
        ``cross_correlation``, ``confidence_intervals``, ``multistart``, ``prediction`` (and
        ``autocorrelation_validation`` with validation data).

    Raises:
        NotADirectoryError: ``directory`` (or a folder above it) is a file (before anything is
            computed).
        IsADirectoryError: a folder in ``directory`` has the name of a plot (before any is
            written).
    """
    from . import _plots
    from ._args import check_dataset, check_fit, check_positive
    from ._own import check_own
    from ._postsim import validate
    from ._prediction import prediction_performance
    from ._uncertainty import uncertainty as _uncertainty

    result = check_fit(result)
    uncertainty, validation = check_own(result, uncertainty, validation)
    if valid is not None:
        check_dataset(valid, "valid (the validation data)")
    fmt = _image_format(fmt)
    dpi = check_positive(dpi, "dpi (dots per inch)")
    out = _plot_folder(directory)
    if validation is None:
        validation = validate(result, valid)
    if uncertainty is None:
        try:
            uncertainty = _uncertainty(result)
        except ValueError:  # no degrees of freedom: no interval plot
            uncertainty = None
    analysis = validation.residual_analysis("auto")
    figures = {
        "fit": _plots.plot_fit(validation),
        "residuals": _plots.plot_residuals(validation),
        "residuals_vs_inputs": _plots.plot_residuals_vs_inputs(validation),
        "autocorrelation": _plots.plot_autocorrelation(
            analysis, title=f"{result.model.name}: identification residuals"
        ),
        "cross_correlation": _plots.plot_cross_correlation(analysis),
        "multistart": _plots.plot_multistart(result),
    }
    if uncertainty is not None:
        figures["confidence_intervals"] = _plots.plot_confidence_intervals(uncertainty)
    if validation.residuals_cross is not None:
        figures["autocorrelation_validation"] = _plots.plot_autocorrelation(
            validation.residual_analysis("cross"),
            title=f"{result.model.name}: validation residuals",
        )
    if valid is None:
        valid = _valid_dataset(validation)
    try:
        figures["prediction"] = _plots.plot_prediction(prediction_performance(result, valid))
    except ValueError:
        pass
    return _write_figures(out, figures, fmt, dpi)
