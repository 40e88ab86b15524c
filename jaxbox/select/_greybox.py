"""One building's identification: :class:`GreyBox` holds every attempt, a :class:`Case`.

A :class:`GreyBox` owns the data and the cases, compares them in a table and a figure, and saves
itself (:meth:`GreyBox.save`, :meth:`GreyBox.load`, or :func:`save_greybox` and
:func:`load_greybox`). Forward selection over its cases is :func:`jaxbox.select.forward_selection`
(a module above this one: the class does not import the functions that use it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..data import DataError, as_dataset, check_mapping, check_plausibility
from ..data._gaps import DEFAULT_MAX_GAP, duration_seconds
from ..data._plausible import STUCK_HOURS
from ..fit import DEFAULT_STARTS, FitError
from ..fit._batch import fit_data
from ..fit._problem import make_problem, number
from ..models import RCModel, get_model
from ._cases import (
    Case,
    Progress,
    check_seed,
    check_settings,
    check_starts,
    data_checks,
    fmt_se,
)
from ._guess import Guess, manual_guess, naming_guess, parent_guess
from ._persist import PersistError, read_greybox, save_greybox

__all__ = ["GreyBox", "load_greybox"]


def _period(data) -> tuple[str, str]:
    return (str(data.start), str(data.end))


def _pair(value, name: str):
    """A pair argument: a ``(start, end)`` period (either may be ``None``) or a ``(lo, hi)``
    range."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise TypeError(f"{name} must be a pair (a tuple of two values), got {value!r}")
    return tuple(value)


