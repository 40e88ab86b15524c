"""Save and load a GreyBox as plain JSON + NPZ (no pickle), written atomically.

A saved GreyBox is a folder with

* ``greybox.json`` — the index: name, periods, and per case its model (its name and its full
  declaration: nodes, resistances, heat inputs and every parameter's unit, default and bounds,
  so that a custom model — even one named like a library model, or a library model with other
  bounds — loads as the model that was fitted), guess and its source, free/fixed/bounds,
  settings, parent, notes, the estimate (every parameter), the best start and every start's
  status, and the validation errors and verdict as they were;
* ``arrays-<digest>.npz`` — the data (values, time stamps in ns, column names) and every case's
  start values, final values, costs and iteration counts (plain arrays, loaded with
  ``allow_pickle=False``).

Saving writes the arrays under a new name (the digest of their content), then replaces the index
that names them (both atomically: a temporary file renamed over the target), and only then
removes the arrays files older than the previous version. A save interrupted at any point leaves
the previous save intact and loadable; a reader that loads while another process saves gets the
previous or the new version (it reads the index, then the arrays it names, and starts again if a
save removed them meanwhile). Temporary files of a save that was killed are removed by the next
save or load. Saves into one folder take turns (a lock on its ``.greybox.lock``).

Loading trusts nothing in the folder: the index is checked against its schema (one
:class:`PersistError` naming the field for each problem), the arrays file it names must be a
plain ``arrays-<digest>.npz`` inside the folder, and the arrays must have the shapes the index
implies.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import hashlib
import io
import json
import math
import re
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from .._io import atomic_write_bytes, atomic_write_json, remove_stale_temporaries
from ..data import DataError, Dataset
from ..data._checks import offset_text
from ..data._plausible import STUCK_HOURS
from ..models import ModelError, Parameter, RCModel, RCNetwork, get_model
from ._cases import Case, check_seed, check_settings, check_starts, data_checks
from ._guess import Guess

__all__ = ["FORMAT", "PersistError", "Saved", "read_greybox", "save_greybox"]

FORMAT = "jaxbox.greybox/1"
INDEX = "greybox.json"
LOCK = ".greybox.lock"
#: the only names an index may give its arrays file: a plain file inside the folder
_ARRAYS_NAME = re.compile(r"arrays-[0-9a-f]{16}\.npz")
#: attempts of a load that finds its arrays removed by a concurrent save
_ATTEMPTS = 5


class PersistError(ValueError):
    """A saved GreyBox cannot be read: no index, another format, a field missing or of the wrong
    type, an arrays file outside the folder or damaged; or a GreyBox cannot be saved where it
    was asked to (a file, or a folder holding another tool's ``greybox.json``). The message
    names the file and the field."""


@dataclasses.dataclass(frozen=True)
class Saved:
    """The parts of a saved GreyBox, read back (see :meth:`GreyBox.load`)."""

    name: str
    data: Dataset
    train: tuple
    valid: tuple | bool
    cases: list
    ranges: dict
    stuck_hours: float | None = STUCK_HOURS
    max_gap: float | None = None
    index: Path | None = None


# ---- the schema of the index -------------------------------------------------------------------


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _is_str(v) -> bool:
    return isinstance(v, str)


def _is_period(v) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(isinstance(x, str) for x in v)


def _list_of(check: Callable) -> Callable:
    return lambda v: isinstance(v, list) and all(check(x) for x in v)


def _dict_of(check: Callable) -> Callable:
    return lambda v: isinstance(v, dict) and all(check(x) for x in v.values())


def _or_none(check: Callable) -> Callable:
    return lambda v: v is None or check(v)


_TYPES: dict[str, Callable] = {
    "a string": _is_str,
    "an integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "a number": _is_number,
    "true or false": lambda v: isinstance(v, bool),
    "a list": lambda v: isinstance(v, list),
    "an object": lambda v: isinstance(v, dict),
    "a [start, end] pair of time stamps": _is_period,
    "a list of strings": _list_of(_is_str),
    "an object of numbers": _dict_of(_is_number),
    "an object of numbers or nulls": _dict_of(_or_none(_is_number)),
    "an object of [lower, upper] pairs": _dict_of(
        lambda v: isinstance(v, list) and len(v) == 2 and all(_is_number(x) for x in v)
    ),
    "a number, 'inf' or '-inf'": lambda v: _is_number(v) or v in ("inf", "-inf"),
    "a list of objects": lambda v: isinstance(v, list) and all(isinstance(x, dict) for x in v),
    "a list of [kind, value] pairs": lambda v: (
        isinstance(v, list)
        and all(
            isinstance(x, list)
            and len(x) == 2
            and _is_str(x[0])
            and (_is_str(x[1]) or _is_number(x[1]))
            for x in v
        )
    ),
    # an infinite bound (an unbounded parameter) is saved as null
    "an object of [lower, upper] pairs of numbers or nulls": _dict_of(
        lambda v: isinstance(v, list) and len(v) == 2 and all(_or_none(_is_number)(x) for x in v)
    ),
}

#: field -> (expected type, may be null); fields marked optional may be missing
_TOP = {
    "format": ("a string", False),
    "name": ("a string", False),
    "train": ("a [start, end] pair of time stamps", False),
    "valid": ("a [start, end] pair of time stamps", True),
    "arrays": ("a string", False),
    "cases": ("a list", False),
    "ranges": ("an object of [lower, upper] pairs", False),
    "stuck_hours": ("a number", True),
    "tz": ("a string", True),
    "max_gap": ("a number", False),
}
_TOP_OPTIONAL = {"ranges", "stuck_hours", "tz", "max_gap"}
_CASE = {
    "name": ("a string", False),
    "model": ("a string", False),
    "train": ("a [start, end] pair of time stamps", False),
    "valid": ("a [start, end] pair of time stamps", True),
    "guess": ("an object", False),
    "free": ("a list of strings", True),
    "fixed": ("an object of numbers", False),
    "bounds": ("an object of [lower, upper] pairs of numbers or nulls", False),
    "starts": ("an integer", False),
    "seed": ("an integer", True),
    "settings": ("an object", False),
    "parent": ("a string", True),
    "notes": ("a list of strings", False),
    "timing": ("an object of numbers", True),
    "result": ("an object", True),
    "declaration": ("an object", False),
}
#: saves of earlier versions hold no declaration (their models are found by name)
_CASE_OPTIONAL = {"timing", "declaration"}
#: the declaration of a case's model (:func:`model_declaration`)
_DECLARATION = {
    "name": ("a string", False),
    "description": ("a string", False),
    "network": ("an object", False),
    "parameters": ("a list of objects", False),
}
_NETWORK = {
    "name": ("a string", False),
    "description": ("a string", False),
    "nodes": ("a list of objects", False),
    "edges": ("a list of objects", False),
    "sources": ("a list of objects", False),
    "specs": ("a list of objects", False),
}
_NODE = {
    "name": ("a string", False),
    "C": ("a string", False),
    "T0": ("a string", False),
    "output": ("a string", True),
    "constant": ("true or false", False),
}
_EDGE = {
    "a": ("a string", False),
    "b": ("a string", False),
    "R": ("a string", False),
    "scale": ("a number", False),
    "factors": ("a list of [kind, value] pairs", False),
}
_SOURCE = {
    "node": ("a string", False),
    "input": ("a string", False),
    "gain": ("a list of [kind, value] pairs", False),
}
_PARAMETER = {
    "name": ("a string", False),
    "unit": ("a string", False),
    "default": ("a number, 'inf' or '-inf'", False),
    "lower": ("a number, 'inf' or '-inf'", False),
    "upper": ("a number, 'inf' or '-inf'", False),
    "description": ("a string", False),
}
_GUESS = {
    "values": ("an object of numbers", False),
    "source": ("a string", False),
    "parent": ("a string", True),
    "inherited": ("a list of strings", False),
}
_GUESS_OPTIONAL = {"parent", "inherited"}
_RESULT = {
    "arrays": ("a string", False),
    "params": ("an object of numbers or nulls", False),
    "free": ("a list of strings", False),
    "cost": ("a number", True),
    "converged": ("true or false", False),
    "best": ("an integer", False),
    "status": ("a list of strings", False),
    "timing": ("an object", False),
    "settings": ("an object", False),
    "validation": ("an object", True),
    "verdict": ("an object", True),
}
_RESULT_OPTIONAL = {"validation", "verdict"}


def _check_fields(doc, schema: dict, where: str, fail, optional=frozenset()) -> None:
    if not isinstance(doc, dict):
        fail(where or "the index", "must be a JSON object")
    for key, (kind, nullable) in schema.items():
        field = f"{where}.{key}" if where else key
        if key not in doc:
            if key in optional:
                continue
            fail(field, "is missing")
        value = doc[key]
        if value is None and nullable:
            continue
        if not _TYPES[kind](value):
            shown = json.dumps(value)
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            fail(field, f"must be {kind}{' or null' if nullable else ''}, got {shown}")


def _check_index(doc, index: Path) -> None:
    """The index against its schema: one :class:`PersistError` naming the first bad field."""

    def fail(field: str, problem: str):
        raise PersistError(f"{index}: {field} {problem}")

    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise PersistError(f"{index} is not a saved GreyBox (format {got!r}, expected {FORMAT!r})")
    _check_fields(doc, _TOP, "", fail, _TOP_OPTIONAL)
    if not _ARRAYS_NAME.fullmatch(doc["arrays"]):
        fail(
            "arrays",
            f"must name a file arrays-<16 hex digits>.npz in the folder, got {doc['arrays']!r}",
        )
    names = set()
    for i, case in enumerate(doc["cases"]):
        where = f"cases[{i}]"
        _check_fields(case, _CASE, where, fail, _CASE_OPTIONAL)
        _check_fields(case["guess"], _GUESS, f"{where}.guess", fail, _GUESS_OPTIONAL)
        if case["name"] in names:
            fail(f"{where}.name", f"{case['name']!r} is given to two cases")
        names.add(case["name"])
        for key, check in (("starts", check_starts), ("seed", check_seed)):
            try:
                check(case[key])
            except (TypeError, ValueError) as err:
                fail(f"{where}.{key}", f"is out of range ({err})")
        result = case["result"]
        if result is not None:
            _check_fields(result, _RESULT, f"{where}.result", fail, _RESULT_OPTIONAL)
            if result["arrays"] != f"case{i}":
                fail(f"{where}.result.arrays", f"must be 'case{i}', got {result['arrays']!r}")
            n = len(result["status"])
            if not 0 <= result["best"] < max(n, 1):
                fail(f"{where}.result.best", f"must index one of the {n} starts")


def _check_arrays(arrays: dict, doc: dict, path: Path) -> None:
    """The arrays the index implies, with consistent shapes."""

    def need(key: str, ndim: int, kind: str) -> np.ndarray:
        if key not in arrays:
            raise PersistError(f"{path}: the array {key!r} is missing")
        a = arrays[key]
        if a.ndim != ndim or a.dtype.kind not in kind:
            raise PersistError(f"{path}: the array {key!r} has the wrong shape or type")
        return a

    values = need("data/values", 2, "f")
    times = need("data/time_ns", 1, "iu")
    columns = need("data/columns", 1, "U")
    if len(times) != values.shape[0] or len(columns) != values.shape[1]:
        raise PersistError(f"{path}: the data arrays do not agree in shape")
    for i, case in enumerate(doc["cases"]):
        result = case["result"]
        if result is None:
            continue
        key, n = result["arrays"], len(result["status"])
        initial = need(f"{key}/initial", 2, "f")
        params = need(f"{key}/params", 2, "f")
        cost = need(f"{key}/cost", 1, "f")
        steps = need(f"{key}/steps", 1, "iu")
        if not (len(initial) == len(params) == len(cost) == len(steps) == n):
            raise PersistError(f"{path}: the arrays of cases[{i}] do not hold its {n} starts")
        p = len(result["free"])
        if initial.shape[1] != p or params.shape[1] != p:
            raise PersistError(
                f"{path}: the arrays of cases[{i}] do not hold its {p} free parameters"
            )


# ---- the model of a case ----------------------------------------------------------------------


def _number_doc(x: float):
    """A number of a declaration: as it is when finite, ``"inf"``/``"-inf"`` otherwise (JSON has
    no infinity, and null would not say which)."""
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def _parameter_doc(p: Parameter) -> dict:
    """``p`` as :meth:`~jaxbox.models.Parameter.to_dict` gives it, infinite numbers as text."""
    numbers = ("default", "lower", "upper")
    return {k: _number_doc(v) if k in numbers else v for k, v in p.to_dict().items()}


def model_declaration(model: RCModel) -> dict:
    """The declaration of ``model`` as plain JSON: its name and description, its network (nodes,
    resistances, heat inputs, declared parameter specs) and every parameter's unit, default
    and bounds; without the segments of the data it was fitted to (a load segments it again,
    as the fit did). :func:`declared_model` builds the model back from it."""
    base = model.segmented(1)
    net = base.network
    return {
        "name": base.name,
        "description": base.description,
        "network": {
            "name": net.name,
            "description": net.description,
            "nodes": [
                {"name": n.name, "C": n.C, "T0": n.T0, "output": n.output, "constant": n.constant}
                for n in net.nodes
            ],
            "edges": [
                {
                    "a": e.a,
                    "b": e.b,
                    "R": e.R,
                    "scale": e.scale,
                    "factors": [[k, v] for k, v in e.factors],
                }
                for e in net.edges
            ],
            "sources": [
                {"node": x.node, "input": x.input, "gain": [[k, v] for k, v in x.gain]}
                for x in net.sources
            ],
            "specs": [_parameter_doc(p) for p in net.specs],
        },
        "parameters": [_parameter_doc(p) for p in base.parameters],
    }


def _factor_text(kind: str, value) -> str:
    """One factor of a gain or of a resistance's share, as the declaration methods read it."""
    if kind == "const" and _is_number(value):
        return repr(float(value))
    if kind == "param" and _is_str(value):
        return value
    if kind == "compl" and _is_str(value):
        return f"1-{value}"
    raise ModelError(f"unknown factor [{kind!r}, {value!r}]")


def _parameter(doc: dict) -> Parameter:
    """The parameter of a checked ``_PARAMETER`` document (``"inf"`` read back as a number)."""
    numbers = ("default", "lower", "upper")
    return Parameter(**{k: float(doc[k]) if k in numbers else doc[k] for k in _PARAMETER})


def declared_model(doc: dict, where: str = "declaration") -> RCModel:
    """The model of a declaration (:func:`model_declaration`), built again through the
    declaration methods of :class:`~jaxbox.models.RCNetwork` (which check every node,
    resistance, heat input and parameter) and required to declare exactly ``doc``.

    Raises:
        ModelError: the declaration is malformed or does not describe a model (the message
            names the field under ``where``).
    """

    def fail(field: str, problem: str):
        raise ModelError(f"{field} {problem}")

    _check_fields(doc, _DECLARATION, where, fail)
    nd = doc["network"]
    _check_fields(nd, _NETWORK, f"{where}.network", fail)
    for key, schema in (("nodes", _NODE), ("edges", _EDGE), ("sources", _SOURCE)):
        for i, item in enumerate(nd[key]):
            _check_fields(item, schema, f"{where}.network.{key}[{i}]", fail)
    for key, items in (("network.specs", nd["specs"]), ("parameters", doc["parameters"])):
        for i, item in enumerate(items):
            _check_fields(item, _PARAMETER, f"{where}.{key}[{i}]", fail)
    try:
        net = RCNetwork(nd["name"], nd["description"])
        for n in nd["nodes"]:
            if n["constant"]:
                net = net.constant(n["name"], T0=n["T0"])
            else:
                net = net.node(n["name"], C=n["C"], T0=n["T0"], output=n["output"])
        for e in nd["edges"]:
            factors = [_factor_text(k, v) for k, v in e["factors"]]
            scale = "*".join([repr(float(e["scale"])), *factors]) if factors else e["scale"]
            net = net.resistance(e["a"], e["b"], e["R"], scale=scale)
        for x in nd["sources"]:
            net = net.heat(
                x["node"], x["input"], gain="*".join(_factor_text(*f) for f in x["gain"])
            )
        for p in nd["specs"]:
            net = net.parameter(p["name"], spec=_parameter(p))
        model = net.build({p["name"]: _parameter(p) for p in doc["parameters"]})
    except (TypeError, ValueError) as err:  # ModelError, or what a builder did not foresee
        raise ModelError(f"{where} does not describe a model: {err}") from None
    if (model.name, model.description) != (doc["name"], doc["description"]):
        model = dataclasses.replace(model, name=doc["name"], description=doc["description"])
    if model_declaration(model) != doc:
        raise ModelError(
            f"{where} does not describe a model: it reads back as another declaration "
            f"({_differences(doc, model_declaration(model)) or 'in its names or descriptions'})"
        )
    return model


def _differences(saved: dict, other: dict, limit: int = 4) -> str:
    """How the declaration ``other`` differs from ``saved`` in what shapes a fit (names of
    the model and its parameters, network, units, defaults, bounds; not the descriptions), in
    words; ``""`` when it does not."""
    out = []
    if other["name"] != saved["name"]:
        out.append(f"name {other['name']!r} (saved: {saved['name']!r})")
    shape = ("nodes", "edges", "sources")
    if [other["network"][k] for k in shape] != [saved["network"][k] for k in shape]:
        out.append("another network (nodes, resistances or heat inputs)")
    mine = {p["name"]: p for p in other["parameters"]}
    theirs = {p["name"]: p for p in saved["parameters"]}
    out += [f"no parameter {n} (saved with it)" for n in theirs if n not in mine]
    out += [f"a parameter {n} (saved without it)" for n in mine if n not in theirs]
    for n in (n for n in theirs if n in mine):
        for f in ("unit", "default", "lower", "upper"):
            if mine[n][f] != theirs[n][f]:
                out.append(f"{n} {f} {mine[n][f]!r} (saved: {theirs[n][f]!r})")
    more = f"; and {len(out) - limit} more" if len(out) > limit else ""
    return "; ".join(out[:limit]) + more


def _checked_declaration(case: Case) -> dict:
    """The declaration of ``case``'s model, checked to build the model back exactly (a save
    never writes a model that would load as another)."""
    doc = model_declaration(case.model)
    try:
        back = declared_model(json.loads(json.dumps(doc, allow_nan=False)))
    except (TypeError, ValueError) as err:  # ModelError, or what json or a builder refused
        back, why = None, str(err)
    else:
        why = "it builds back as another model"
    if back != case.model.segmented(1):
        raise PersistError(
            f"case {case.name!r} cannot be saved: the declaration of its model "
            f"{case.model.name!r} does not give the model back ({why}); declare the model with "
            "jaxbox.models.RCNetwork and its components"
        )
    return doc


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
        "declaration": _checked_declaration(case),
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
    """Save GreyBox ``gb`` with all its cases into folder ``path`` (created if needed),
    atomically: a reader sees the previous or the new version, a save interrupted at any point
    leaves the previous one.

    Returns:
        The path of the index file ``greybox.json``.
    """
    folder = _save_folder(path)
    with _saving(folder):
        _check_not_foreign(folder / INDEX)
        return _save(gb, folder)


def _save_folder(path) -> Path:
    """The folder to save into, created if needed; a file there, or a file on the way to it, is
    a :class:`PersistError`."""
    folder = Path(path)
    for p in (folder, *folder.parents):
        if p.exists() and not p.is_dir():
            where = "is a file" if p == folder else f"lies under the file {p}"
            raise PersistError(f"cannot save a GreyBox into {folder}: it {where}; give a folder")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _check_not_foreign(index: Path) -> None:
    """A save replaces a saved GreyBox only: a ``greybox.json`` of another tool, of another
    format version, or unreadable is left alone (a :class:`PersistError`)."""
    if not index.exists():
        return
    try:
        doc = json.loads(index.read_text(encoding="utf-8"))
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
    except (OSError, ValueError):
        got = "unreadable"
    if got != FORMAT:
        raise PersistError(
            f"{index} is not a saved GreyBox of this version (format {got!r}, expected "
            f"{FORMAT!r}) and a save would replace it; save into another folder, or remove it"
        )


def _tz_text(tz) -> str | None:
    """The time zone of the data as text: ``None``, ``"+02:00"`` for a fixed offset, or the
    zone's name (``"Europe/Berlin"``, ``"UTC"``)."""
    if tz is None:
        return None
    if isinstance(tz, datetime.timezone) and tz is not datetime.timezone.utc:
        return offset_text(tz.utcoffset(None))
    return str(getattr(tz, "key", None) or getattr(tz, "zone", None) or tz)


def _with_tz(index: pd.DatetimeIndex, text: str | None) -> pd.DatetimeIndex:
    """``index`` (naive UTC instants, as saved) in the saved time zone ``text``."""
    if text is None:
        return index
    offset = re.fullmatch(r"[+-]\d\d:\d\d", text)
    tz = pd.Timestamp(f"2000-01-01T00:00{text}").tzinfo if offset else text
    return index.tz_localize("UTC").tz_convert(tz)


@contextlib.contextmanager
def _saving(folder: Path):
    """One save at a time into ``folder`` (an exclusive lock on its ``.greybox.lock``, where the
    system has them): a save must not remove the arrays another save has just written."""
    try:
        import fcntl
    except ImportError:  # no advisory locks here: saves into one folder must not overlap
        yield
        return
    with open(folder / LOCK, "a+b") as handle:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)


