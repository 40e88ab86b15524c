"""Forward selection: climb from the simplest model while cross-validation improves.

Candidates are sorted by their number of free parameters. Each is identified (multistart, all
starts in one batched call) with its initial guess inherited from the best valid case so far
(same-named parameters take the parent's optimum, new ones their defaults), post-simulated on the
identification and validation data, and judged. Where the initial temperature of an unmeasured
state ends on its bound (a slow boundary or wall state whose start biases the energy balance),
the case is retried once with that bound narrowed to the span of the temperatures around the
state (:func:`~jaxbox.select.state_ranges`), and the retry is recorded. Once a candidate is
valid, the selection stops when ``patience`` candidates in a row are not valid or do not lower
the cross-validation SE of the best valid case by at least ``margin`` (relative). The accepted
model is the valid case with the lowest cross-validation SE.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from ..data import Dataset
from ..fit import DEFAULT_STARTS
from ..models import RCModel, get_model, list_models
from ._cases import (
    Case,
    Progress,
    check_seed,
    check_settings,
    check_starts,
    quiet,
    run_cases,
    verdict_text,
)
from ._greybox import GreyBox
from ._guess import state_ranges

__all__ = ["Selection", "forward_selection", "forward_selection_many", "candidate_models"]


@dataclasses.dataclass(frozen=True)
class Selection:
    """Outcome of a forward selection.

    Attributes:
        accepted: name of the accepted case (``None`` when no candidate was valid).
        order: case names in the order they were identified.
        stopped: why the selection stopped, in words.
        skipped: candidate models never identified (after the stop).
        elapsed_s: wall-clock time of the selection [s].
        verdict: what was accepted, in words: the accepted model, or why none was (the
            likeliest cause first); the ``accepted: …`` line of the progress.
    """

    greybox: GreyBox
    accepted: str | None
    order: tuple[str, ...]
    stopped: str
    skipped: tuple[str, ...]
    elapsed_s: float
    verdict: str = ""

    @property
    def case(self) -> Case | None:
        """The accepted case."""
        return None if self.accepted is None else self.greybox.cases[self.accepted]

    def table(self):
        """The comparison table of the cases of this selection (pandas DataFrame)."""
        t = self.greybox.table()
        return t.loc[[n for n in self.order if n in t.index]]

    def to_dict(self) -> dict:
        return {
            "accepted": self.accepted,
            "order": list(self.order),
            "stopped": self.stopped,
            "skipped": list(self.skipped),
            "elapsed_s": self.elapsed_s,
            "verdict": self.verdict,
        }


def candidate_models(candidates, data=None) -> list[RCModel]:
    """Resolve candidates: a list of names/models, a library family name, or ``"all"`` (every
    library model whose inputs and outputs are all columns of ``data``).

    Sorted by number of parameters (stable: library order among equals). The same model
    named twice is a ``ValueError``.
    """
    if not isinstance(candidates, str | Sequence) or isinstance(candidates, bytes):
        raise TypeError(
            "candidates must be a list of model names or models, a library family name or "
            f"'all', got {type(candidates).__name__}"
        )
    if isinstance(candidates, str):
        if candidates == "all":
            models = [get_model(n) for n in list_models()]
            if data is not None:
                cols = set(data.columns)
                models = [m for m in models if set(m.inputs) | set(m.outputs) <= cols]
        else:
            models = [get_model(n) for n in list_models(family=candidates)]
    else:
        cols = None if data is None else data.columns  # structures built for the data's columns
        models = [get_model(m, cols) for m in candidates]
        twice = sorted({m.name for m in models if [n.name for n in models].count(m.name) > 1})
        if twice:
            raise ValueError(
                f"candidates name {', '.join(twice)} more than once; give each model once"
            )
    if not models:
        raise ValueError(f"no candidate model from {candidates!r} (with these data)")
    return sorted(models, key=lambda m: len(m.param_names))


def _pinned_unmeasured_states(case: Case) -> list[str]:
    """Initial temperatures of unmeasured states that ended at or near a bound."""
    if case.verdict is None:
        return []
    measured = {n.T0 for n in case.model.network.nodes if n.output is not None}
    flagged = case.verdict.flagged("at_bound")
    return [n for n in flagged if case.model.parameter(n).is_initial_state and n not in measured]


def _retry_of(gb: GreyBox, case: Case, suffix: str, **changes) -> Case:
    """Declare (not run) a case like ``case`` (same model, windows, starts, seed and settings)
    named ``<case>+<suffix>`` (``#2``… added when taken), with ``changes`` (``guess``,
    ``free``, ``fixed``, ``bounds``) and the same parent."""
    fields = dict(guess=case.guess, free=case.free, fixed=case.fixed, bounds=case.bounds)
    retry = gb.add_case(
        case.model,
        name=gb._unique(f"{case.name}+{suffix}"),
        **{**fields, **changes},
        starts=case.starts,
        seed=case.seed,
        train=(str(case.ident.start), str(case.ident.end)),
        valid=None if case.valid is None else (str(case.valid.start), str(case.valid.end)),
        **case.settings,
    )
    retry.parent = case.parent
    return retry


def _narrowed_retry(gb: GreyBox, case: Case, pinned, say: Progress) -> Case:
    """Declare (not run) a retry of ``case`` with the pinned initial temperatures' bounds
    narrowed to the span of the temperatures around their states."""
    ranges = state_ranges(case.model, case.ident)
    bounds = dict(case.bounds)
    told = []
    for n in pinned:
        lo, _, hi = ranges[n]
        bounds[n] = (lo, hi)
        told.append(f"{n} in [{lo:.2f}, {hi:.2f}] °C")
    say(f"  {case.name}: initial temperature(s) on a bound; retry with {', '.join(told)}")
    retry = _retry_of(gb, case, "narrowed", bounds=bounds)
    retry.notes.append(f"retry of {case.name}: bounds narrowed from the data ({', '.join(told)})")
    case.notes.append(f"initial temperature on its bound; retried as {retry.name}")
    return retry


class _Climb:
    """The forward selection of one GreyBox, one case at a time: :meth:`next_case` declares
    the case to run next (``None`` once stopped), :meth:`record` takes it back run."""

    def __init__(
        self, greybox, models, *, starts, seed, margin, patience, inherit, retry, settings, say
    ) -> None:
        self.gb, self.models, self.say = greybox, models, say
        self.starts, self.seed, self.settings = starts, seed, settings
        self.margin, self.patience, self.inherit, self.retry = margin, patience, inherit, retry
        self.k, self.best, self.order, self.misses = 0, None, [], 0
        self.stopped = ""  # why the climb stopped early; "" while it runs through
        self.streak: list[str] = []  # what each candidate since the best one did instead
        self.skipped: tuple[str, ...] = ()
        self.finished = False
        self.pending: Case | None = None  # a retry to run before the next model
        self.retried: Case | None = None  # the case that retry replaces

    def next_case(self) -> Case | None:
        if self.pending is not None:
            return self.pending
        if self.finished or self.k >= len(self.models):
            self.finished = True
            return None
        model, gb = self.models[self.k], self.gb
        self.say(f"[{self.k + 1}/{len(self.models)}] {model.name}")
        parent = self.best
        if parent is None and self.order:  # nothing valid yet: the lowest validation error
            run = [gb.cases[n] for n in self.order if gb.cases[n].done]
            parent = min(run, key=lambda c: c.score, default=None)
        kw = {"starts": self.starts, "seed": self.seed, **self.settings}
        if self.inherit and parent is not None:
            return gb.add_case(model, guess="parent", parent=parent.name, **kw)
        return gb.add_case(model, **kw)

    def record(self, case: Case) -> None:
        self.order.append(case.name)
        if case is self.pending:  # a retry: it replaces its case if valid or better
            original, self.pending, self.retried = self.retried, None, None
            if not (case.done and (case.is_valid or case.score < original.score)):
                case = original
        elif case.done and self.retry and not case.is_valid:
            pinned = _pinned_unmeasured_states(case)
            if pinned:
                try:
                    self.pending = _narrowed_retry(self.gb, case, pinned, self.say)
                    self.retried = case
                    return  # judged once the retry has run
                except ValueError as err:
                    self.say(f"  retry failed ({err})")
        self._judge(case)

    def _judge(self, case: Case) -> None:
        self.k += 1
        best, margin = self.best, self.margin
        improved = (
            case.done
            and case.is_valid
            and np.isfinite(case.score)
            and (best is None or case.score < (1.0 - margin) * best.score)
        )
        if improved:
            self.best, self.misses, self.streak = case, 0, []
            return
        if best is None:  # nothing valid yet: keep climbing
            return
        self.misses += 1
        if not case.done:
            self.streak.append("could not be identified")
        elif not case.is_valid:
            self.streak.append("not valid")
        else:
            se = "identification" if case.valid is None else "validation"
            by = f" by {100 * margin:g} %" if margin else ""
            self.streak.append(f"did not lower the {se} SE{by}")
        if self.misses >= self.patience and self.k < len(self.models):
            kinds = list(dict.fromkeys(self.streak))
            if len(kinds) == 1:
                why = kinds[0]
            else:
                why = (
                    f"did not improve on {best.name} ("
                    + ", ".join(f"{self.streak.count(k)} {k}" for k in kinds)
                    + ")"
                )
            self.stopped = f"stopped after {case.name}: {self.misses} candidate(s) in a row {why}"
            self.skipped = tuple(m.name for m in self.models[self.k :])
            self.finished = True

    def _ran_through(self) -> str:
        """Why a climb that did not stop early ended, true to what happened: every candidate
        identified, some that could not be (their fits failed), or none."""
        failed = [n for n in self.order if not self.gb.cases[n].done]
        if not failed:
            return "every candidate was identified"
        if len(failed) == len(self.order):
            return (
                f"every candidate was tried and none could be identified: all {len(failed)} "
                "fit(s) failed (each case's notes say why)"
            )
        shown = ", ".join(failed[:5]) + (", …" if len(failed) > 5 else "")
        return (
            f"every candidate was tried; {len(failed)} of {len(self.order)} case(s) could not "
            f"be identified: {shown} (their notes say why)"
        )

    def selection(self, elapsed: float) -> Selection:
        gb, order = self.gb, self.order
        self.stopped = self.stopped or self._ran_through()
        accepted = gb.best(valid_only=True)
        if accepted is not None and accepted.name not in set(order):
            accepted = min(
                (gb.cases[n] for n in order if gb.cases[n].is_valid),
                key=lambda c: c.score,
                default=None,
            )
        verdict = verdict_text(gb.cases, order, accepted)
        self.say(f"accepted: {verdict}; {self.stopped} ({elapsed:.0f} s)")
        return Selection(
            greybox=gb,
            accepted=None if accepted is None else accepted.name,
            order=tuple(order),
            stopped=self.stopped,
            skipped=self.skipped,
            elapsed_s=elapsed,
            verdict=verdict,
        )


_TAKES = (
    "a GreyBox, a jaxbox Dataset, a pandas DataFrame with a time index or the path of a CSV file"
)


def _as_greybox(obj, what: str) -> GreyBox:
    """A GreyBox as it is, or a new one (default periods) on data given as a Dataset, a
    DataFrame or a path."""
    if isinstance(obj, GreyBox):
        return obj
    if isinstance(obj, Dataset | pd.DataFrame | str | os.PathLike):
        return GreyBox(obj, name=str(obj) if isinstance(obj, str | os.PathLike) else "building")
    raise TypeError(f"{what} takes {_TAKES}; got {type(obj).__name__}")


def _flag(value, name: str) -> bool:
    """A true/false argument (``inherit``, ``retry_bounds``): text such as ``"no"`` is not
    taken for true."""
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def check_run(starts, seed, settings: Mapping, progress) -> dict:
    """The arguments every case of a selection or a search shares, checked before the first
    case is declared: ``starts``, ``seed``, the solver ``settings`` and ``progress`` (a
    callable or ``None``). Returns the settings."""
    check_starts(starts)
    check_seed(seed)
    if progress is not None and not callable(progress):
        raise TypeError(
            f"progress must be a function taking one line of text (such as print) or None, got "
            f"{progress!r}"
        )
    return check_settings(settings)


def _fraction(value, name: str) -> float:
    """``margin``: a fraction in [0, 1)."""
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )
    if not ok or not 0.0 <= value < 1.0:  # nan fails too
        raise ValueError(f"{name} must be a fraction in [0, 1), e.g. 0.05 for 5 %, got {value!r}")
    return float(value)


def forward_selection(
    greybox,
    candidates: str | Sequence[str | RCModel] = "all",
    *,
    starts: int = DEFAULT_STARTS,
    seed: int | None = 0,
    margin: float = 0.0,
    patience: int = 1,
    inherit: bool = True,
    retry_bounds: bool = True,
    progress: Progress | None = None,
    **settings,
) -> Selection:
    """Forward selection over candidate models on a :class:`GreyBox`'s data.

    Args:
        greybox: the building (data, identification and validation periods); the cases are
            added to it. Data alone (a :class:`~jaxbox.data.Dataset`, a DataFrame with a time
            index or a CSV path) gets a new GreyBox with the default periods (halves), found
            in :attr:`Selection.greybox`.
        candidates: model names/models, a library family (``"exp1"``…), or ``"all"`` (every
            library model the data can feed).
        starts: starts per case (the guess plus Latin-hypercube samples), fitted in one call.
        seed: seed of the Latin hypercubes.
        margin: a candidate improves when its cross-validation SE is below ``(1 − margin)``
            times the best valid one so far.
        patience: stop after this many candidates in a row that are not valid or do not
            improve.
        inherit: children take the optimum of the best valid case so far as their guess (of
            the case with the lowest validation SE while none is valid).
        retry_bounds: retry a case whose unmeasured initial temperature ends on its bound, with
            that bound narrowed from the data.
        progress: called with one line of text per step (per model, per batch of starts).
        settings: solver settings for :func:`jaxbox.fit.fit` (``max_steps``…).

    Returns:
        :class:`Selection` (the cases are in ``greybox.cases``).
    """
    return forward_selection_many(
        [_as_greybox(greybox, "forward_selection")],
        candidates,
        starts=starts,
        seed=seed,
        margin=margin,
        patience=patience,
        inherit=inherit,
        retry_bounds=retry_bounds,
        progress=progress,
        **settings,
    )[0]


def forward_selection_many(
    greyboxes: Sequence,
    candidates: str | Sequence[str | RCModel] = "all",
    *,
    starts: int = DEFAULT_STARTS,
    seed: int | None = 0,
    margin: float = 0.0,
    patience: int = 1,
    inherit: bool = True,
    retry_bounds: bool = True,
    progress: Progress | None = None,
    **settings,
) -> list[Selection]:
    """Forward selection on several buildings in lock-step, each step batched over them.

    Each building climbs on its own (its own parents, retries and stop, exactly as
    :func:`forward_selection` on it alone), but the cases of one step — the same model on every
    building still climbing — are fitted together: with identification data of the same length,
    every start of every building in one compiled call (:func:`~jaxbox.select.run_cases`).
    Arguments as :func:`forward_selection`; the candidates are those every building can feed.

    Returns:
        One :class:`Selection` per GreyBox, in order (``elapsed_s``: the whole run).
    """
    say = progress or quiet
    if isinstance(greyboxes, GreyBox | str | bytes | Mapping) or not isinstance(
        greyboxes, Sequence
    ):
        raise TypeError(
            f"forward_selection_many takes a list of buildings (each {_TAKES}); got "
            f"{type(greyboxes).__name__}"
        )
    greyboxes = [_as_greybox(gb, "forward_selection_many") for gb in greyboxes]
    if not greyboxes:
        raise ValueError("forward selection needs at least one GreyBox")
    margin = _fraction(margin, "margin")
    if isinstance(patience, bool) or not isinstance(patience, int | np.integer) or patience < 1:
        raise ValueError(f"patience must be a whole number ≥ 1, got {patience!r}")
    inherit, retry_bounds = _flag(inherit, "inherit"), _flag(retry_bounds, "retry_bounds")
    settings = check_run(starts, seed, settings, progress)
    models = candidate_models(candidates, greyboxes[0].data)
    for gb in greyboxes[1:]:
        feeds = set(m.name for m in candidate_models(candidates, gb.data))
        models = [m for m in models if m.name in feeds]
    say(
        f"forward selection over {len(models)} model(s): "
        + ", ".join(f"{m.name} ({len(m.param_names)})" for m in models)
        + (f", on {len(greyboxes)} buildings in lock-step" if len(greyboxes) > 1 else "")
    )
    several = len(greyboxes) > 1
    climbs = [
        _Climb(
            gb,
            models,
            starts=starts,
            seed=seed,
            margin=margin,
            patience=patience,
            inherit=inherit,
            retry=retry_bounds,
            settings=settings,
            say=(lambda msg, name=gb.name: say(f"{name}: {msg}")) if several else say,
        )
        for gb in greyboxes
    ]
    t0 = time.perf_counter()
    while True:
        step = [(c, c.next_case()) for c in climbs]
        step = [(c, case) for c, case in step if case is not None]
        if not step:
            break
        run_cases(
            [case for _, case in step],
            say,
            catch=True,
            labels=[f"{c.gb.name}: " if several else "" for c, _ in step],
        )
        for c, case in step:
            c.record(case)
    elapsed = time.perf_counter() - t0
    return [c.selection(elapsed) for c in climbs]
