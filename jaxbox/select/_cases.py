"""One identification attempt, :class:`Case`, and running several at once (:func:`run_cases`).

A :class:`Case` is one identification attempt: a model structure, its identification and
validation slices of a building's data, an initial guess and where it came from, the solver
settings, and once run the fit, its post-simulation validation and its validity verdict.
:func:`run_cases` fits every start of several cases in as few compiled calls as their shapes
allow. The lowest floor of :mod:`jaxbox.select`: it imports nothing else of the package but the
initial guesses.
"""

from __future__ import annotations

import dataclasses
import numbers
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..fit import DEFAULT_CONCENTRATION, DEFAULT_STARTS
from ..fit._fit import check_continued, check_homotopy, check_polish
from ..models import RCModel
from ._guess import Guess, lhs_starts

__all__ = [
    "Case",
    "Progress",
    "SETTINGS",
    "check_seed",
    "check_settings",
    "check_starts",
    "check_whole",
    "run_cases",
    "unit_doubts",
    "idle_heat_inputs",
    "verdict_text",
]

Progress = Callable[[str], None]

#: Solver settings a case passes on to :func:`jaxbox.fit.fit_batch`.
FIT_SETTINGS = (
    "max_steps",
    "rtol",
    "atol",
    "concentration",
    "weights",
    "simulator",
    "max_gap",
    "homotopy",
    "continued",
    "polish",
)
#: Settings of a case: the solver's, and ``postsim``, the post-simulation method of its
#: validation (``"diffrax"``, adaptive, by default; ``"exact"``, the matrix exponential).
SETTINGS = (*FIT_SETTINGS, "postsim")
#: the simulators of a fit and the post-simulation methods of a validation
SIMULATORS = ("exact", "diffrax")
#: the most starts of one case and the most solver iterations per start (the command line's
#: limits of ``--starts`` and ``--max-steps``)
MAX_STARTS = 100_000
MAX_STEPS = 1_000_000


def check_whole(value, name: str, lo: int, hi: int | None = None) -> int:
    """An integer argument in ``[lo, hi]``, as an ``int``: any integral number (``int``, numpy's
    ``int64``…) is taken; a bool, a float (even ``2.0``) or text is a ``TypeError``, one out of
    range a ``ValueError``, each naming ``name``."""
    span = f"from {lo} to {hi}" if hi is not None else f"≥ {lo}"
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be a whole number {span}, got {value!r}")
    if value < lo or (hi is not None and value > hi):
        raise ValueError(f"{name} must be a whole number {span}, got {value}")
    return int(value)


def check_starts(value, name: str = "starts") -> int:
    """The number of starts of a case: a whole number from 1 to :data:`MAX_STARTS`."""
    return check_whole(value, name, 1, MAX_STARTS)


def check_seed(value, name: str = "seed") -> int | None:
    """The seed of the Latin hypercube of a case: ``None`` or a whole number ≥ 0."""
    return None if value is None else check_whole(value, name, 0)