def _save(gb, folder: Path) -> Path:
    remove_stale_temporaries(folder)
    buf = io.BytesIO()
    np.savez_compressed(buf, **_arrays(gb))
    blob = buf.getvalue()
    arrays_name = f"arrays-{hashlib.sha256(blob).hexdigest()[:16]}.npz"
    previous = _named_arrays(folder / INDEX)
    atomic_write_bytes(folder / arrays_name, blob)
    doc = {
        "format": FORMAT,
        "name": gb.name,
        "train": list(gb.train),
        "valid": None if gb.valid_period is None else list(gb.valid_period),
        "arrays": arrays_name,
        "ranges": {k: list(v) for k, v in getattr(gb, "ranges", {}).items()},
        "stuck_hours": getattr(gb, "stuck_hours", STUCK_HOURS),
        "tz": _tz_text(gb.data.index.tz),
        "max_gap": getattr(gb, "max_gap", None),
        "cases": [_case_doc(i, c) for i, c in enumerate(gb.cases.values())],
    }
    index = atomic_write_json(folder / INDEX, doc)
    # the previous version's arrays stay one save longer, for a reader that has just read the
    # previous index; older ones go
    keep = {arrays_name, previous}
    for old in folder.glob("arrays-*.npz"):
        if _ARRAYS_NAME.fullmatch(old.name) and old.name not in keep:  # only what saves write
            old.unlink(missing_ok=True)
    return index


