"""One building's identification: :class:`GreyBox` holds every attempt, a :class:`Case`.

A :class:`Case` is one identification attempt: a model structure, its identification and
validation slices of the building's data, an initial guess and where it came from, the solver
settings, and once run the fit, its post-simulation validation and its validity verdict. A
:class:`GreyBox` owns the data and the cases, compares them in a table and a figure, runs forward
selection (:meth:`GreyBox.select`) and saves itself (:meth:`GreyBox.save`, :meth:`GreyBox.load`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..models import RCModel, get_model
from ._guess import Guess, lhs_starts, manual_guess, naming_guess, parent_guess

__all__ = ["Case", "GreyBox", "Progress", "run_cases"]

Progress = Callable[[str], None]

#: Solver settings a case passes on to :func:`jaxbox.fit.fit`.
SETTINGS = ("max_steps", "rtol", "atol", "concentration", "weights", "simulator")


def _quiet(msg: str) -> None:
    pass


def _period(data) -> tuple[str, str]:
    return (str(data.start), str(data.end))


@dataclasses.dataclass(eq=False)
class Case:
    """One identification attempt of a :class:`GreyBox`.

    Attributes:
        name: unique name within the GreyBox (the model name by default).
        model: the model structure.
        ident: identification data (a slice of the GreyBox's data).
        valid: validation data directly following ``ident`` (or ``None``).
        guess: the initial guess and its source (naming, parent, manual).
        free, fixed, bounds: the estimation problem (see :func:`jaxbox.fit.fit`; SI units).
        starts: number of starts (the guess plus Latin-hypercube samples), fitted in one call.
        seed: seed of the Latin hypercube.
        settings: solver settings (``max_steps``, ``rtol``, ``atol``, ``concentration``,
            ``weights``, ``simulator``).
        parent: name of the case the guess was inherited from.
        notes: what happened on the way (a retry with narrowed bounds, …).
        result: the :class:`~jaxbox.fit.FitResult` once run.
        validation: its :class:`~jaxbox.validate.Validation` (auto and cross).
        verdict: its :class:`~jaxbox.validate.Verdict`.
        timing: ``fit_s``, ``validate_s``, ``verdict_s`` [s] of the run.
    """

    name: str
    model: RCModel
    ident: Any
    valid: Any
    guess: Guess
    free: tuple[str, ...] | None = None
    fixed: dict = dataclasses.field(default_factory=dict)
    bounds: dict = dataclasses.field(default_factory=dict)
    starts: int = 8
    seed: int | None = 0
    settings: dict = dataclasses.field(default_factory=dict)
    parent: str | None = None
    notes: list = dataclasses.field(default_factory=list)
    result: Any = None
    validation: Any = None
    verdict: Any = None
    timing: dict = dataclasses.field(default_factory=dict)

    # -- running ---------------------------------------------------------------------------------

    def start_values(self) -> np.ndarray:
        """The starts [S, n_free] this case fits (the guess first), reproducible for its seed."""
        _, x0 = lhs_starts(
            self.model,
            self.ident,
            self._guess_in_bounds(),
            self.starts,
            free=self.free,
            fixed=self.fixed,
            bounds=self.bounds,
            seed=self.seed,
            concentration=self.settings.get("concentration", 4.0),
        )
        return x0

    def _guess_in_bounds(self) -> dict:
        out = {}
        for n, v in self.guess.values.items():
            if n in self.fixed:
                continue
            spec = self.model.parameter(n)
            lo, hi = self.bounds.get(n, (spec.lower, spec.upper))
            out[n] = float(np.clip(v, lo, hi))
        return out

    def run(self, progress: Progress | None = None) -> Case:
        """Fit every start in one batched call, post-simulate, and judge validity."""
        return run_cases([self], progress)[0]

    def _request(self) -> dict:
        """The :func:`jaxbox.fit.fit_batch` request of this case."""
        opts = {k: v for k, v in self.settings.items() if k in SETTINGS}
        return {
            "model": self.model,
            "data": self.ident,
            "free": self.free,
            "fixed": self.fixed or None,
            "bounds": self.bounds or None,
            "guess": self._guess_in_bounds(),
            "starts": self.start_values(),
            "seed": self.seed,
            **opts,
        }

    def _complete(self, result, fit_s: float, say: Progress) -> Case:
        """Post-simulate a fitted case and judge it."""
        from ..validate import check_validity, uncertainty, validate

        self.result = result
        t1 = time.perf_counter()
        self.validation = validate(self.result, self.valid)
        t2 = time.perf_counter()
        try:
            unc = uncertainty(self.result)
        except ValueError:
            unc = None
        self.verdict = check_validity(self.result, unc, check_intervals=unc is not None)
        t3 = time.perf_counter()
        self.timing = {
            "fit_s": fit_s,
            "compile_s": float(self.result.timing.get("compile_s", 0.0)),
            "validate_s": t2 - t1,
            "verdict_s": t3 - t2,
        }
        if self.result.timing.get("batch", 1) > 1:
            self.timing["batch"] = int(self.result.timing["batch"])
        say(
            f"  {self.name}: {self.result.starts.status_summary()}; RMSE auto "
            f"{self.se_auto:.3f} K, cross {_fmt(self.se_cross)} K, "
            f"{'valid' if self.is_valid else 'not valid'} ({fit_s + t3 - t1:.1f} s)"
        )
        return self

    def judge(self, **options) -> Case:
        """Judge validity again with other :func:`~jaxbox.validate.check_validity` options."""
        from ..validate import check_validity

        self._require_run()
        self.verdict = check_validity(self.result, **options)
        return self

    def _require_run(self) -> None:
        if self.result is None:
            raise ValueError(f"case {self.name!r} has not been run yet; call case.run()")

    # -- summaries -------------------------------------------------------------------------------

    @property
    def done(self) -> bool:
        return self.result is not None

    @property
    def n_params(self) -> int:
        """Number of free parameters (initial states included)."""
        if self.result is not None:
            return len(self.result.free)
        if self.free is not None:
            return len(self.free)
        return len([n for n in self.model.param_names if n not in self.fixed])

    @property
    def se_auto(self) -> float:
        """Simulation error Σ q RMSE on the identification data [K] (nan before running)."""
        return float("nan") if self.validation is None else float(self.validation.se_auto)

    @property
    def se_cross(self) -> float:
        """Simulation error on the validation data [K] (nan without validation data)."""
        v = self.validation
        return float("nan") if v is None or v.se_cross is None else float(v.se_cross)

    @property
    def is_valid(self) -> bool:
        return bool(self.verdict is not None and self.verdict.valid)

    @property
    def reasons(self) -> tuple[str, ...]:
        return () if self.verdict is None else tuple(self.verdict.reasons)

    def row(self) -> dict:
        """One row of :meth:`GreyBox.table`."""
        v = self.validation
        out = {
            "case": self.name,
            "model": self.model.name,
            "n_params": self.n_params,
            "guess": self.guess.source + (f" ({self.parent})" if self.parent else ""),
            "starts": self.starts,
            "se_auto": self.se_auto,
            "se_cross": self.se_cross,
            "valid": self.is_valid if self.verdict is not None else None,
            "reasons": "; ".join(self.reasons),
            "notes": "; ".join(self.notes),
        }
        if v is not None:
            for o, r in v.rmse_auto.items():
                out[f"rmse_auto_{o}"] = float(r)
            for o, r in (v.rmse_cross or {}).items():
                out[f"rmse_cross_{o}"] = float(r)
        return out

    def __repr__(self) -> str:
        state = (
            f"se_auto={self.se_auto:.4g}, se_cross={self.se_cross:.4g}, valid={self.is_valid}"
            if self.done
            else "not run"
        )
        return f"Case({self.name!r}, model={self.model.name!r}, {state})"


def run_cases(
    cases: Sequence[Case],
    progress: Progress | None = None,
    *,
    catch: bool = False,
    labels: Sequence[str] | None = None,
) -> list[Case]:
    """Run several cases together: every start of every case in as few compiled calls as the
    shapes allow (one, for cases of the same shape — e.g. one model on several buildings).

    Args:
        cases: cases not run yet (of one or several GreyBoxes).
        progress: called with one line of text per step.
        catch: record a case that fails (every start failed, non-finite post-simulation) in its
            ``notes`` and go on, instead of raising.
        labels: a prefix per case for the progress lines (e.g. the building).

    Returns:
        The cases, run (a failed one, with ``catch``, has no result).
    """
    from ..fit import FitError, fit_batch

    say = progress or _quiet
    labels = list(labels) if labels is not None else [""] * len(cases)
    tell = [(lambda msg, lab=lab: say(f"{lab}{msg}")) if lab else say for lab in labels]
    requests = []
    for case, told in zip(cases, tell, strict=True):
        req = case._request()
        told(
            f"  {case.name}: {len(req['starts'])} starts in one batch "
            f"({len(req['starts'][0])} free parameters) …"
        )
        requests.append(req)
    t0 = time.perf_counter()
    outcomes = fit_batch(requests, errors="return")
    fit_s = (time.perf_counter() - t0) / max(1, len(cases))
    for case, outcome, told in zip(cases, outcomes, tell, strict=True):
        try:
            if isinstance(outcome, FitError):
                raise outcome
            case._complete(outcome, fit_s, told)
        except (ValueError, FloatingPointError) as err:  # FitError, non-finite post-simulation
            if not catch:
                raise
            case.result = case.validation = case.verdict = None
            case.notes.append(f"failed: {err}")
            told(f"  {case.name}: failed ({err})")
    return list(cases)


def _fmt(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{x:.3f}"


class GreyBox:
    """Every identification attempt (:class:`Case`) on one building's data.

    Args:
        data: the building's :class:`~jaxbox.data.Dataset` (inputs and outputs).
        train: identification period ``(start, end)`` (inclusive; ``None`` sides are open);
            default the first half of ``data``.
        valid: validation period ``(start, end)``; default everything after ``train``. Pass
            ``valid=False`` for no validation data.
        name: a label for tables and reports (the building).
    """

    def __init__(self, data, *, train=None, valid=None, name: str = "building") -> None:
        self.data = data
        self.name = str(name)
        if train is None and valid is None:
            ident, val = data.split()
            self.train = _period(ident)
            self.valid_period = _period(val)
        else:
            ident = data.slice(*train) if train is not None else None
            if ident is None:
                first = data.slice(*valid)
                before = data.index[data.index < first.start]
                if len(before) == 0:
                    raise ValueError("no data before the validation period to identify on")
                ident = data.slice(None, before[-1])
            self.train = _period(ident)
            if valid is False:
                self.valid_period = None
            elif valid is not None:
                self.valid_period = _period(data.slice(*valid))
            else:
                rest = data.index[data.index > ident.end]
                self.valid_period = (str(rest[0]), str(data.end)) if len(rest) else None
        self.cases: dict[str, Case] = {}

    # -- data ------------------------------------------------------------------------------------

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
        starts: int = 8,
        seed: int | None = 0,
        train: tuple | None = None,
        valid: tuple | None = None,
        **settings,
    ) -> Case:
        """Declare a case (not run yet; call :meth:`Case.run` or use :meth:`identify`).

        Args:
            model: a library model name or an :class:`~jaxbox.models.RCModel`.
            name: case name (default the model name, made unique).
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
                ``atol``, ``concentration``, ``weights``, ``simulator``).
        """
        model = get_model(model)
        bad = [k for k in settings if k not in SETTINGS]
        if bad:
            raise TypeError(
                f"unknown setting(s) {', '.join(bad)}; settings are {', '.join(SETTINGS)}"
            )
        ident = self.data.slice(*train) if train is not None else self.ident
        if valid is not None:
            val = self.data.slice(*valid)
        elif train is not None:
            rest = self.data.index[self.data.index > ident.end]
            val = self.data.slice(rest[0], None) if len(rest) else None
        else:
            val = self.valid
        ident.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
        if isinstance(guess, Guess):
            g = guess
        elif isinstance(guess, Mapping):
            g = manual_guess(model, ident, guess)
        elif guess == "naming":
            g = naming_guess(model, ident)
        elif guess == "parent":
            if parent is None:
                raise ValueError("guess='parent' needs parent=<name of a case that has been run>")
            p = self[parent]
            p._require_run()
            g = parent_guess(model, ident, p.result.params, parent)
        else:
            raise ValueError(
                f"unknown guess {guess!r}; give 'naming', 'parent' (with parent=), a dict of "
                "values or a Guess"
            )
        case = Case(
            name=self._unique(name or model.name),
            model=model,
            ident=ident,
            valid=val,
            guess=g,
            free=None if free is None else tuple(free),
            fixed=dict(fixed or {}),
            bounds={k: (float(a), float(b)) for k, (a, b) in (bounds or {}).items()},
            starts=int(starts),
            seed=seed,
            settings=dict(settings),
            parent=parent if g.source == "parent" else g.parent,
        )
        self.cases[case.name] = case
        return case

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

    def select(self, candidates="all", **options):
        """Forward selection over ``candidates``; see :func:`jaxbox.select.forward_selection`."""
        from ._forward import forward_selection

        return forward_selection(self, candidates, **options)

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
                f"{c.name:<{width}} {c.n_params:>4} {_fmt(c.se_auto):>8} {_fmt(c.se_cross):>9} "
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

    def save(self, path) -> Any:
        """Save as plain JSON + NPZ into folder ``path``, atomically; see
        :func:`jaxbox.select.save_greybox`."""
        from ._persist import save_greybox

        return save_greybox(self, path)

    @classmethod
    def load(cls, path) -> GreyBox:
        """Load a GreyBox saved with :meth:`save`."""
        from ._persist import load_greybox

        return load_greybox(path)


def _short(reason: str, width: int = 90) -> str:
    head = reason.split(":")[0]
    return head if len(head) <= width else head[: width - 1] + "…"