def _tolerance(value, name: str) -> float:
    """A solver tolerance: a finite number ≥ 0."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        raise TypeError(f"{name} must be a number ≥ 0, got {value!r}")
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"{name} must be a finite number ≥ 0, got {value!r}")
    return float(value)


def check_settings(settings: Mapping) -> dict:
    """The settings of a case (:data:`SETTINGS`), checked before anything is declared or run:
    unknown names, and ``max_steps``, ``rtol``, ``atol``, ``concentration``, ``simulator``,
    ``postsim``, ``homotopy``, ``continued`` and ``polish`` of the wrong type or out of range,
    name the setting
    (``weights`` and ``max_gap`` are checked with the estimation problem and the data)."""
    bad = [str(k) for k in settings if k not in SETTINGS]
    if bad:
        raise TypeError(f"unknown setting(s) {', '.join(bad)}; settings are {', '.join(SETTINGS)}")
    out = dict(settings)
    if "max_steps" in out:
        out["max_steps"] = check_whole(out["max_steps"], "max_steps", 1, MAX_STEPS)
    for key in ("rtol", "atol", "concentration"):
        if key in out:
            out[key] = _tolerance(out[key], key)
    for key in ("simulator", "postsim"):
        if key in out and (not isinstance(out[key], str) or out[key] not in SIMULATORS):
            raise ValueError(
                f"{key} must be one of {', '.join(map(repr, SIMULATORS))}, got {out[key]!r}"
            )
    if "homotopy" in out:  # a FitError (a ValueError) naming the setting
        out["homotopy"] = check_homotopy(out["homotopy"])
    if "continued" in out:
        out["continued"] = check_continued(out["continued"], 1)[0]
    if "polish" in out:
        out["polish"] = check_polish(out["polish"], 1)[0]
    return out


def data_checks(ranges, stuck_hours) -> dict:
    """The options of a verdict's data check (:func:`~jaxbox.validate.check_validity`'s
    ``data_overrides`` and ``stuck_hours``) from the plausibility options the data were taken
    with: ``ranges`` per column (empty: the defaults) and ``stuck_hours``."""
    return {"data_overrides": dict(ranges) or None, "stuck_hours": stuck_hours}


def quiet(msg: str) -> None:
    """A progress callback that says nothing."""


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
            ``weights``, ``simulator``, ``max_gap``, ``homotopy``, ``continued``: how many
            starts, the first, take the continuation as well; ``polish``: how many of the best
            starts are solved to ``rtol`` after all were solved to a looser tolerance;
            ``postsim``).
        parent: name of the case the guess was inherited from.
        notes: what happened on the way (a retry with narrowed bounds, …).
        result: the :class:`~jaxbox.fit.FitResult` once run.
        validation: its :class:`~jaxbox.validate.Validation` (auto and cross).
        verdict: its :class:`~jaxbox.validate.Verdict`.
        timing: ``fit_s``, ``validate_s``, ``verdict_s`` [s] of the run.
        data_checks: how the verdict checks the case's data, the GreyBox's plausibility options
            (``data_overrides``: its ``ranges``; ``stuck_hours``), so that data the GreyBox
            accepted are not refused again in the verdict.
    """

    name: str
    model: RCModel
    ident: Any
    valid: Any
    guess: Guess
    free: tuple[str, ...] | None = None
    fixed: dict = dataclasses.field(default_factory=dict)
    bounds: dict = dataclasses.field(default_factory=dict)
    starts: int = DEFAULT_STARTS
    seed: int | None = 0
    settings: dict = dataclasses.field(default_factory=dict)
    parent: str | None = None
    notes: list = dataclasses.field(default_factory=list)
    result: Any = None
    validation: Any = None
    verdict: Any = None
    timing: dict = dataclasses.field(default_factory=dict)
    data_checks: dict = dataclasses.field(default_factory=dict)

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
            concentration=self.settings.get("concentration", DEFAULT_CONCENTRATION),
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

    @property
    def postsim(self) -> str:
        """The post-simulation method of the validation (``settings["postsim"]``)."""
        return self.settings.get("postsim", "diffrax")

    def _request(self) -> dict:
        """The :func:`jaxbox.fit.fit_batch` request of this case."""
        opts = {k: v for k, v in self.settings.items() if k in FIT_SETTINGS}
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

    def _complete(self, result, fit_s: float, say: Progress, judge: bool = True) -> Case:
        """Post-simulate a fitted case and (with ``judge``) judge it."""
        from ..validate import validate

        self.result = result
        t1 = time.perf_counter()
        self.validation = validate(self.result, self.valid, method=self.postsim)
        t2 = time.perf_counter()
        self.timing = {
            "fit_s": fit_s,
            "compile_s": float(self.result.timing.get("compile_s", 0.0)),
            "validate_s": t2 - t1,
        }
        if self.result.timing.get("batch", 1) > 1:
            self.timing["batch"] = int(self.result.timing["batch"])
        if judge:
            self.assess()
        verdict = (
            "not judged" if self.verdict is None else ("valid" if self.is_valid else "not valid")
        )
        say(
            f"  {self.name}: {self.result.starts.status_summary()}; RMSE auto "
            f"{self.se_auto:.3f} K, cross {fmt_se(self.se_cross)} K, {verdict} "
            f"({fit_s + time.perf_counter() - t1:.1f} s)"
        )
        return self

    def assess(self) -> Case:
        """Intervals (σ²(JᵀJ)⁻¹) and the validity verdict of a fitted, post-simulated case."""
        from ..validate._verdict import verdict_of

        self._require_run()
        t2 = time.perf_counter()
        self.verdict = verdict_of(self.result, self.validation, **self.data_checks)
        self.timing["verdict_s"] = time.perf_counter() - t2
        return self

    def judge(self, **options) -> Case:
        """Judge validity again with other :func:`~jaxbox.validate.check_validity` options."""
        from ..validate import check_validity

        self._require_run()
        self.verdict = check_validity(
            self.result, **{"validation": self.validation, **self.data_checks, **options}
        )
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
    def score(self) -> float:
        """What selection compares [K]: :attr:`se_cross`, or :attr:`se_auto` for a case
        without validation data (``valid=False``, ``--validate none``)."""
        return self.se_auto if self.valid is None else self.se_cross

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
    judge: bool = True,
    inputs: int = 0,
    sizes: Mapping[str, int] | Sequence[Mapping[str, int]] | None = None,
) -> list[Case]:
    """Run several cases together: every start of every case in as few compiled calls as the
    shapes allow (one, for cases of the same shape — e.g. one model on several buildings).

    Args:
        cases: cases not run yet (of one or several GreyBoxes).
        progress: called with one line of text per step.
        catch: record a case that fails (every start failed, non-finite post-simulation) in its
            ``notes`` and go on, instead of raising.
        labels: a prefix per case for the progress lines (e.g. the building).
        judge: compute each case's intervals and verdict (``False``: post-simulate only;
            :meth:`Case.assess` judges later).
        inputs: input columns to pad the batch to at least (the most of any call to come, so
            that the calls share compiled programs; see :func:`jaxbox.fit.fit_batch`).
        sizes: other sizes to pad the batch to at least (free and fixed parameters, states,
            edges, …; an earlier batch's ``timing["sizes"]``, so that this one runs its
            compiled program), or a sequence of such sizes, the first that holds the batch
            (see :func:`jaxbox.fit.solve_jobs`).

    Returns:
        The cases, run (a failed one, with ``catch``, has no result).
    """
    from ..fit import FitError, fit_batch

    say = progress or quiet
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
    # bucketed: the next call (a search's next step, a chain's next model) of neighbouring
    # sizes reuses this one's compiled program
    several = [sizes] if sizes is None or isinstance(sizes, Mapping) else list(sizes)
    least = [
        {**(m or {}), "inputs": max(int(inputs), int((m or {}).get("inputs", 0)))} for m in several
    ]
    outcomes = fit_batch(requests, errors="return", bucket=least[0] if len(least) == 1 else least)
    fit_s = (time.perf_counter() - t0) / max(1, len(cases))
    for case, outcome, told in zip(cases, outcomes, tell, strict=True):
        try:
            if isinstance(outcome, FitError):
                raise outcome
            case._complete(outcome, fit_s, told, judge)
        except (ValueError, FloatingPointError) as err:  # FitError, non-finite post-simulation
            if not catch:
                raise
            case.result = case.validation = case.verdict = None
            case.notes.append(f"failed: {err}")
            told(f"  {case.name}: failed ({err})")
    return list(cases)


