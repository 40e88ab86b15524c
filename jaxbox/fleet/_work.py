"""One partition of a fleet: load, check, identify, validate and compute the KPIs of its
buildings, in batched calls; one row (and one fit document) per building.

This is the function a Dask worker runs. It never raises for one building: bad data, a fit
that fails or a model that is not valid become that building's ``status`` and ``message``.
The compiled functions stay in the worker process between partitions (and in JAX's persistent
compilation cache between processes), so only a worker's first partition of a shape compiles.
"""

from __future__ import annotations

import math
import os
import time
import warnings

import numpy as np

from ..data._plausible import STUCK_HOURS
from ._config import FleetConfig
from ._sources import Building, read_buildings

__all__ = ["process_partition", "STATUSES"]

#: the values of the ``status`` column
STATUSES = ("ok", "no_valid_model", "bad_data", "failed")
#: fewest identification samples a building needs
MIN_SAMPLES = 24
#: the parameter covariance of the KPI intervals: HAC (autocorrelated residuals), as the fit
#: documents, ``select`` and :func:`~jaxbox.validate.fit_report` give them
KPI_INTERVAL = "hac"


def _setup() -> str:
    """float64, the persistent compilation cache (unless ``JAXBOX_CACHE=0``); the worker's
    name."""
    import logging

    from .._x64 import enable_x64

    enable_x64()
    logging.getLogger("jax._src.callback").setLevel(logging.CRITICAL)
    if os.environ.get("JAXBOX_CACHE", "1").strip().lower() not in ("0", "no", "off", "false"):
        from .._cache import enable_compilation_cache

        try:
            enable_compilation_cache()
        except OSError:
            pass
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"pid:{os.getpid()}"


def _windows(data, cfg: FleetConfig):
    """(identification, validation) datasets of one building."""
    if cfg.train is not None:
        return data.slice(*cfg.train), data.slice(*cfg.valid)
    return data.split(fraction=cfg.fraction)


def _check(data, cfg: FleetConfig, models):
    """Windows of a building, checked for the model columns; raises DataError/ValueError."""
    from ..data import DataError

    ident, valid = _windows(data, cfg)
    if len(ident) < MIN_SAMPLES or len(valid) < 1:
        raise DataError(
            f"{len(ident)} identification and {len(valid)} validation samples; at least "
            f"{MIN_SAMPLES} and 1 are needed"
        )
    columns = sorted({c for m in models for c in (*m.inputs, *m.outputs)})
    data.require(columns, what=f"model {models[0].name}" if len(models) == 1 else "the models")
    for part in (ident, valid):
        part.check_plausible(columns=columns, warn=False, stuck_hours=cfg.stuck_hours)
    return ident, valid


def _rms(values: dict | None) -> float:
    """The root mean square over outputs of per-output RMSEs (the RMSE with one output)."""
    if not values:
        return math.nan
    v = np.asarray([float(x) for x in values.values()], dtype=float)
    return float(np.sqrt(np.mean(v * v)))


def _empty_row(name: str, status: str, message: str) -> dict:
    return {"building": name, "status": status, "message": message}


def _params(result, unc) -> list[dict]:
    table = {} if unc is None else unc.table()
    out = []
    for s in result.model.parameters:
        u = table.get(s.name)
        lo, hi = (math.nan, math.nan) if u is None else u["ci95"]
        out.append(
            {
                "name": s.name,
                "unit": s.unit,
                "value": float(result.params[s.name]),
                "std": math.nan if u is None else float(u["std"]),
                "ci_lo": float(lo),
                "ci_hi": float(hi),
                "free": s.name in result.free,
            }
        )
    return out


