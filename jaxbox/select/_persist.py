"""Save and load a :class:`GreyBox` as plain JSON + NPZ (no pickle), written atomically.

A saved GreyBox is a folder with

* ``greybox.json`` — the index: name, periods, and per case its model (library name, or the full
  declaration of a custom model is not stored: such cases need ``models=`` on load), guess and
  its source, free/fixed/bounds, settings, parent, notes, the estimate (every parameter), the
  best start and every start's status, and the validation errors and verdict as they were;
* ``arrays-<digest>.npz`` — the data (values, time stamps in ns, column names) and every case's
  start values, final values, costs and iteration counts (plain arrays, loaded with
  ``allow_pickle=False``).

Every file is written to a temporary file and renamed over the target; the arrays file is named
by the digest of its content and written first, the index last, and stale arrays files are
removed only after the new index is in place. A save interrupted at any point leaves the
previous save intact and loadable.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
from pathlib import Path

import numpy as np
import pandas as pd

from .._io import atomic_write_bytes, atomic_write_json
from ..data import Dataset
from ..models import RCModel, get_model
from ._cases import Case
from ._guess import Guess

__all__ = ["save_greybox", "read_greybox", "Saved", "FORMAT"]


@dataclasses.dataclass(frozen=True)
class Saved:
    """The parts of a saved GreyBox, read back."""

    name: str
    data: Dataset
    train: tuple
    valid: tuple | bool
    cases: list


FORMAT = "jaxbox.greybox/1"
INDEX = "greybox.json"


def _arrays(gb) -> dict[str, np.ndarray]:
    frame = gb.data.frame
    out = {
        "data/values": frame.to_numpy(dtype=np.float64),
        "data/time_ns": frame.index.as_unit("ns").asi8.astype(np.int64),
        "data/columns": np.asarray([str(c) for c in frame.columns], dtype=str),
    }
    for i, case in enumerate(gb.cases.values()):
        if case.result is None:
            continue
        st = case.result.starts
        out[f"case{i}/initial"] = np.asarray(st.initial, dtype=np.float64)
        out[f"case{i}/params"] = np.asarray(st.params, dtype=np.float64)
        out[f"case{i}/cost"] = np.asarray(st.cost, dtype=np.float64)
        out[f"case{i}/steps"] = np.asarray(st.steps, dtype=np.int64)
    return out


def _case_doc(i: int, case: Case) -> dict:
    doc = {
        "name": case.name,
        "model": case.model.name,
        "train": [str(case.ident.start), str(case.ident.end)],
        "valid": None if case.valid is None else [str(case.valid.start), str(case.valid.end)],
        "guess": case.guess.to_dict(),
        "free": None if case.free is None else list(case.free),
        "fixed": dict(case.fixed),
        "bounds": {k: list(v) for k, v in case.bounds.items()},
        "starts": case.starts,
        "seed": case.seed,
        "settings": dict(case.settings),
        "parent": case.parent,
        "notes": list(case.notes),
        "timing": dict(case.timing),
        "result": None,
    }
    r = case.result
    if r is not None:
        doc["result"] = {
            "arrays": f"case{i}",
            "params": dict(r.params),
            "free": list(r.free),
            "cost": r.cost,
            "converged": r.converged,
            "best": r.best,
            "status": list(r.starts.status),
            "timing": dict(r.timing),
            "settings": dict(r.settings),
            "validation": None if case.validation is None else case.validation.to_dict(),
            "verdict": None if case.verdict is None else case.verdict.to_dict(),
        }
    return doc


def save_greybox(gb, path) -> Path:
    """Save ``gb`` with all its cases into folder ``path`` (created if needed), atomically.

    Returns:
        The path of the index file ``greybox.json``.
    """
    folder = Path(path)
    folder.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    np.savez_compressed(buf, **_arrays(gb))
    blob = buf.getvalue()
    digest = hashlib.sha256(blob).hexdigest()[:16]
    arrays_name = f"arrays-{digest}.npz"
    atomic_write_bytes(folder / arrays_name, blob)
    doc = {
        "format": FORMAT,
        "name": gb.name,
        "train": list(gb.train),
        "valid": None if gb.valid_period is None else list(gb.valid_period),
        "arrays": arrays_name,
        "cases": [_case_doc(i, c) for i, c in enumerate(gb.cases.values())],
    }
    index = atomic_write_json(folder / INDEX, doc)
    for old in folder.glob("arrays-*.npz"):
        if old.name != arrays_name:
            old.unlink(missing_ok=True)
    return index


def _model(name: str, models) -> RCModel:
    if models and name in models:
        return get_model(models[name])
    return get_model(name)


def read_greybox(path, *, models: dict | None = None):
    """Load a GreyBox saved with :func:`save_greybox` (folder or its ``greybox.json``).

    Args:
        path: the folder (or the index file in it).
        models: ``{name: RCModel}`` for cases whose model is not in the library.

    The fits are rebuilt from the stored values (no refit): parameters, costs and every start's
    outcome are identical, so validating them again gives identical numbers. The validation and
    verdict are recomputed on load.
    """
    from ..fit import FitResult, StartReport, make_problem
    from ..validate import check_validity, uncertainty, validate

    p = Path(path)
    index = p if p.is_file() else p / INDEX
    doc = json.loads(index.read_text(encoding="utf-8"))
    if doc.get("format") != FORMAT:
        raise ValueError(f"{index} is not a saved GreyBox (format {doc.get('format')!r})")
    with np.load(index.parent / doc["arrays"], allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    frame = pd.DataFrame(
        arrays["data/values"],
        index=pd.DatetimeIndex(pd.to_datetime(arrays["data/time_ns"], unit="ns"), name="time"),
        columns=[str(c) for c in arrays["data/columns"]],
    )
    data = Dataset(frame)
    cases = []
    for cd in doc["cases"]:
        model = _model(cd["model"], models)
        ident = data.slice(*cd["train"])
        valid = None if cd["valid"] is None else data.slice(*cd["valid"])
        case = Case(
            name=cd["name"],
            model=model,
            ident=ident,
            valid=valid,
            guess=Guess.from_dict(cd["guess"]),
            free=None if cd["free"] is None else tuple(cd["free"]),
            fixed={k: float(v) for k, v in cd["fixed"].items()},
            bounds={k: (float(a), float(b)) for k, (a, b) in cd["bounds"].items()},
            starts=int(cd["starts"]),
            seed=cd["seed"],
            settings=dict(cd["settings"]),
            parent=cd["parent"],
            notes=list(cd["notes"]),
            timing=dict(cd.get("timing") or {}),
        )
        rd = cd["result"]
        if rd is not None:
            guess = {n: v for n, v in case._guess_in_bounds().items()}
            opts = {k: v for k, v in case.settings.items() if k in ("weights", "simulator")}
            problem = make_problem(
                model,
                ident,
                free=case.free,
                fixed=case.fixed or None,
                bounds=case.bounds or None,
                guess=guess,
                **opts,
            )
            key = rd["arrays"]
            report = StartReport(
                initial=arrays[f"{key}/initial"],
                params=arrays[f"{key}/params"],
                cost=arrays[f"{key}/cost"],
                steps=arrays[f"{key}/steps"],
                status=tuple(rd["status"]),
            )
            case.result = FitResult(
                problem=problem,
                data=ident,
                params={n: float(rd["params"][n]) for n in model.param_names},
                cost=float(rd["cost"]),
                converged=bool(rd["converged"]),
                best=int(rd["best"]),
                starts=report,
                timing=dict(rd["timing"]),
                settings=dict(rd["settings"]),
            )
            case.validation = validate(case.result, valid)
            if rd.get("verdict") is not None:
                try:
                    unc = uncertainty(case.result)
                except ValueError:
                    unc = None
                case.verdict = check_validity(case.result, unc, check_intervals=unc is not None)
        cases.append(case)
    return Saved(
        name=doc["name"],
        data=data,
        train=tuple(doc["train"]),
        valid=False if doc["valid"] is None else tuple(doc["valid"]),
        cases=cases,
    )