def verdict_text(cases: Mapping[str, Case], names, accepted: Case | None) -> str:
    """What a selection over ``names`` (keys of ``cases``) accepted, in words: the accepted
    case's name, or why none was: no valid model among those identified (first the doubt on
    an input's unit that may explain it, :func:`unit_doubts`), or none identified."""
    if accepted is not None:
        return accepted.name
    if any(cases[n].done for n in names):
        judged = [cases[n] for n in names]
        doubts = idle_heat_inputs(judged) + unit_doubts(judged)
        return f"none (no valid model{''.join(f'; {d}' for d in doubts[:1])})"
    return "none (no model could be identified)"


def unit_doubts(cases: Sequence[Case]) -> list[str]:
    """The warnings on an input's unit (``kilowatt``, ``fahrenheit`` findings of
    :func:`jaxbox.data.find_implausible` on the identification data) that may explain why
    ``cases`` are not valid: those about an input whose gain (a parameter that scales the input
    and nothing else, such as a solar aperture) sits on a bound in one of the cases. Each
    names the parameter and the option that fixes the unit."""
    from ..data import find_implausible

    at_bound: dict[str, set[str]] = {}  # input -> parameters on a bound
    for case in cases:
        flags = getattr(case.verdict, "flags", ()) if case.done else ()
        for flag in flags:
            if flag.kind == "at_bound":
                for p in flag.parameters:
                    for name in _gain_inputs(case.model, case.result.params, p):
                        at_bound.setdefault(name, set()).add(p)
    out: list[str] = []
    for case in cases:
        if not at_bound:
            break
        names = [n for n in at_bound if n in case.ident.columns]
        for f in find_implausible(case.ident, columns=names) if names else ():
            if f.kind in ("kilowatt", "fahrenheit") and not f.severe:
                text = (
                    f"{f.message.rstrip('.')} ({', '.join(sorted(at_bound[f.column]))} on a bound)"
                )
                if text not in out:
                    out.append(text)
        if out:
            break
    return out