def _kpi_columns(kp) -> dict:
    """``hlc``/``solar_aperture`` [W/K, m²] with ``_std``, ``_lo``, ``_hi``; time constants [h]
    as lists; ``kpi_interval``: how the intervals were made (``None`` without KPIs)."""
    out: dict = {}
    for key in ("hlc", "solar_aperture"):
        k = None if kp is None else getattr(kp, key)
        out[key] = math.nan if k is None else k.value
        out[f"{key}_std"] = math.nan if k is None else k.std
        out[f"{key}_lo"] = math.nan if k is None else k.ci95[0]
        out[f"{key}_hi"] = math.nan if k is None else k.ci95[1]
    taus = () if kp is None else kp.time_constants
    out["tau_h"] = [t.value for t in taus]
    out["tau_std_h"] = [t.std for t in taus]
    out["tau_lo_h"] = [t.ci95[0] for t in taus]
    out["tau_hi_h"] = [t.ci95[1] for t in taus]
    out["kpi_interval"] = None if kp is None else kp.method
    return out


def _judge(
    result, valid, *, validation=None, verdict=None, fit_json: bool, stuck_hours=STUCK_HOURS
):
    """Validation, uncertainty, verdict, KPIs (and the fit document) of a fit."""
    from ..validate import check_validity, fit_report, kpis, uncertainty, validate

    t0 = time.perf_counter()
    if validation is None:
        validation = validate(result, valid, method="exact")
    try:
        unc = uncertainty(result)
    except ValueError:
        unc = None
    if verdict is None:
        verdict = check_validity(
            result,
            unc,
            check_intervals=unc is not None,
            validation=validation,
            stuck_hours=stuck_hours,
        )
    t1 = time.perf_counter()
    kp = None
    if unc is not None:
        try:
            kp = kpis(result, unc, interval=KPI_INTERVAL)
        except (ValueError, np.linalg.LinAlgError):
            kp = None
    t2 = time.perf_counter()
    doc = None
    if fit_json:
        doc = fit_report(result, valid, validation=validation, uncertainty=unc)
    t3 = time.perf_counter()
    timing = {"validate_s": t1 - t0, "kpi_s": t2 - t1, "report_s": t3 - t2}
    return validation, unc, verdict, kp, doc, timing


def _fit_row(name, result, validation, unc, verdict, kp) -> dict:
    status = "ok" if verdict.valid else "no_valid_model"
    message = "" if verdict.valid else "; ".join(verdict.reasons)
    row = _empty_row(name, status, message)
    row.update(
        model=result.model.name,
        form="temperature",
        n_train=int(result.n_samples),
        n_valid=0 if validation.y_cross is None else int(len(validation.y_cross)),
        step_s=float(result.data.step),
        params=_params(result, unc),
        cost=float(result.cost),
        converged=bool(result.converged),
        starts=int(result.starts.n),
        starts_at_best=int(result.starts.n_at_best()),
        rmse_auto=_rms(validation.rmse_auto),
        rmse_cross=_rms(validation.rmse_cross),
        valid=bool(verdict.valid),
        reasons=" | ".join(verdict.reasons),
        warnings=" | ".join(verdict.warnings),
        **_kpi_columns(kp),
    )
    return row


def _selection_hlc(row: dict, sel) -> None:
    """The HLC's interval of a selection's accepted model as ``jaxbox select`` reports it
    (:func:`jaxbox.validate.hlc_interval`: coloured residuals, the near-best structures, the
    conductance the record shows), in place of the model's own."""
    from ..validate import hlc_interval

    try:
        hi = hlc_interval(sel)
    except (ValueError, np.linalg.LinAlgError):  # no finite optimum, a singular model
        return
    if hi is None or not math.isfinite(hi.value):
        return
    row.update(hlc=float(hi.value), hlc_lo=float(hi.ci95[0]), hlc_hi=float(hi.ci95[1]))
    row["kpi_interval"] = hi.method