def _stuck_hours(value) -> float | None:
    """``stuck_hours``: ``None`` (no check) or a positive number of hours."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeError(f"stuck_hours must be a number of hours or None, got {value!r}")
    if not np.isfinite(value) or value <= 0:
        raise DataError(
            f"stuck_hours must be a positive number of hours (or None for no check), got {value!r}"
        )
    return float(value)


def _case_name(name) -> str | None:
    """``name=`` of :meth:`GreyBox.add_case`: ``None`` (the model's name) or non-empty text."""
    if name is None:
        return None
    if not isinstance(name, str):
        raise TypeError(f"name must be the case's name (text) or None, got {name!r}")
    if not name.strip():
        raise ValueError("name must not be empty; give the case a name or None for the model's")
    return name


def _problem(model, ident, free, fixed, bounds, guess, settings, label: str):
    """The estimation problem of a case, set up once when it is declared, so that a parameter
    name, value or bound the model does not take is refused then (not when the case runs)."""
    try:
        return make_problem(
            model,
            ident,
            free=free,
            fixed=fixed or None,
            bounds=bounds or None,
            guess=dict(guess) if isinstance(guess, Mapping) else None,
            weights=settings.get("weights"),
            simulator=settings.get("simulator", "exact"),
        )
    except FitError as err:
        raise FitError(f"{label}: {err}") from None


def _checked_guess(guess: Guess, model: RCModel, label: str) -> Guess:
    """A :class:`Guess` given to :meth:`GreyBox.add_case`: finite numbers for parameters of
    ``model``."""
    bad = [k for k in guess.values if k not in model.param_names]
    if bad:
        raise ValueError(
            f"{label}: the guess names {', '.join(map(str, bad))}, which the model does not "
            f"have; its parameters are {', '.join(model.param_names)}"
        )
    for k, v in guess.values.items():
        try:
            finite = np.isfinite(number(v, f"guess of {k}"))
        except FitError:
            finite = False
        if not finite:
            raise ValueError(f"{label}: the guess of {k} must be a finite number, got {v!r}")
    return guess


class GreyBox:
    """Every identification attempt (:class:`Case`) on one building's data.

    Args:
        data: the building's inputs and outputs: a :class:`~jaxbox.data.Dataset`, a pandas
            DataFrame with a time index or a ``time`` column, or the path of a CSV file (read
            with :func:`jaxbox.data.load`); anything else is a ``TypeError``.
        train: identification period ``(start, end)`` (inclusive; ``None`` sides are open);
            default the first half of ``data``.
        valid: validation period ``(start, end)``; default everything after ``train``. Pass
            ``valid=False`` for no validation data.
        name: a label for tables and reports (the building).
        ranges: plausible range per column, ``{"T_zon": (lo, hi)}`` in canonical units, where
            the defaults of :func:`jaxbox.data.check_plausibility` do not fit the building
            (the identification and validation windows are checked when the data are
            attached).
        max_gap: the longest input gap [s] (or text such as ``"2h"``) interpolated in the
            windows; longer gaps split a window into segments that share the parameters, each
            with its own initial states (see :func:`jaxbox.data.prepare_window`). Output gaps
            are masked.
        stuck_hours: a temperature that does not change for this many hours is refused as a
            stuck sensor (default 24; ``None`` turns the check off, e.g. for a coarse sensor in
            a steady cellar).

    A time stamp shared by ``train`` and ``valid`` belongs to the identification window
    (:meth:`jaxbox.data.Dataset.windows`).
    """

    def __init__(
        self,
        data,
        *,
        train=None,
        valid=None,
        name: str = "building",
        ranges: Mapping[str, tuple[float, float]] | None = None,
        max_gap: float | str = DEFAULT_MAX_GAP,
        stuck_hours: float | None = STUCK_HOURS,
    ) -> None:
        data = as_dataset(data, what="the data of a GreyBox")
        self.data = data
        if not isinstance(name, str):
            raise TypeError(f"name must be the building's name (text), got {name!r}")
        self.name = name
        self.ranges = {
            str(k): tuple(map(float, _pair(v, f"ranges[{k!r}]")))
            for k, v in check_mapping(ranges, "ranges").items()
        }
        for value, label in ((train, "train"), (valid, "valid")):
            if value is not None and value is not False:
                _pair(value, label)
        ident, val = data.windows(train, valid)
        self.max_gap = duration_seconds(max_gap)
        self.stuck_hours = _stuck_hours(stuck_hours)
        checks = {"overrides": self.ranges, "stuck_hours": self.stuck_hours}
        check_plausibility(ident, what="identification data", **checks)
        if val is not None:
            check_plausibility(val, what="validation data", **checks)
        self.train = _period(ident)
        self.valid_period = None if val is None else _period(val)
        self.cases: dict[str, Case] = {}

    # -- data ------------------------------------------------------------------------------------

    @property
    def data_checks(self) -> dict:
        """The plausibility options of this GreyBox as the verdict of its cases takes them
        (``data_overrides``: :attr:`ranges`; ``stuck_hours``)."""
        return data_checks(self.ranges, self.stuck_hours)

    @property
    def ident(self):
        """The identification slice of the data."""
        return self.data.slice(*self.train)

    @property
    def valid(self):
        """The validation slice of the data (``None`` when there is none)."""
        return None if self.valid_period is None else self.data.slice(*self.valid_period)

    def __repr__(self) -> str:
        return (
            f"GreyBox({self.name!r}, {len(self.data)} samples, train {self.train[0]} .. "
            f"{self.train[1]}, {len(self.cases)} case(s))"
        )

    def __getitem__(self, name: str) -> Case:
        try:
            return self.cases[name]
        except KeyError:
            raise KeyError(
                f"no case {name!r}; cases: {', '.join(self.cases) or '(none)'}"
            ) from None

    def __iter__(self):
        return iter(self.cases.values())

    def __len__(self) -> int:
        return len(self.cases)

    # -- cases -----------------------------------------------------------------------------------

    def _unique(self, name: str) -> str:
        """``name``, or ``name#2``, ``name#3``… when taken: for names the GreyBox makes up (the
        model's name, a retry's), never for a name the user gives (:meth:`add_case` refuses a
        name already used)."""
        if name not in self.cases:
            return name
        k = 2
        while f"{name}#{k}" in self.cases:
            k += 1
        return f"{name}#{k}"

    def add_case(
        self,
        model: str | RCModel,
        *,
        name: str | None = None,
        guess: str | Mapping[str, float] | Guess = "naming",
        parent: str | None = None,
        free: Sequence[str] | None = None,
        fixed: Mapping[str, float] | None = None,
        bounds: Mapping[str, tuple[float, float]] | None = None,
        starts: int = DEFAULT_STARTS,
        seed: int | None = 0,
        train: tuple | None = None,
        valid: tuple | None = None,
        **settings,
    ) -> Case:
        """Declare a case (not run yet; call :meth:`Case.run` or use :meth:`identify`).

        Args:
            model: a library model name or an :class:`~jaxbox.models.RCModel`.
            name: case name (default the model name, made unique with ``#2``, ``#3``…). A
                name given here must not be in use: a case of that name is refused
                (``ValueError``), never renamed; pick another or :meth:`remove_case` the old one.
            guess: ``"naming"`` (defaults per prefix, initial states from the data),
                ``"parent"`` (same-named parameters from the optimum of case ``parent``; new
                ones their defaults), a mapping of values (manual, over the naming guess), or a
                :class:`Guess`.
            parent: the parent case (required for ``guess="parent"``).
            free, fixed, bounds: the estimation problem (SI), as in :func:`jaxbox.fit.fit`.
            starts: number of starts: the guess plus ``starts − 1`` Latin-hypercube samples.
            seed: seed of the Latin hypercube.
            train, valid: periods overriding the GreyBox's (``(start, end)``).
            settings: solver settings for :func:`jaxbox.fit.fit` (``max_steps``, ``rtol``,
                ``atol``, ``concentration``, ``weights``, ``simulator``, ``max_gap``,
                ``homotopy``; ``()`` fits every start's output error directly, without the
                continuation route) and ``postsim``, the validation's simulator.
        """
        model = get_model(model, self.data.columns)  # a structure built for the data's columns
        name = _case_name(name)
        if name is not None and name in self.cases:
            raise ValueError(
                f"GreyBox {self.name!r} already has a case named {name!r}; pick another name= "
                f"(or leave name out for one made from the model's), or remove the old case "
                f"first with remove_case({name!r})"
            )
        fixed = check_mapping(fixed, "fixed")
        bounds = check_mapping(bounds, "bounds")
        if free is not None and (isinstance(free, str | bytes) or not isinstance(free, Sequence)):
            raise TypeError(
                f"free must be a list of parameter names, e.g. free=['R_wal', 'C_zon'], got "
                f"{free!r}"
            )
        settings = check_settings(settings)
        starts, seed = check_starts(starts), check_seed(seed)
        if parent is not None:
            self._parent(parent, guess)
        if train is not None or valid is not None:
            ident, val = self.data.windows(
                None if train is None else _pair(train, "train"),
                None if valid is None else _pair(valid, "valid"),
            )
        else:
            ident, val = self.ident, self.valid
        ident.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
        settings.setdefault("max_gap", self.max_gap)
        try:
            model, ident = fit_data(model, ident, settings["max_gap"])
        except FitError as err:
            raise DataError(str(err)) from None
        label = f"case {name or model.name!r} (model {model.name})"
        problem = _problem(model, ident, free, fixed, bounds, guess, settings, label)
        if isinstance(guess, Guess):
            g = _checked_guess(guess, model, label)
        elif isinstance(guess, Mapping):
            g = manual_guess(model, ident, guess)
        elif guess == "naming":
            g = naming_guess(model, ident)
        elif guess == "parent":
            if parent is None:
                raise ValueError("guess='parent' needs parent=<name of a case that has been run>")
            g = parent_guess(model, ident, self.cases[parent].result.params, parent)
        else:
            error = ValueError if isinstance(guess, str) else TypeError
            raise error(
                f"unknown guess {guess!r}; give 'naming', 'parent' (with parent=), a dict of "
                "values or a Guess"
            )
        case = Case(
            name=name if name is not None else self._unique(model.name),
            model=model,
            ident=ident,
            valid=val,
            guess=g,
            free=None if free is None else problem.free,
            fixed={k: float(v) for k, v in fixed.items()},
            bounds={k: (float(a), float(b)) for k, (a, b) in bounds.items()},
            starts=starts,
            seed=seed,
            settings=settings,
            parent=parent if g.source == "parent" else g.parent,
            data_checks=self.data_checks,
        )
        self.cases[case.name] = case
        return case

    def remove_case(self, name: str) -> Case:
        """Remove the case ``name`` (to declare another under its name) and return it.

        Raises:
            KeyError: no case of that name.
            ValueError: other cases started from its optimum (``guess='parent'``): remove
                them first, or their ``parent`` would name whatever case takes the name next.
        """
        if not isinstance(name, str):
            raise TypeError(f"remove_case takes the name of a case (text), got {name!r}")
        case = self[name]  # KeyError naming the cases
        children = [c.name for c in self.cases.values() if c is not case and c.parent == name]
        if children:
            raise ValueError(
                f"case {name!r} is the parent of {', '.join(map(repr, children))}; remove "
                "those first"
            )
        return self.cases.pop(name)

    def _parent(self, parent, guess) -> None:
        """``parent=`` of :meth:`add_case`: a run case of this GreyBox, given with
        ``guess='parent'``."""
        if not isinstance(parent, str):
            raise TypeError(f"parent must be the name of a case (text), got {parent!r}")
        if parent not in self.cases:
            raise ValueError(
                f"parent {parent!r} is not a case of this GreyBox; cases: "
                f"{', '.join(self.cases) or '(none)'}"
            )
        if not (isinstance(guess, str) and guess == "parent"):
            raise ValueError(
                f"parent={parent!r} is used only with guess='parent' (to start from its "
                f"optimum); pass guess='parent' or leave parent out (guess is {guess!r})"
            )
        self.cases[parent]._require_run()

    def identify(self, model: str | RCModel, *, progress: Progress | None = None, **kw) -> Case:
        """Declare a case and run it (see :meth:`add_case` for the arguments)."""
        return self.add_case(model, **kw).run(progress)

    def best(self, valid_only: bool = True) -> Case | None:
        """The run case with the lowest cross-validation SE (only valid ones by default);
        without validation data, the lowest identification SE."""
        done = [c for c in self.cases.values() if c.done and (c.is_valid or not valid_only)]
        if not done:
            return None
        key = (lambda c: c.se_cross) if self.valid_period is not None else (lambda c: c.se_auto)
        finite = [c for c in done if np.isfinite(key(c))]
        return min(finite, key=key) if finite else None

    # -- comparison ------------------------------------------------------------------------------

    def table(self) -> pd.DataFrame:
        """One row per case: model, number of free parameters, guess source, RMSE and SE on
        identification (auto) and validation (cross) data [K], validity and its reasons."""
        rows = [c.row() for c in self.cases.values()]
        cols = ["case", "model", "n_params", "guess", "starts", "se_auto", "se_cross", "valid"]
        frame = pd.DataFrame(rows)
        if frame.empty:
            return pd.DataFrame(columns=[*cols, "reasons", "notes"])
        extra = [c for c in frame.columns if c.startswith("rmse_")]
        return frame[[*cols, *extra, "reasons", "notes"]].set_index("case")

    def table_text(self) -> str:
        """The comparison table as fixed-width text."""
        width = max([24, *(len(c.name) for c in self.cases.values())])
        lines = [
            f"{'case':<{width}} {'#par':>4} {'SE auto':>8} {'SE cross':>9} {'valid':>6}  reasons"
        ]
        for c in self.cases.values():
            valid = "-" if c.verdict is None else ("yes" if c.is_valid else "no")
            reasons = "; ".join(_short(r) for r in c.reasons)
            lines.append(
                f"{c.name:<{width}} {c.n_params:>4} {fmt_se(c.se_auto):>8} {fmt_se(c.se_cross):>9} "
                f"{valid:>6}  {reasons}"
            )
        return "\n".join(lines)

    def plot(self, ax=None, *, accepted: str | None = None):
        """RMSE (SE) on identification and validation data against the number of free
        parameters, one point per run case; filled markers for valid cases."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, ax = plt.subplots(figsize=(7.5, 4.2), layout="constrained")
        else:
            fig = ax.figure
        done = [c for c in self.cases.values() if c.done]
        order = sorted(done, key=lambda c: (c.n_params, c.name))
        x = np.asarray([c.n_params for c in order], dtype=float)
        auto = np.asarray([c.se_auto for c in order])
        cross = np.asarray([c.se_cross for c in order])
        ok = np.asarray([c.is_valid for c in order], dtype=bool)
        ax.plot(x, auto, "-", color="tab:blue", alpha=0.5)
        ax.plot(x, cross, "-", color="tab:red", alpha=0.5)
        for sel, face in ((ok, None), (~ok, "none")):
            kw = {} if face is None else {"facecolors": face}
            ax.scatter(x[sel], auto[sel], marker="o", color="tab:blue", **kw)
            ax.scatter(x[sel], cross[sel], marker="s", color="tab:red", **kw)
        for xi, yi, c in zip(x, cross, order, strict=True):
            if np.isfinite(yi):
                ax.annotate(
                    c.name,
                    (xi, yi),
                    textcoords="offset points",
                    xytext=(4, 4),
                    fontsize="x-small",
                    rotation=20,
                )
        if accepted is not None and accepted in self.cases:
            a = self.cases[accepted]
            ax.scatter(
                [a.n_params],
                [a.se_cross],
                s=160,
                facecolors="none",
                edgecolors="k",
                linewidths=1.5,
                label=f"accepted: {accepted}",
            )
        ax.plot([], [], "o-", color="tab:blue", label="identification (auto)")
        ax.plot([], [], "s-", color="tab:red", label="validation (cross)")
        ax.scatter([], [], marker="o", facecolors="none", color="0.4", label="not valid")
        ax.set_xlabel("number of free parameters")
        ax.set_ylabel("SE = Σ q RMSE [K]")
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        ax.set_title(f"{self.name}: simulation error against model size", fontsize="medium")
        return fig

    # -- persistence -----------------------------------------------------------------------------

    def save(self, path) -> Path:
        """Save as plain JSON + NPZ into folder ``path``, atomically; see :func:`save_greybox`."""
        return save_greybox(self, path)

    @classmethod
    def load(cls, path, *, models: Mapping[str, RCModel] | None = None) -> GreyBox:
        """Load a GreyBox saved with :meth:`save`; see :func:`load_greybox`."""
        saved = read_greybox(path, models=check_mapping(models, "models"))
        try:
            gb = cls(
                saved.data,
                train=saved.train,
                valid=saved.valid,
                name=saved.name,
                ranges=saved.ranges,
                stuck_hours=saved.stuck_hours,
                max_gap=DEFAULT_MAX_GAP if saved.max_gap is None else saved.max_gap,
            )
        except (TypeError, ValueError) as err:  # periods, ranges, stuck_hours, max_gap
            raise PersistError(
                f"{saved.index}: the GreyBox cannot be set up again ({err})"
            ) from None
        gb.cases = {case.name: case for case in saved.cases}
        return gb


def _short(reason: str, width: int = 90) -> str:
    head = reason.split(":")[0]
    return head if len(head) <= width else head[: width - 1] + "…"


def load_greybox(path, *, models: Mapping[str, RCModel] | None = None) -> GreyBox:
    """Load a GreyBox saved with :func:`save_greybox` (its folder or its ``greybox.json``).

    Args:
        path: the folder (or the index file in it).
        models: ``{name: RCModel}``, rarely needed: a save holds the declaration of every
            case's model and loads it as it was fitted (a custom model, even one named like a
            library model, included). A model given here for a name must be that model (it may
            differ in its descriptions only; a :class:`PersistError` names the differences);
            saves of earlier versions, which hold no declarations, take it for a model not in
            the library.

    The fits are rebuilt from the stored values (no refit): parameters, costs and every start's
    outcome are identical, so validating them again gives identical numbers. The validation and
    verdict are recomputed on load. A save running at the same time is not seen half-done: the
    previous or the new version is loaded.

    Raises:
        PersistError: the folder holds no saved GreyBox, or a damaged one (the message names
            the file and the field).
    """
    return GreyBox.load(path, models=models)