def idle_heat_inputs(cases: Sequence[Case]) -> list[str]:
    """One sentence when every heat input of ``cases``' models is zero throughout their
    identification data (each power input [W] they take, e.g. ``Q_hea``: the heating was
    off) or when they take none (no heat input measured); else none. With no heat input the
    data fix the time constants and the ratios of the parameters but not their scale:
    scaling every capacity and solar aperture by k and every resistance by 1/k leaves the
    temperatures unchanged, so neither the heat-loss coefficient nor the capacities are
    identifiable, whatever the structure. (A constant heat input that is not zero does set
    the scale, through the mean temperature it holds; a heat demand as the output too.)"""
    from ..data import signal_unit
    from ..data._errors import list_names
    from ..data._suggest import suggestion_text

    if not cases:
        return []
    powers: dict[str, np.ndarray] = {}
    for case in cases:
        if any(signal_unit(name) == "W" for name in case.model.outputs):
            return []  # a heat demand as the output: its scale is measured
        for name in case.model.inputs:
            if signal_unit(name) == "W" and name in case.ident.columns and name not in powers:
                x = np.asarray(case.ident[name], dtype=float)
                powers[name] = x[np.isfinite(x)]
    if not powers:
        columns = cases[0].ident.columns
        unused = [c for c in columns if signal_unit(c) == "W"]
        # columns under names no model reads: perhaps the heating, not mapped
        unread = [c for c in columns if signal_unit(c) is None]
        if unused:
            what = f"none of the models takes a heat input ('{unused[0]}' is in the data)"
        elif unread:
            what = (
                "no heat input is measured (no column such as 'Q_hea'; the data also have "
                f"{list_names(unread, limit=6)}, under names no model reads: if one of them is "
                "the heating, map yours with columns={'Q_hea': 'your_col'} in jaxbox.data.load"
                f"{suggestion_text(['Q_hea'], unread)})"
            )
        else:
            what = "no heat input is measured (no column such as 'Q_hea')"
        return [
            f"{what}: the data fix the time constants but not the heat-loss coefficient or "
            "the capacities (only their ratios); add the heating power, or fix a capacity"
        ]
    if any(len(x) == 0 or np.any(x != 0.0) for x in powers.values()):
        return []
    names = " and ".join(f"'{n}'" for n in powers)
    return [
        f"{names} {'is' if len(powers) == 1 else 'are'} 0 W throughout the identification "
        "data: with no heat input, the data fix the time constants but not the heat-loss "
        "coefficient or the capacities (only their ratios); identify on a period with "
        "heating, or fix a capacity"
    ]


def _gain_inputs(model: RCModel, params: Mapping[str, float], name: str) -> tuple[str, ...]:
    """The inputs that parameter ``name`` scales alone: its change moves columns of B (or D)
    and leaves A unchanged; empty for any other parameter."""
    theta = dict(params)
    if name not in theta:
        return ()
    a0, b0, _, d0 = model.state_space_numpy(theta)
    theta[name] = theta[name] * 1.5 if theta[name] != 0 else 1.0
    a1, b1, _, d1 = model.state_space_numpy(theta)
    if not np.allclose(a0, a1, rtol=1e-12, atol=0):
        return ()
    moved = ~np.all(np.isclose(b0, b1, rtol=1e-12, atol=0), axis=0)
    moved |= ~np.all(np.isclose(d0, d1, rtol=1e-12, atol=0), axis=0)
    return tuple(str(model.inputs[k]) for k in np.flatnonzero(moved))


def fmt_se(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{x:.3f}"