def _form_row(name: str, fm, ident, valid) -> dict:
    """The row of a building whose search accepted the heat-demand or the steady-state form
    (:attr:`jaxbox.select.Search.form_model`): the HLC with the interval and method ``jaxbox
    select`` reports; the error is the heating's, in ``message`` (the RMSE columns, in K, are
    the temperature form's and stay empty)."""
    from ..models._parameters import parameter_for

    row = _empty_row(name, "ok", fm.summary().splitlines()[0])
    params = []
    if fm.form == "heat demand":
        for n, v in fm.params.items():
            lo, hi = fm.intervals.get(n, (math.nan, math.nan))
            params.append(
                {
                    "name": n,
                    "unit": parameter_for(n).unit,
                    "value": float(v),
                    "std": math.nan,
                    "ci_lo": float(lo),
                    "ci_hi": float(hi),
                    "free": n not in fm.fixed,
                }
            )
        gA = fm.params.get("gA", math.nan)
        gA_ci = fm.intervals.get("gA", (math.nan, math.nan))
    else:
        dropped = "gA" in fm.dropped
        gA = math.nan if dropped else fm.gA
        gA_ci = (math.nan, math.nan) if dropped else fm.gA_interval
    lo, hi = fm.hlc_interval
    row.update(
        model=fm.structure,
        form=fm.form,
        n_train=int(len(ident)),
        n_valid=int(len(valid)),
        step_s=float(ident.step),
        params=params,
        valid=bool(fm.valid),
        reasons=" | ".join(fm.reasons),
        warnings=" | ".join(getattr(fm, "warnings", ())),
        hlc=float(fm.hlc),
        hlc_lo=float(lo),
        hlc_hi=float(hi),
        solar_aperture=float(gA),
        solar_aperture_lo=float(gA_ci[0]),
        solar_aperture_hi=float(gA_ci[1]),
        kpi_interval=fm.hlc_method,
    )
    return row


def _doc(name: str, row: dict, report: dict | None, timing: dict) -> dict:
    from .._io import to_jsonable

    doc = {"building": name, "status": row["status"], "message": row["message"]}
    if report is not None:
        doc.update(report)
    doc["timing"] = timing
    return to_jsonable(doc)


def _fixed_model(model, checked: dict, cfg: FleetConfig, fit_json: bool, out: dict) -> None:
    """Fit one model to every checked building (one batched call per data shape: records of
    neighbouring lengths are padded to one, see :func:`~jaxbox.fit.solve_jobs`); a structure
    name is built for each building's columns."""
    from ..fit import FitError, fit_batch
    from ..fit._fit import bucket_samples
    from ..models import get_model

    names = list(checked)
    extra = {} if cfg.max_steps is None else {"max_steps": cfg.max_steps}
    if cfg.continued is not None:
        extra["continued"] = cfg.continued
    if cfg.polish is not None:
        extra["polish"] = cfg.polish or None

    def request(n):
        return {
            "model": get_model(model, checked[n][0].columns),
            "data": checked[n][0],
            "starts": cfg.starts,
            "seed": cfg.seed,
            "max_gap": cfg.max_gap,
            **extra,
        }

    shapes: dict[tuple, list[str]] = {}
    for n in names:
        length = bucket_samples(len(checked[n][0]))
        shapes.setdefault((length, round(checked[n][0].step, 6)), []).append(n)
    fitted: dict[str, object] = {}
    for members in shapes.values():
        # a partition's batches are padded to its size (repeating a building; the copies are
        # dropped): every batch of a worker has one shape and reuses one compiled solve
        pad = max(0, cfg.partition_size - len(members))
        reqs = [request(n) for n in members] + [request(members[0])] * pad
        try:
            outcome = fit_batch(reqs, errors="return")[: len(members)]
        except Exception as err:  # a batch that cannot run at all: each building fails
            outcome = [FitError(f"{type(err).__name__}: {err}")] * len(members)
        for n, r in zip(members, outcome, strict=True):
            fitted[n] = r
    results = [fitted[n] for n in names]
    for name, result in zip(names, results, strict=True):
        _, valid, load_s, _ = checked[name]
        if isinstance(result, Exception):
            out[name] = (_empty_row(name, "failed", str(result)), None, {"load_s": load_s})
            continue
        batch = int(result.timing.get("batch", 1))
        timing = {
            "load_s": load_s,
            "fit_s": float(result.timing.get("fit_s", 0.0)) / max(batch, 1),
            "compile_s": float(result.timing.get("compile_s", 0.0)),
            "batch": batch,
        }
        try:
            validation, unc, verdict, kp, report, more = _judge(
                result, valid, fit_json=fit_json, stuck_hours=cfg.stuck_hours
            )
        except Exception as err:  # non-finite post-simulation and the like
            out[name] = (_empty_row(name, "failed", f"validation: {err}"), None, timing)
            continue
        timing.update(more)
        row = _fit_row(name, result, validation, unc, verdict, kp)
        out[name] = (row, report, timing)