def _named_arrays(index: Path) -> str | None:
    """The arrays file the index names, if it is readable and names one."""
    try:
        name = json.loads(index.read_text(encoding="utf-8")).get("arrays")
    except (OSError, ValueError, AttributeError):
        return None
    return name if isinstance(name, str) and _ARRAYS_NAME.fullmatch(name) else None


def _model(name: str, models, where: str, index: Path) -> RCModel:
    """The model of a case saved without its declaration (by an earlier version): given in
    ``models``, or the library model of that name."""
    try:
        if models and name in models:
            return get_model(models[name])
        return get_model(name)
    except ModelError as err:
        raise PersistError(
            f"{index}: {where}.model: {err}; pass models={{{name!r}: model}} for a model that is "
            "not in the library"
        ) from None


def _case_model(cd: dict, models, where: str, index: Path) -> RCModel:
    """The model of saved case ``cd``: built from its declaration (the model that was fitted,
    custom or not); one given in ``models`` under its name must be that model (it may differ
    only in descriptions). Saves without declarations find it by name (:func:`_model`)."""
    name, doc = cd["model"], cd.get("declaration")
    if doc is None:
        return _model(name, models, where, index)
    given = _model(name, models, where, index) if models and name in models else None
    try:
        model = declared_model(doc, f"{where}.declaration")
    except (TypeError, ValueError) as err:  # ModelError, or what a builder did not foresee
        if given is not None:  # a declaration this version cannot build: the model given
            return given
        raise PersistError(
            f"{index}: {err}; pass models={{{name!r}: model}} with the model case "
            f"{cd['name']!r} was fitted with"
        ) from None
    if model.name != name:
        raise PersistError(
            f"{index}: {where}.model is {name!r} but its declaration is of model {model.name!r}"
        )
    if given is None:
        return model
    if differences := _differences(doc, model_declaration(given)):
        raise PersistError(
            f"{index}: {where}: models[{name!r}] is not the model case {cd['name']!r} was fitted "
            f"and saved with ({differences}); leave it out of models= to load the saved model"
        )
    return given


