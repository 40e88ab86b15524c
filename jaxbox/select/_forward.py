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
import time
from collections.abc import Sequence

import numpy as np

from ..models import RCModel, get_model, list_models
from ._greybox import Case, GreyBox, Progress, _quiet
from ._guess import state_ranges

__all__ = ["Selection", "forward_selection", "candidate_models"]


@dataclasses.dataclass(frozen=True)
class Selection:
    """Outcome of a forward selection.

    Attributes:
        accepted: name of the accepted case (``None`` when no candidate was valid).
        order: case names in the order they were identified.
        stopped: why the selection stopped, in words.
        skipped: candidate models never identified (after the stop).
        elapsed_s: wall-clock time of the selection [s].
    """

    greybox: GreyBox
    accepted: str | None
    order: tuple[str, ...]
    stopped: str
    skipped: tuple[str, ...]
    elapsed_s: float

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
        }


def candidate_models(candidates, data=None) -> list[RCModel]:
    """Resolve candidates: a list of names/models, a library family name, or ``"all"`` (every
    library model whose inputs and outputs are all columns of ``data``).

    Sorted by number of parameters (stable: library order among equals).
    """
    if isinstance(candidates, str):
        if candidates == "all":
            models = [get_model(n) for n in list_models()]
            if data is not None:
                cols = set(data.columns)
                models = [m for m in models if set(m.inputs) | set(m.outputs) <= cols]
        else:
            models = [get_model(n) for n in list_models(family=candidates)]
    else:
        models = [get_model(m) for m in candidates]
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


def _retry_narrowed(gb: GreyBox, case: Case, pinned, say: Progress) -> Case:
    ranges = state_ranges(case.model, case.ident)
    bounds = dict(case.bounds)
    told = []
    for n in pinned:
        lo, _, hi = ranges[n]
        bounds[n] = (lo, hi)
        told.append(f"{n} in [{lo:.2f}, {hi:.2f}] °C")
    say(f"  {case.name}: initial temperature(s) on a bound; retry with {', '.join(told)}")
    retry = gb.add_case(
        case.model,
        name=f"{case.name}+narrowed",
        guess=case.guess,
        free=case.free,
        fixed=case.fixed,
        bounds=bounds,
        starts=case.starts,
        seed=case.seed,
        train=(str(case.ident.start), str(case.ident.end)),
        valid=None if case.valid is None else (str(case.valid.start), str(case.valid.end)),
        **case.settings,
    )
    retry.parent = case.parent
    retry.notes.append(f"retry of {case.name}: bounds narrowed from the data ({', '.join(told)})")
    case.notes.append(f"initial temperature on its bound; retried as {retry.name}")
    return retry.run(say)


def forward_selection(
    greybox: GreyBox,
    candidates: str | Sequence[str | RCModel] = "all",
    *,
    starts: int = 8,
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
            added to it.
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
    say = progress or _quiet
    if greybox.valid_period is None:
        raise ValueError("forward selection needs validation data; give the GreyBox valid=…")
    if not 0.0 <= margin < 1.0:
        raise ValueError(f"margin must be in [0, 1), got {margin}")
    if patience < 1:
        raise ValueError(f"patience must be at least 1, got {patience}")
    models = candidate_models(candidates, greybox.data)
    say(
        f"forward selection over {len(models)} model(s): "
        + ", ".join(f"{m.name} ({len(m.param_names)})" for m in models)
    )
    t0 = time.perf_counter()
    best: Case | None = None
    order: list[str] = []
    misses = 0
    stopped = "every candidate was identified"
    skipped: tuple[str, ...] = ()
    for k, model in enumerate(models):
        say(f"[{k + 1}/{len(models)}] {model.name}")
        parent = best
        if parent is None and order:  # nothing valid yet: the lowest validation error so far
            run = [greybox.cases[n] for n in order if greybox.cases[n].done]
            parent = min(run, key=lambda c: c.se_cross, default=None)
        if inherit and parent is not None:
            case = greybox.add_case(
                model, guess="parent", parent=parent.name, starts=starts, seed=seed, **settings
            )
        else:
            case = greybox.add_case(model, starts=starts, seed=seed, **settings)
        try:
            case.run(say)
        except (ValueError, FloatingPointError) as err:  # FitError, non-finite post-simulation
            case.notes.append(f"failed: {err}")
            say(f"  {case.name}: failed ({err})")
        order.append(case.name)
        if case.done and retry_bounds and not case.is_valid:
            pinned = _pinned_unmeasured_states(case)
            if pinned:
                try:
                    retry = _retry_narrowed(greybox, case, pinned, say)
                    order.append(retry.name)
                    if retry.is_valid or retry.se_cross < case.se_cross:
                        case = retry
                except (ValueError, FloatingPointError) as err:
                    say(f"  retry failed ({err})")
        improved = (
            case.done
            and case.is_valid
            and np.isfinite(case.se_cross)
            and (best is None or case.se_cross < (1.0 - margin) * best.se_cross)
        )
        if improved:
            best, misses = case, 0
            continue
        if best is None:  # nothing valid yet: keep climbing
            continue
        misses += 1
        if misses >= patience and k + 1 < len(models):
            why = "not valid" if not case.is_valid else "did not improve the validation SE"
            stopped = f"stopped after {case.name}: {misses} candidate(s) in a row {why}" + (
                f" by {100 * margin:g} %" if margin and case.is_valid else ""
            )
            skipped = tuple(m.name for m in models[k + 1 :])
            break
    accepted = greybox.best(valid_only=True)
    names = set(order)
    if accepted is not None and accepted.name not in names:
        accepted = min(
            (greybox.cases[n] for n in order if greybox.cases[n].is_valid),
            key=lambda c: c.se_cross,
            default=None,
        )
    elapsed = time.perf_counter() - t0
    say(
        f"accepted: {accepted.name if accepted else 'none (no valid model)'}; {stopped} "
        f"({elapsed:.0f} s)"
    )
    return Selection(
        greybox=greybox,
        accepted=None if accepted is None else accepted.name,
        order=tuple(order),
        stopped=stopped,
        skipped=skipped,
        elapsed_s=elapsed,
    )