def _selections(models, boxes, cfg: FleetConfig) -> list:
    """The structure search on each building (``models == "search"``), or the forward selection
    over ``models`` on all of them in lock-step (batched per step)."""
    from ..select import forward_selection_many, structure_search

    settings = {} if cfg.max_steps is None else {"max_steps": cfg.max_steps}
    if cfg.continued is not None:
        settings["continued"] = cfg.continued
    if cfg.polish is not None:
        settings["polish"] = cfg.polish or None
    if cfg.margin is not None:  # else each method's own default
        settings["margin"] = cfg.margin
    if models == "search":
        return [structure_search(gb, starts=cfg.starts, seed=cfg.seed, **settings) for gb in boxes]
    return forward_selection_many(
        boxes,
        [m.name for m in models],
        starts=cfg.starts,
        seed=cfg.seed,
        patience=cfg.patience,
        **settings,
    )


def _selection(models, checked: dict, cfg: FleetConfig, fit_json: bool, out: dict) -> None:
    """The selection (:func:`_selections`) on every checked building."""
    from ..select import GreyBox

    names = list(checked)
    boxes = []
    for n in names:
        ident, valid, _, data = checked[n]
        boxes.append(
            GreyBox(
                data,
                train=(str(ident.start), str(ident.end)),
                valid=(str(valid.start), str(valid.end)),
                name=n,
                max_gap=cfg.max_gap,
                stuck_hours=cfg.stuck_hours,
            )
        )
    t0 = time.perf_counter()
    try:
        selections = _selections(models, boxes, cfg)
    except Exception:
        if len(names) == 1:
            raise
        for n in names:  # one building spoils the lock-step: each on its own
            one = {n: checked[n]}
            try:
                _selection(models, one, cfg, fit_json, out)
            except Exception as err:
                out[n] = (
                    _empty_row(n, "failed", f"{type(err).__name__}: {err}"),
                    None,
                    {"load_s": checked[n][2]},
                )
        return
    share = (time.perf_counter() - t0) / len(names)
    for n, gb, sel in zip(names, boxes, selections, strict=True):
        timing = {"load_s": checked[n][2], "select_s": share, "models_fitted": len(sel.order)}
        case = sel.case
        form_model = getattr(sel, "form_model", None)
        if case is None and form_model is not None:  # the heat-demand or steady-state form
            ident, valid = checked[n][0], checked[n][1]
            report = {"selection": sel.to_dict()} if fit_json else None
            if report is not None and cfg.reports:
                from ..report import greybox_report

                report["_html"] = greybox_report(gb, sel)
            out[n] = (_form_row(n, form_model, ident, valid), report, timing)
            continue
        if case is None:
            done = [gb.cases[c] for c in sel.order if gb.cases[c].result is not None]
            if not done:
                out[n] = (
                    _empty_row(n, "failed", f"no model could be fitted: {sel.stopped}"),
                    None,
                    timing,
                )
                continue
            case = min(done, key=lambda c: c.se_cross if math.isfinite(c.se_cross) else math.inf)
        try:
            validation, unc, verdict, kp, report, more = _judge(
                case.result,
                case.valid,
                validation=case.validation,
                verdict=case.verdict,
                fit_json=fit_json,
            )
        except Exception as err:
            out[n] = (_empty_row(n, "failed", f"validation: {err}"), None, timing)
            continue
        timing.update(more)
        row = _fit_row(n, case.result, validation, unc, verdict, kp)
        if sel.case is not None:
            _selection_hlc(row, sel)
        else:
            row["status"] = "no_valid_model"
            row["message"] = f"{sel.stopped}; best attempt {case.name}: " + "; ".join(case.reasons)
        if report is not None:
            report["selection"] = sel.to_dict()
            if cfg.reports:
                from ..report import greybox_report

                report["_html"] = greybox_report(gb, sel)
        out[n] = (row, report, timing)


