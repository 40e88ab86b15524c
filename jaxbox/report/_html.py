"""One self-contained HTML page per GreyBox: data, selection table and figure, accepted model.

Figures are embedded as base64 PNG, so the page is a single file that opens anywhere. For the
accepted case (or the best valid one) the page shows its parameters with confidence intervals,
the fit on identification and validation data, residual diagnostics and the validity verdict.
"""

from __future__ import annotations

import base64
import html
import io
import math
from datetime import datetime
from os import PathLike
from pathlib import Path

from .._io import atomic_write_text

__all__ = ["greybox_report", "write_report"]

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;font-size:.9em;margin:.6em 0}
th,td{border:1px solid #ddd;padding:.25em .6em;text-align:right;vertical-align:top}
th{background:#f3f3f3}td.l,th.l{text-align:left}
tr.accepted{background:#eaf6ea;font-weight:600}tr.invalid td{color:#777}
img{max-width:100%;display:block;margin:.6em 0}.bad{color:#a00}.ok{color:#070}
.small{font-size:.85em;color:#555}
"""


def _png(fig, dpi: int = 90) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img alt="figure" src="data:image/png;base64,{data}">'


def _e(x) -> str:
    return html.escape(str(x))


def _num(x, fmt: str = ".3f") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return format(x, fmt)


def _data_section(gb) -> list[str]:
    d = gb.data
    out = [
        "<h2>Data</h2>",
        f"<p>{len(d)} samples every {d.step / 60:g} min from {_e(d.start)} to {_e(d.end)}; "
        f"columns: {_e(', '.join(d.columns))}.</p>",
        f"<p>Identification {_e(gb.train[0])} … {_e(gb.train[1])}"
        + (
            f"; validation {_e(gb.valid_period[0])} … {_e(gb.valid_period[1])}.</p>"
            if gb.valid_period
            else "; no validation data.</p>"
        ),
    ]
    try:
        names = [c for c in d.columns if c.startswith(("T_", "Q_hea", "I_glo"))] or None
        out.append(_png(d.plot(names)))
    except Exception as err:  # a figure must not cost the report
        out.append(f"<p class=bad>data plot failed: {_e(err)}</p>")
    return out


def _table_section(gb, accepted) -> list[str]:
    rows = [
        "<h2>Model selection</h2>",
        "<table><tr><th class=l>case</th><th class=l>model</th><th>#params</th>"
        "<th class=l>guess</th><th>RMSE auto [K]</th><th>RMSE cross [K]</th>"
        "<th>SE auto [K]</th><th>SE cross [K]</th><th>valid</th><th class=l>reasons / notes</th>"
        "</tr>",
    ]
    for c in gb.cases.values():
        if not c.done:
            continue
        v = c.validation
        ra = ", ".join(_num(x) for x in v.rmse_auto.values())
        rc = ", ".join(_num(x) for x in (v.rmse_cross or {}).values()) or "–"
        cls = "accepted" if c.name == accepted else ("" if c.is_valid else "invalid")
        why = "<br>".join(_e(r) for r in (*c.reasons, *c.notes)) or "–"
        rows.append(
            f"<tr class='{cls}'><td class=l>{_e(c.name)}</td><td class=l>{_e(c.model.name)}</td>"
            f"<td>{c.n_params}</td><td class=l>{_e(c.row()['guess'])}</td><td>{ra}</td>"
            f"<td>{rc}</td><td>{_num(c.se_auto)}</td><td>{_num(c.se_cross)}</td>"
            f"<td class={'ok' if c.is_valid else 'bad'}>{_valid_text(c)}</td>"
            f"<td class=l>{why}</td></tr>"
        )
    rows.append("</table>")
    rows.append(_png(gb.plot(accepted=accepted)))
    return rows


def _valid_text(case) -> str:
    if case.verdict is None:
        return "not judged"
    return "yes" if case.is_valid else "no"


def _tree_section(search) -> list[str]:
    """The search tree as nested lists: structure, criterion value, status and why."""
    tree = getattr(search, "tree", ())
    if not tree:
        return []
    children = search.children()

    def walk(parent) -> list[str]:
        out = ["<ul>"]
        for n in children.get(parent, []):
            value = _num(n.criterion, ".4g")
            cls = {"accepted": "ok", "grown": "ok", "not valid": "bad", "failed": "bad"}.get(
                n.status, ""
            )
            added = "" if n.parent is None else f" <span class=small>+ {_e(n.added)}</span>"
            why = f" <span class=small>({_e(n.why)})</span>" if n.why else ""
            out.append(
                f"<li><b>{_e(n.structure)}</b>{added}: {search.criterion} {value}, "
                f"<span class={cls}>{_e(n.status)}</span>{why}"
            )
            if n.case in children:
                out += walk(n.case)
            out.append("</li>")
        out.append("</ul>")
        return out

    head = (
        f"<h2>Structure search</h2><p class=small>Criterion {_e(search.criterion)}; "
        f"{len(tree)} candidates; {_e(search.stopped)}. Each line: a structure, what it adds "
        "to its parent, its criterion value and its fate (grown: extended in the next step; "
        "not valid: its branch pruned).</p>"
    )
    return [head, *walk(None)]


def _accepted_section(case, selection) -> list[str]:
    from ..validate import (
        fit_report,
        plot_autocorrelation,
        plot_confidence_intervals,
        plot_fit,
        plot_residuals,
        plot_residuals_vs_inputs,
        uncertainty,
    )

    r, v = case.result, case.validation
    out = [f"<h2>Accepted model: {_e(case.name)}</h2>", f"<p>{_e(case.model.description)}</p>"]
    if selection is not None:
        out.append(f"<p class=small>{_e(selection.stopped)}.</p>")
    try:
        unc = uncertainty(r)
    except ValueError:
        unc = None
    doc = fit_report(
        r,
        case.valid,
        validation=v,
        uncertainty=unc,
        verdict_options=getattr(case, "data_checks", None) or None,
    )
    out.append(
        "<table><tr><th class=l>parameter</th><th>value</th><th class=l>unit</th>"
        "<th>std</th><th>95 % interval</th><th>±%</th><th>bounds</th><th class=l>note</th></tr>"
    )
    for n, p in doc["params"].items():
        ci = p["ci95"]
        note = "fixed" if not p["free"] else ("AT BOUND" if p["at_bound"] else "")
        out.append(
            f"<tr><td class=l>{_e(n)}</td><td>{_num(p['value'], '.4g')}</td>"
            f"<td class=l>{_e(p['unit'])}</td><td>{_num(p['std'], '.3g')}</td>"
            f"<td>{'–' if ci is None else f'{ci[0]:.4g} … {ci[1]:.4g}'}</td>"
            f"<td>{_num(None if p['rel_ci'] is None else 100 * p['rel_ci'], '.3g')}</td>"
            f"<td>{p['lower']:.3g} … {p['upper']:.3g}</td><td class=l>{note}</td></tr>"
        )
    out.append("</table>")
    verdict = "valid" if doc["valid"] else "NOT valid"
    out.append(f"<p><b>Verdict: {verdict}.</b></p>")
    if doc["reasons"]:
        out.append("<ul>" + "".join(f"<li>{_e(x)}</li>" for x in doc["reasons"]) + "</ul>")
    if doc["warnings"]:
        out.append(
            "<p>Warnings:</p><ul>" + "".join(f"<li>{_e(x)}</li>" for x in doc["warnings"]) + "</ul>"
        )
    tc = ", ".join(f"{t:.3g} h" for t in doc["time_constants_h"])
    out.append(f"<p>Time constants: {tc}.</p>")
    out += _kpi_table(doc.get("kpis"))
    out += _hlc_section(selection)
    out.append("<h3>Fit on identification and validation data</h3>")
    figures = [
        lambda: plot_fit(v),
        lambda: plot_residuals(v),
        lambda: plot_residuals_vs_inputs(v),
        lambda: plot_autocorrelation(
            v.residual_analysis("auto"), title=f"{case.name}: identification residuals"
        ),
    ]
    if v.residuals_cross is not None:
        figures.append(
            lambda: plot_autocorrelation(
                v.residual_analysis("cross"), title=f"{case.name}: validation residuals"
            )
        )
    if unc is not None:
        figures.append(lambda: plot_confidence_intervals(unc))
    for make in figures:
        try:
            out.append(_png(make()))
        except Exception as err:  # one failing figure must not cost the report
            out.append(f"<p class=bad>figure failed: {_e(err)}</p>")
    return out


def _kpi_table(kpis) -> list[str]:
    """The physical indicators with their intervals (see :func:`jaxbox.validate.kpis`)."""
    if not kpis:
        return []
    rows = [("heat-loss coefficient", kpis["hlc"])]
    rows += [(f"solar aperture ({k})", v) for k, v in kpis["apertures"].items()]
    if len(kpis["apertures"]) > 1:
        rows.append(("solar aperture (total)", kpis["solar_aperture"]))
    rows += [(f"time constant {i + 1}", t) for i, t in enumerate(kpis["time_constants"])]
    out = [
        "<table><tr><th class=l>indicator</th><th>value</th><th class=l>unit</th>"
        "<th>std</th><th>95 % interval</th></tr>"
    ]
    for name, k in rows:
        if k is None:
            continue
        ci = k["ci95"]
        out.append(
            f"<tr><td class=l>{_e(name)}</td><td>{_num(k['value'], '.4g')}</td>"
            f"<td class=l>{_e(k['unit'])}</td><td>{_num(k['std'], '.3g')}</td>"
            f"<td>{'–' if ci is None else f'{ci[0]:.4g} … {ci[1]:.4g}'}</td></tr>"
        )
    out.append("</table>")
    if kpis.get("method"):
        out.append(f"<p class=small>Intervals: {_e(kpis['method'])}.</p>")
    out += [f"<p class=bad>Warning: {_e(w)}</p>" for w in kpis.get("warnings", ())]
    return out


def _hlc_section(selection) -> list[str]:
    """The heat-loss coefficient with an interval over the near-best structures too (see
    :func:`jaxbox.validate.hlc_interval`)."""
    import numpy as np

    from ..validate import hlc_interval

    if selection is None:
        return []
    try:
        hlc = hlc_interval(selection)
    except (ValueError, np.linalg.LinAlgError):
        return []
    if hlc is None:
        return []
    lo, hi = hlc.ci95
    ci = f"{lo:.4g} … {hi:.4g} W/K" if math.isfinite(lo) and math.isfinite(hi) else "–"
    out = [
        f"<p><b>Heat-loss coefficient: {hlc.value:.4g} W/K</b>, {round(100 * hlc.level)} % "
        f"interval {ci} ({_e(hlc.method)}).</p>"
    ]
    if len(hlc.models) > 1:
        each = ", ".join(
            f"{_e(m['model'])} {m['value']:.4g} W/K [{m['ci95'][0]:.4g} … {m['ci95'][1]:.4g}]"
            for m in hlc.models
        )
        out.append(f"<p class=small>Near-best models: {each}.</p>")
    if hlc.outdoor is not None and hlc.outdoor.follow:
        from ..validate._hlc import _outdoor_text

        line = _outdoor_text(hlc.outdoor.to_dict(), round(100 * hlc.level))
        out.append(
            f"<p>{_e(line[0].upper() + line[1:])}: the heating per kelvin of zone–outdoor "
            "difference with the measured boundaries as they behave in the data.</p>"
        )
    if hlc.zone_excess is not None:
        from ..validate._hlc import _unmeasured_text

        line = _unmeasured_text(hlc.zone_excess)
        out.append(f"<p>{_e(line[0].upper() + line[1:])}.</p>")
    return out + [f"<p class=bad>Warning: {_e(w)}</p>" for w in hlc.warnings]


def _form_section(selection, model) -> list[str]:
    """The accepted model of another form than the zone temperature's (a held zone: the
    heat-demand form; steady-state data: the steady-state model), with why."""
    why = getattr(selection, "choice", None)
    why = getattr(why, "why", "") if why is not None else ""
    return [
        f"<h2>Accepted model: {_e(selection.form)} form</h2>",
        f"<p>{_e(why)}</p>" if why else "",
        f"<pre>{_e(model.summary())}</pre>",
    ]


def greybox_report(gb, selection=None, *, title: str | None = None) -> str:
    """The HTML page (a string) of a :class:`~jaxbox.select.GreyBox`.

    Args:
        gb: the GreyBox (its run cases are tabulated and plotted).
        selection: a :class:`~jaxbox.select.Selection` naming the accepted case; without it
            the best valid case is shown.
        title: page title (default from the GreyBox's name).
    """
    from ..select import GreyBox, Selection

    if not isinstance(gb, GreyBox):
        raise TypeError(f"gb must be a jaxbox.select.GreyBox, got {type(gb).__name__}")
    if selection is not None and not isinstance(selection, Selection):
        raise TypeError(
            "selection must be a Selection (from GreyBox.select or GreyBox.search) or None, "
            f"got {type(selection).__name__}"
        )
    if title is not None and not isinstance(title, str):
        raise TypeError(f"title must be text or None, got {type(title).__name__}")
    accepted = None
    if selection is not None:
        accepted = selection.accepted
        case = gb.cases.get(accepted) if accepted is not None else None
        if accepted is not None and (case is None or not case.done):
            raise ValueError(
                f"the selection accepted {accepted!r}, which is not a fitted case of this "
                f"GreyBox ({', '.join(c.name for c in gb.cases.values() if c.done) or 'none'}); "
                "pass the selection made on this GreyBox"
            )
    else:
        best = gb.best()
        accepted = None if best is None else best.name
    title = title or f"jaxbox report: {gb.name}"
    parts = [
        "<!DOCTYPE html><html lang=en><head><meta charset=utf-8>",
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f"<p class=small>Generated {datetime.now():%Y-%m-%d %H:%M} by jaxbox.</p>",
    ]
    parts += _data_section(gb)
    parts += _table_section(gb, accepted)
    parts += _tree_section(selection)
    other = getattr(selection, "form_model", None) if accepted is None else None
    if accepted is not None:
        parts += _accepted_section(gb.cases[accepted], selection)
    elif other is not None:
        parts += _form_section(selection, other)
    else:
        parts.append("<h2>Accepted model</h2><p class=bad>No valid model.</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _report_path(path) -> Path:
    """``path`` as a file path to write (its folder is created when missing)."""
    if not isinstance(path, str | PathLike):
        raise TypeError(f"path must be a file path such as 'report.html', got {path!r}")
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(
            f"path {str(path)!r} is a folder; give a file name in it such as "
            f"{str(path / 'report.html')!r}"
        )
    return path


def write_report(gb, path, selection=None, **kw) -> Path:
    """Write :func:`greybox_report` to ``path`` atomically (the whole page or nothing: a failure
    leaves no partial file and an earlier report in place); returns the path. A missing folder
    is created.

    Raises:
        TypeError: ``path`` is not a path, or an argument of :func:`greybox_report` is wrong.
        IsADirectoryError: ``path`` is a folder.
        OSError: the file cannot be written there (the message names the path).
    """
    path = _report_path(path)
    text = greybox_report(gb, selection, **kw)
    try:
        return atomic_write_text(path, text)
    except OSError as err:
        raise type(err)(
            err.errno, f"cannot write the report to {str(path)!r}: {err.strerror}"
        ) from None