def _read(index: Path) -> tuple[dict, dict]:
    """The index and the arrays it names, consistent with each other: read again when a save
    going on elsewhere removed the arrays between the two reads."""
    for attempt in range(_ATTEMPTS):
        try:
            text = index.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise PersistError(f"no saved GreyBox at {index.parent} (no {INDEX} there)") from None
        except (OSError, UnicodeDecodeError) as err:
            raise PersistError(f"{index}: cannot be read ({err})") from None
        try:
            doc = json.loads(text)
        except ValueError as err:
            raise PersistError(f"{index}: not valid JSON ({err})") from None
        _check_index(doc, index)
        path = index.parent / doc["arrays"]
        if path.is_symlink() and path.resolve().parent != index.parent.resolve():
            raise PersistError(f"{index}: arrays {doc['arrays']!r} links outside the folder")
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except FileNotFoundError:
            if attempt + 1 < _ATTEMPTS:
                continue  # a save replaced the index and removed these arrays meanwhile
            raise PersistError(f"{index}: the arrays file {doc['arrays']!r} is missing") from None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
            raise PersistError(f"{path}: not a readable arrays file ({err})") from None
        _check_arrays(arrays, doc, path)
        return doc, arrays
    raise AssertionError("unreachable")


def read_greybox(path, *, models: dict | None = None) -> Saved:
    """The parts of a GreyBox saved with :func:`save_greybox` (folder or its ``greybox.json``);
    :meth:`GreyBox.load` builds the GreyBox from them.

    Raises:
        PersistError: no saved GreyBox there, or a damaged one (the message names the field).
    """
    for name, model in (models or {}).items():
        if not isinstance(model, RCModel | str):
            raise TypeError(
                f"models[{name!r}] must be an RCModel (or a library model name) for the cases "
                f"saved with model {name!r}, got {type(model).__name__}"
            )
    p = Path(path)
    index = p if p.name == INDEX and not p.is_dir() else p / INDEX
    remove_stale_temporaries(index.parent)
    doc, arrays = _read(index)
    try:
        frame = pd.DataFrame(
            arrays["data/values"],
            index=_with_tz(
                pd.DatetimeIndex(pd.to_datetime(arrays["data/time_ns"], unit="ns"), name="time"),
                doc.get("tz"),
            ),
            columns=[str(c) for c in arrays["data/columns"]],
        )
        data = Dataset(frame)
    except (DataError, ValueError, KeyError) as err:
        raise PersistError(f"{index}: the saved data cannot be read back ({err})") from None
    ranges = {k: tuple(v) for k, v in doc.get("ranges", {}).items()}
    stuck_hours = doc.get("stuck_hours", STUCK_HOURS)
    checks = _saved_checks(ranges, stuck_hours)
    cases = [_case(i, cd, data, arrays, models, index, checks) for i, cd in enumerate(doc["cases"])]
    return Saved(
        name=doc["name"],
        data=data,
        train=tuple(doc["train"]),
        valid=False if doc["valid"] is None else tuple(doc["valid"]),
        cases=cases,
        ranges=ranges,
        stuck_hours=stuck_hours,
        max_gap=doc.get("max_gap"),
        index=index,
    )