def process_partition(
    index: int, buildings: list[Building], config: dict, fit_json: bool = True
) -> dict:
    """Identify every building of one partition.

    Args:
        index: the partition's number (kept in the rows).
        buildings: its buildings.
        config: :meth:`FleetConfig.to_dict` of the run.
        fit_json: also build each building's fit document (:func:`jaxbox.validate.fit_report`
            with the KPIs and timings).

    Returns:
        ``{"rows": [one dict per building], "docs": {building: fit document}, "html":
        {building: report}}``, in the order of ``buildings``.
    """
    from .._compiled import release
    from ..data import DataError
    from ..models import Grammar, ModelError, get_model, roots
    from ..select import candidate_models

    worker = _setup()
    cfg = FleetConfig(**config)
    out: dict[str, tuple] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        loaded = read_buildings(buildings, cfg.load_options())
        load_s = (time.perf_counter() - t0) / max(1, len(buildings))
        fixed = cfg.fixed_model
        checked: dict[str, tuple] = {}
        for b in buildings:
            data = loaded[b.name]
            if isinstance(data, Exception):
                out[b.name] = (_empty_row(b.name, "bad_data", str(data)), None, {"load_s": load_s})
                continue
            try:
                if fixed:  # a structure name built for this building's columns
                    models = [get_model(fixed, data.columns)]
                elif cfg.models == "search":  # the simplest structure's columns are needed
                    grammar = Grammar.from_columns(data.columns)
                    models = [roots(grammar)[0].build(grammar)]
                else:
                    models = candidate_models(cfg.models, data)
                ident, valid = _check(data, cfg, models)
                checked[b.name] = (ident, valid, load_s, data.slice(ident.start, valid.end))
            except (DataError, ModelError, ValueError) as err:
                out[b.name] = (_empty_row(b.name, "bad_data", str(err)), None, {"load_s": load_s})
        if checked:
            if fixed:
                _fixed_model(fixed, checked, cfg, fit_json, out)
            elif cfg.models == "search":  # each building its own search
                for n, item in checked.items():
                    _selection("search", {n: item}, cfg, fit_json, out)
                    release()  # each search compiles structures of its own
            else:
                groups: dict[tuple, dict] = {}
                for n, item in checked.items():  # the same candidates climb together
                    key = tuple(m.name for m in candidate_models(cfg.models, item[3]))
                    groups.setdefault(key, {})[n] = item
                for key, members in groups.items():
                    _selection([get_model(m) for m in key], members, cfg, fit_json, out)
    rows, docs, html = [], {}, {}
    for b in buildings:
        row, report, timing = out[b.name]
        timing["total_s"] = sum(
            v for k, v in timing.items() if k.endswith("_s") and k != "compile_s"
        )
        row.update(partition=int(index), worker=worker, **_row_timing(timing))
        rows.append(row)
        if report is not None and "_html" in report:
            html[b.name] = report.pop("_html")
        if fit_json:
            docs[b.name] = _doc(b.name, row, report, timing)
    return {"rows": rows, "docs": docs, "html": html}


_TIMINGS = (
    "load_s",
    "fit_s",
    "select_s",
    "compile_s",
    "validate_s",
    "kpi_s",
    "report_s",
    "total_s",
)


def _row_timing(timing: dict) -> dict:
    out = {k: float(timing.get(k, math.nan)) for k in _TIMINGS}
    out["batch"] = int(timing.get("batch", 1))
    return out