def _saved_checks(ranges: dict, stuck_hours) -> dict:
    """The saved GreyBox's data checks for its cases' verdicts (:attr:`Case.data_checks`) where
    they are well formed; else none here (the GreyBox made from the index names the field)."""

    def number(v) -> bool:
        return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)

    pairs = all(len(v) == 2 and all(map(number, v)) and v[0] < v[1] for v in ranges.values())
    hours = stuck_hours is None or (number(stuck_hours) and stuck_hours > 0)
    return data_checks(ranges, stuck_hours) if pairs and hours else {}


def _case(i: int, cd: dict, data, arrays: dict, models, index: Path, checks: dict) -> Case:
    """One saved case, its fit rebuilt from the stored values and validated again (``checks``:
    the saved GreyBox's data checks, :attr:`Case.data_checks`)."""
    from ..data import DataWarning
    from ..data._gaps import DEFAULT_MAX_GAP
    from ..fit import FitError, FitResult, StartReport, make_problem
    from ..fit._batch import fit_data
    from ..validate import validate
    from ..validate._verdict import verdict_of

    where = f"cases[{i}]"
    model = _case_model(cd, models, where, index)
    try:
        check_settings(cd["settings"])
    except (TypeError, ValueError) as err:
        raise PersistError(f"{index}: {where}.settings: {err}") from None
    try:
        ident = data.slice(*cd["train"])
        valid = None if cd["valid"] is None else data.slice(*cd["valid"])
    except DataError as err:
        raise PersistError(f"{index}: {where}.train/valid: {err}") from None
    try:  # the window's gaps prepared as for the fit, the model segmented to it
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            model, ident = fit_data(model, ident, cd["settings"].get("max_gap", DEFAULT_MAX_GAP))
    except FitError as err:
        raise PersistError(f"{index}: {where}.train: {err}") from None
    case = Case(
        name=cd["name"],
        model=model,
        ident=ident,
        valid=valid,
        guess=Guess.from_dict(cd["guess"]),
        free=None if cd["free"] is None else tuple(cd["free"]),
        fixed={k: float(v) for k, v in cd["fixed"].items()},
        bounds={
            k: (_bound(a, -math.inf), _bound(b, math.inf)) for k, (a, b) in cd["bounds"].items()
        },
        starts=int(cd["starts"]),
        seed=cd["seed"],
        settings=dict(cd["settings"]),
        parent=cd["parent"],
        notes=list(cd["notes"]),
        timing=dict(cd.get("timing") or {}),
        data_checks=dict(checks),
    )
    rd = cd["result"]
    if rd is None:
        return case
    missing = [n for n in model.param_names if n not in rd["params"]]
    if missing:
        raise PersistError(f"{index}: {where}.result.params lacks {', '.join(missing)}")
    try:
        opts = {k: v for k, v in case.settings.items() if k in ("weights", "simulator")}
        problem = make_problem(
            model,
            ident,
            free=case.free,
            fixed=case.fixed or None,
            bounds=case.bounds or None,
            guess=case._guess_in_bounds(),
            **opts,
        )
    except (FitError, ModelError, DataError) as err:
        raise PersistError(f"{index}: {where} cannot be set up again ({err})") from None
    if tuple(rd["free"]) != problem.free:
        raise PersistError(
            f"{index}: {where}.result.free ({', '.join(rd['free'])}) are not the free parameters "
            f"of its estimation problem ({', '.join(problem.free)})"
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
        params={n: _float(rd["params"][n]) for n in model.param_names},
        cost=_float(rd["cost"]),
        converged=bool(rd["converged"]),
        best=int(rd["best"]),
        starts=report,
        timing=dict(rd["timing"]),
        settings=dict(rd["settings"]),
    )
    case.validation = validate(case.result, valid, method=case.postsim)
    if rd.get("verdict") is not None:
        case.verdict = verdict_of(case.result, case.validation, **checks)
    return case


def _float(v) -> float:
    return math.nan if v is None else float(v)


def _bound(v, infinite: float) -> float:
    """A saved bound: null for an infinite one (JSON has no infinity)."""
    return infinite if v is None else float(v)
