"""Structure search: grow a model from the component grammar while the data ask for it.

From the simplest structures the data can drive (:func:`jaxbox.models.grammar.roots`), each step
identifies every one-component extension (:func:`jaxbox.models.grammar.extensions`) of the
current best structure, or of a beam of the ``beam`` best, all in one batched call
(:func:`~jaxbox.select.run_cases`), each child starting from its parent's optimum. Children are
ranked by the criterion:

- ``"cv"`` (default): the simulation error on the validation data (on the identification data
  when there is none), among valid candidates;
- ``"aic"``, ``"bic"``: Akaike's or Schwarz's criterion of the output-error fit on the
  identification data (Gaussian likelihood, one variance per output);
- ``"lr"``: a likelihood-ratio test of each child against its parent (nested: one component
  more), significant at ``alpha``.

A child *improves* when it is valid and beats its parent significantly: a validation SE lower by
at least ``margin`` (relative), a lower AIC/BIC, or a significant likelihood ratio. The beam of
the next step holds the best improving children. An invalid child prunes its branch, not the
search; a child that does not improve is not grown further.

**Reduce, don't reject.** A child made invalid only by parameters that sit where their
component vanishes (an aperture or gain at 0, a fraction at 0 or 1, a resistance on its upper
bound, a capacity on its lower bound, an offset, gain or aperture whose interval spans zero,
an initial temperature the outputs forget) is identified again in the same step with those
parameters fixed there, and the reduced structure is judged against the same parent
(:func:`~jaxbox.select._reduce.reduction`: the grammar's smaller structure where whole
components vanish). The tree shows each reduction.

When no child of a beam case improves, the search looks one component further from that case
before it gives it up: the ``lookahead`` children that fit the identification data best
(relative to it, at least 10 % better) are grown all the same as *stepping stones*, and their
children are judged against the case. Components that help only together (an envelope capacity
and an internal mass: either alone can fit worse on validation than neither) are found that
way. Then it looks one component back: the structures one component smaller than the case
(:func:`jaxbox.models.reductions`) are identified, judged against it, and one that improves
carries the search on (a component taken early, a facade's sun for what an envelope and a mass
explain together, may be worse than none once they are in). A case is stuck on its own: with a
beam of two, the other case's improving children do not spare it these looks. The search stops
when none of these steps improves for any beam case.

With two measured zones the roots are both zones as states (coupled) and each zone alone with
the other's measured temperature as a boundary input (a zone held by its thermostat behaves as
one). Each set of predicted zones is a *lineage* with its own beam: candidates are compared by
the criterion within a lineage only. Every root is grown, valid or not (the simplest model of a
set of zones is often too simple to be valid, and a component more may make it so). The accepted
model is the best valid candidate of its lineage; between lineages, the one predicting more
zones, unless another predicts the zones they share far better (mean RMSE relative to each
zone's measured spread, lower by a third: a zone fed the other zone's measured temperature has
an edge it does not owe to its structure); between lineages of as many zones, the lower such
relative RMSE.

A zone held by its thermostat (its temperature barely varies, the heating does) gives the
temperature form little to predict: there the search also fits the heat-demand form (the
heating from the zone's measured temperature through the same network) and the steady state
(daily means), and accepts the form the data determine (:mod:`jaxbox.select._forms`);
:attr:`Search.form` says which, :attr:`Search.form_model` holds a model of another form.

Validity is judged lazily: a candidate's intervals and verdict are computed only when its
criterion value could make it improve, which keeps the cost of a step close to the cost of its
batched fits.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import threading
import time

import numpy as np
from scipy import stats

from ..fit import DEFAULT_STARTS
from ..models import REFERENCE_HLC
from ..models._grammar import (
    Grammar,
    Structure,
    extensions,
    parse_structure,
    reductions,
    roots,
)
from ._cases import Case, Progress, check_whole, quiet, run_cases, verdict_text
from ._forms import FormChoice, choose_form
from ._forward import (
    Selection,
    _as_greybox,
    _fraction,
    check_run,
)
from ._guess import parent_guess
from ._reduce import Reduction, reduction
from ._scale import building_scale

__all__ = ["SearchNode", "Search", "structure_search", "CRITERIA"]

#: criteria of :func:`structure_search`
CRITERIA = ("cv", "aic", "bic", "lr")
#: between lineages, how much lower (relative) the error on the shared zones of a model
#: predicting fewer zones must be for it to be accepted
LINEAGE_MARGIN = 0.33


@dataclasses.dataclass(frozen=True)
class SearchNode:
    """One candidate of a structure search.

    Attributes:
        case: case name in the GreyBox.
        structure: canonical structure name.
        parent: the case it extends (``None`` for a root).
        added: the component it adds to its parent, in words.
        depth: 0 for a root.
        criterion: its criterion value (SE [K] for ``cv``; AIC/BIC; the likelihood-ratio
            p-value for ``lr``).
        status: ``"accepted"``, ``"grown"`` (in a beam), ``"improves"`` (not in the beam),
            ``"stepping stone"`` (grown for the lookahead without improving), ``"no
            improvement"``, ``"not valid"``, ``"failed"`` or ``"not judged"``.
        why: the reason in words (the verdict's first reason, the comparison with the parent).
    """

    case: str
    structure: str
    parent: str | None
    added: str
    depth: int
    criterion: float
    status: str
    why: str = ""

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["criterion"] = None if not math.isfinite(self.criterion) else self.criterion
        return d


@dataclasses.dataclass(frozen=True)
class Search(Selection):
    """Outcome of a :func:`structure_search`: a :class:`~jaxbox.select.Selection` with the tree.

    Attributes:
        criterion: the criterion used.
        tree: every candidate, in the order identified.
        margin: the relative decrease of the criterion that counted as an improvement (also
            the margin of the near-best models of :func:`~jaxbox.validate.hlc_interval`).
        scale: the building's size the structures were built for
            (:attr:`jaxbox.models.Grammar.scale`): 1 for a building up to
            :data:`~jaxbox.models.REFERENCE_HLC`, else its heat input per kelvin over it.
    """

    criterion: str = "cv"
    tree: tuple[SearchNode, ...] = ()
    margin: float = 0.02
    choice: FormChoice = FormChoice()
    scale: float = 1.0

    @property
    def form(self) -> str:
        """The form accepted: ``"temperature"`` (the case :attr:`accepted`), ``"heat demand"``
        or ``"steady state"`` (the model in :attr:`form_model`); see
        :mod:`jaxbox.select._forms`."""
        return self.choice.form

    @property
    def form_model(self):
        """The accepted heat-demand or steady-state model (``None`` for the temperature form or
        when none is valid)."""
        return self.choice.model

    def to_dict(self) -> dict:
        d = super().to_dict()
        d.update(criterion=self.criterion, tree=[n.to_dict() for n in self.tree])
        d["scale"] = self.scale
        d.update(self.choice.to_dict())
        return d

    def children(self) -> dict[str | None, list[SearchNode]]:
        """Parent case name (``None`` for the roots) -> its candidates, in the order run."""
        out: dict[str | None, list[SearchNode]] = {}
        for n in self.tree:
            out.setdefault(n.parent, []).append(n)
        return out

    def tree_text(self) -> str:
        """The search tree as indented text (one line per candidate)."""
        children = self.children()
        lines: list[str] = []

        def walk(parent, indent):
            for n in children.get(parent, []):
                value = "n/a" if not math.isfinite(n.criterion) else f"{n.criterion:.4g}"
                mark = "*" if n.case == self.accepted else " "
                why = f" ({n.why})" if n.why else ""
                retry = " (reduced)" if n.case != n.structure else ""
                lines.append(
                    f"{mark} {'  ' * indent}{n.structure}{retry}  [{self.criterion} {value}] "
                    f"{n.status}{why}"
                )
                walk(n.case, indent + 1)

        walk(None, 0)
        hd = self.choice.heat_demand
        if hd is not None and hd.tree:
            lines.append("heat-demand form (the heating from the zone's measured temperature):")
            chosen = self.choice.model is not None and self.choice.model is hd.best
            lines += ["  " + line for line in hd.tree_text(chosen).splitlines()]
        if self.choice.steady is not None:
            lines.append(self.choice.steady.summary())
        if self.choice.why:
            lines.append(f"form accepted: {self.choice.form} ({self.choice.why})")
        return "\n".join(lines)


# ---- criteria -----------------------------------------------------------------------------------


def _loglik(case: Case) -> tuple[float, int]:
    """Gaussian log-likelihood of the output-error fit on the identification data (one variance
    per output, at its maximum-likelihood value) and the number of samples."""
    e = np.asarray(case.validation.residuals_auto, dtype=float)
    ll, n = 0.0, 0
    for j in range(e.shape[1]):
        ej = e[:, j][np.isfinite(e[:, j])]
        nj = ej.size
        s2 = max(float(np.mean(ej**2)), 1e-300)
        ll += -0.5 * nj * (math.log(2.0 * math.pi * s2) + 1.0)
        n += nj
    return ll, n


def _relative_rmse(case: Case, outputs) -> float:
    """Mean over ``outputs`` of the validation RMSE (identification RMSE without validation
    data) divided by that output's measured spread: comparable across models of different
    zones."""
    v = case.validation
    rmse, y = (v.rmse_cross, v.y_cross) if case.valid is not None else (v.rmse_auto, v.y_auto)
    out = []
    for j, o in enumerate(v.outputs):
        if o in outputs:
            spread = float(np.nanstd(np.asarray(y)[:, j]))
            out.append(float(rmse[o]) / max(spread, 1e-9))
    return float(np.mean(out)) if out else math.inf


class _Judge:
    """The criterion of a search: values, and whether a child improves on its parent."""

    def __init__(self, criterion: str, margin: float, alpha: float) -> None:
        self.criterion, self.margin, self.alpha = criterion, margin, alpha

    def value(self, case: Case) -> float:
        if not case.done or not np.isfinite(case.score):
            return math.inf
        if self.criterion == "cv":
            return float(case.score)
        ll, n = _loglik(case)
        k = case.n_params
        if self.criterion == "aic":
            return -2.0 * ll + 2.0 * k
        if self.criterion == "bic":
            return -2.0 * ll + k * math.log(max(n, 1))
        return -ll  # lr: ranks by likelihood; the test is in improves()

    def improves(self, child: Case, parent: Case | None) -> tuple[bool, str]:
        """Whether ``child`` beats ``parent`` significantly (before validity), and why."""
        if not child.done or not np.isfinite(child.score):
            return False, "failed"
        if parent is None:
            return True, "root"
        c, p = self.value(child), self.value(parent)
        if self.criterion == "cv":
            ok = c < (1.0 - self.margin) * p
            return ok, f"SE {c:.4g} K against {p:.4g} K of {parent.model.name}"
        if self.criterion in ("aic", "bic"):
            return c < p, f"{self.criterion.upper()} {c:.1f} against {p:.1f}"
        dk = max(child.n_params - parent.n_params, 1)
        stat = max(2.0 * (p - c), 0.0)
        pval = float(stats.chi2.sf(stat, dk))
        return pval < self.alpha, f"LR {stat:.1f} on {dk} df, p = {pval:.2g}"


def _rank(case: Case, judge: _Judge) -> float:
    """Sort key within a lineage (candidates of the same zones): the criterion."""
    return judge.value(case)


def _lineage(case: Case) -> tuple[str, ...]:
    """The zones a candidate predicts: candidates are compared by the criterion within one."""
    return tuple(case.model.outputs)


def _accept(valid: list[Case], judge: _Judge) -> Case | None:
    """The accepted model: the best valid candidate of each lineage by the criterion; between
    lineages (models predicting different zones), the one predicting more zones unless another
    predicts the zones they share far better (relative RMSE lower by :data:`LINEAGE_MARGIN`: a
    model fed the other zone's measured temperature has an edge it does not owe to its
    structure). Between lineages of as many zones, the lower relative RMSE leads. A model of
    both zones gives way to the model of one zone fed the other's measured temperature when the
    best model of that other zone alone cuts its link back (:func:`_coupling_cut`): that zone
    does not depend on the first, it is an input."""
    best: dict[tuple, Case] = {}
    for c in valid:
        k = _lineage(c)
        if k not in best or _rank(c, judge) < _rank(best[k], judge):
            best[k] = c
    if not best:
        return None
    # more zones first; between lineages of as many zones, the error relative to the spread of
    # the zones each predicts (the SE of a zone held by its thermostat is small for want of
    # anything to predict, not for a better model)
    order = sorted(
        best.values(),
        key=lambda c: (-len(_lineage(c)), _relative_rmse(c, set(_lineage(c))), _rank(c, judge)),
    )
    champion = order[0]
    for other in order[1:]:
        common = set(_lineage(champion)) & set(_lineage(other))
        if not common:  # no zone in common: their mean relative errors
            common_c, common_o = set(_lineage(champion)), set(_lineage(other))
        else:
            common_c = common_o = common
        a, b = _relative_rmse(champion, common_c), _relative_rmse(other, common_o)
        if b < (1.0 - LINEAGE_MARGIN) * a:
            champion = other
    if len(_lineage(champion)) > 1:
        # a zone whose best model cuts its link to the other zone does not depend on it (held
        # by its own thermostat, say): it is a measured input of the other zone, not a state
        for lineage, case in best.items():
            if len(lineage) == 1 and _coupling_cut(case):
                rest = [o for o in champion.model.outputs if o not in lineage]
                if len(rest) == 1 and (rest[0],) in best:
                    return best[(rest[0],)]
    return champion


def _coupling_cut(case: Case) -> bool:
    """Whether a one-zone model fed the other zone's measured temperature has its resistance
    to it (``R_bou``) cut: fixed at, or estimated on, its upper bound."""
    if "R_bou" not in case.model.param_names or not any(
        i.startswith("T_zon") for i in case.model.inputs
    ):
        return False
    if "R_bou" in case.fixed:
        upper = case.bounds.get("R_bou", (None, case.model.parameter("R_bou").upper))[1]
        return case.fixed["R_bou"] >= upper * (1.0 - 1e-9)
    return case.result.bound_position().get("R_bou", 0.0) > 0.99


# ---- the search ---------------------------------------------------------------------------------

#: how many of a grown candidate's starts (the first ones; the first is its parent's optimum)
#: are solved along the continuation as well as the output error, the others along the output
#: error alone (a root's starts take both routes): the default of the search's ``continued=``,
#: ``None`` for all. Fewer save steps but lose models the continuation finds from the other
#: starts: one start halves the twin houses' fits with the same accepted models, yet a detailed
#: building then accepts a worse model (0.240 K against 0.170 K), and half of the starts lose a
#: two-zone zoo building's true structure (``benchmarks/NOTES.md``)
GROWN_CONTINUED = None
#: how many of each candidate's best starts are solved on to the fit's tolerance after every
#: start was solved to a looser one (:data:`~jaxbox.fit._fit.POLISH_RTOL`; see
#: :func:`~jaxbox.fit.solve_jobs`): the default of the search's ``polish=``, ``None`` for every
#: start to the fit's tolerance. A candidate is judged by its best start; the others' last
#: digits are steps the search does not need (twin house N2: the same accepted model for 51 k
#: Levenberg–Marquardt steps instead of 113 k, ``benchmarks/NOTES.md``)
SEARCH_POLISH = 2
#: the least sizes of the search's batched fits (:func:`~jaxbox.fit.solve_jobs`'s ``bucket``):
#: the roots and first steps run the program of the second step's sizes instead of one of their
#: own (a compilation at the start, where nothing runs beside it, costs more than their padded
#: steps); every later batch pads to the cheapest sizes a batch of the search ran at that hold
#: it, so that the search compiles one fit program per size it grows to and none for a step
#: that shrinks (``benchmarks/NOTES.md``)
SEARCH_SIZES = {"free": 16, "states": 4}
#: the search compiles the next size ahead (in a background thread, while it fits and judges
#: the current one) once a step's candidates come within this many free parameters, or this
#: many states, of the sizes its batches run at (in that size only: one more bucket of free
#: parameters, of states, or of both)
AHEAD_FREE, AHEAD_STATES = 4, 0


def _ahead(sizes: dict[str, int], free: bool, states: bool) -> dict[str, int]:
    """The size a search's batches grow to once they outgrow ``sizes``: one bucket more free
    parameters (``free``) and states (``states``, see :data:`~jaxbox.fit._fit.BUCKETS`), the
    other sizes kept."""
    from ..fit._fit import BUCKETS

    return {
        **sizes,
        "free": sizes.get("free", 0) + BUCKETS["free"] * free,
        "states": sizes.get("states", 0) + BUCKETS["states"] * states,
    }


def _cost(sizes: dict[str, int]) -> tuple[int, ...]:
    """What a step of a batch of these sizes costs, to order them (the sensitivities: states²
    × free parameters a sample)."""
    return (sizes.get("states", 0) ** 2 * sizes.get("free", 0), *sorted(sizes.items()))


def _compile_sensitivities(case: Case) -> None:
    """The shared sensitivity program (the parameter intervals' and verdicts') of ``case``'s
    problem compiled and kept (a background thread's work while the search's first fit
    compiles: it is needed right after that fit; a failure is not reported here, the interval
    that needs the program compiles it and reports it)."""
    from ..fit._batch import request_problem
    from ..validate._uncertainty import prepare_sensitivities

    try:
        # (no warnings from this thread: the fit gives the data's, on the main thread)
        prepare_sensitivities(*request_problem(case._request(), warn=False))
    except Exception:  # noqa: BLE001 - compiled again, and reported, where it is needed
        pass


def _compile_ahead(requests: list[dict], sizes: dict[str, int]) -> None:
    """The fit program of ``sizes`` compiled and kept (a background thread's work: a failure
    is not reported here, the batch that needs the program compiles it and reports it)."""
    from ..fit import compile_batch

    try:
        compile_batch(requests, bucket=sizes)
    except Exception:  # noqa: BLE001 - compiled again, and reported, where it is needed
        pass


#: how many times a step reduces what its reductions left invalid (each round one batched call)
REDUCTION_ROUNDS = 3
#: identification windows with more samples than this, at a step of at most FINE_STEP [s], get a
#: note that means over a longer step search faster
FINE_SAMPLES = 2000
FINE_STEP = 1200.0


def fine_sampling_note(ident) -> str | None:
    """A note for an identification window of many short steps (more than
    :data:`FINE_SAMPLES` samples at most :data:`FINE_STEP` apart): every candidate is fitted
    to all of them, so the search's fits take time in proportion; hourly means keep what the
    grammar's slow modes show. ``None`` otherwise."""
    n, step = len(ident), float(getattr(ident, "step", math.nan))
    if n <= FINE_SAMPLES or not step <= FINE_STEP:
        return None
    minutes = f"{step / 60:.3g}-minute"
    return (
        f"note: {n} samples at a {minutes} step: every candidate is fitted to all of them, and "
        "the fits take time in proportion; hourly means keep what the building's slower modes "
        "show and search several times faster (twin house N2: the same accepted model at 10 "
        "minutes and hourly, benchmarks/VARIANTS.md): resample='1h' (command line: "
        "--resample 1h)"
    )


class _Search:
    """One structure search: its candidates and the steps that make them (see the module).

    ``propose`` (:meth:`extensions`, :meth:`removals`, stepping stones), ``identify`` (one
    batched call a step), ``judge`` (the criterion, then the verdict of what could improve),
    ``reduce`` (:func:`~jaxbox.select._reduce.reduction`), ``choose`` (:func:`_accept`).
    """

    def __init__(self, gb, grammar: Grammar, judge: _Judge, *, beam, lookahead, max_depth, kw, say):
        self.gb, self.grammar, self.rule = gb, grammar, judge
        self.beam, self.lookahead, self.max_depth = beam, lookahead, max_depth
        # ``continued`` applies to the grown candidates only (a root's starts take both routes)
        self.grown = kw.get("continued", GROWN_CONTINUED)
        self.kw = {k: v for k, v in kw.items() if k != "continued"}
        self.say = say
        self.nodes: dict[str, dict] = {}  # case name -> SearchNode fields
        self.seen: set[str] = set()  # structures (and reduced problems) declared
        self.reduced: dict[str, str] = {}  # case name -> what it was reduced to, in words
        self.widest = 0  # the most input columns of a step so far: later steps pad to it
        # the sizes the search's batches were padded to (each a compiled program): a batch pads
        # to the cheapest of them that holds it, or to the next size (compiled ahead in a
        # thread) once it outgrows them all
        self.used: list[dict[str, int]] = []
        self.next: dict[str, int] | None = None  # what they grow to (compiled ahead)
        self.ahead: list[dict[str, int]] = []  # the sizes compiled ahead (each once)
        self.background: list[threading.Thread] = []  # every thread, joined in finish()

    # ---- propose --------------------------------------------------------------------------------

    def declare(
        self, structure: Structure, parent: Case | None, added: str, depth: int, **problem
    ) -> Case:
        """A new candidate of ``structure`` starting from ``parent``'s optimum (``problem``:
        ``name``, ``fixed``, ``bounds``; ``tree_parent`` where the tree shows another parent)."""
        model = structure.build(self.grammar)
        tree_parent = problem.pop("tree_parent", None if parent is None else parent.name)
        start = problem.pop("start", None)
        if parent is None:
            case = self.gb.add_case(model, **problem, **self.kw)
        elif start:  # the parent's optimum, some values moved (a merged node's capacity)
            moved = {**parent.result.params, **start}
            guess = parent_guess(model, self.gb.ident, moved, parent.name)
            case = self.gb.add_case(model, guess=guess, **problem, **self.kw)
        else:
            case = self.gb.add_case(model, guess="parent", parent=parent.name, **problem, **self.kw)
        case.settings.setdefault("postsim", "exact")
        if parent is not None and self.grown is not None and self.grown < case.starts:
            case.settings["continued"] = self.grown
        self.seen.add(structure.name)
        self.nodes[case.name] = dict(
            case=case.name, structure=structure.name, parent=tree_parent, added=added, depth=depth
        )
        return case

    def structure(self, case: Case) -> Structure:
        return parse_structure(self.nodes[case.name]["structure"])

    def extensions(self, pairs: list[tuple[Case, Case]], depth: int) -> list[tuple[Case, Case]]:
        """Every new one-component extension of each ``(case, reference)``: ``(child, reference)``
        pairs, each child starting from ``case``."""
        out = []
        for grown, ref in pairs:
            for added, child in extensions(self.structure(grown), self.grammar):
                if child.name not in self.seen:
                    out.append((self.declare(child, grown, added, depth), ref))
        return out

    def removals(self, cases: list[Case], depth: int) -> list[tuple[Case, Case]]:
        """Every new structure one component smaller than each of ``cases``, judged against it."""
        out = []
        for case in cases:
            for removed, smaller in reductions(self.structure(case), self.grammar):
                if smaller.name not in self.seen:
                    out.append((self.declare(smaller, case, removed, depth), case))
        return out

    # ---- identify, judge, reduce ----------------------------------------------------------------

    def identify(self, cases: list[Case], depth: int, *, ahead: bool = True) -> None:
        """Fit ``cases`` in one batched call, padded to the cheapest sizes the search ran at that
        hold them; then, with ``ahead``, compile the next size ahead (:meth:`compile_ahead`)."""
        self.say(f"step {depth}: {len(cases)} candidate(s) in one batched call")
        self.widest = max(self.widest, len({u for c in cases for u in c.model.inputs}))
        sizes = sorted(self.used, key=_cost) or [dict(SEARCH_SIZES)]
        sizes += [self.next] if self.next is not None else []
        run_cases(cases, self.say, catch=True, judge=False, inputs=self.widest, sizes=sizes)
        for case in cases:
            padded = case.result.timing.get("sizes") if case.result is not None else None
            if padded and padded not in self.used:
                self.used.append(dict(padded))
        if ahead:
            self.compile_ahead(cases)

    def compile_ahead(self, cases: list[Case]) -> None:
        """The size the batches grow to next, from ``cases`` (a step's candidates): one bucket
        more free parameters where they came within :data:`AHEAD_FREE` of the sizes the batches
        run at, one more of states where within :data:`AHEAD_STATES`; its program compiled in
        a thread, so that the step that outgrows the sizes finds it compiled. The batch pads to
        it whether or not it was (the results do not depend on when it compiles)."""
        done = [c for c in cases if c.result is not None]
        if not done:
            return
        largest = dict(SEARCH_SIZES)  # each size, the most of the batches so far
        for sizes in self.used:
            for name, size in sizes.items():
                largest[name] = max(largest.get(name, 0), size)
        free = max(len(c.result.problem.free) for c in done)
        states = max(len(c.model.states) for c in done)
        near_free = free + AHEAD_FREE > largest["free"]
        near_states = states + AHEAD_STATES >= largest["states"]
        self.next = None
        if not (near_free or near_states):
            return
        self.next = target = _ahead(largest, near_free, near_states)
        if target in self.ahead:
            return
        widest = max(done, key=lambda c: len(c.result.problem.free))
        request = {**widest._request(), "starts": 1}
        self.ahead.append(target)
        self.in_background(_compile_ahead, [request], target)

    def in_background(self, work, *args) -> threading.Thread:
        """``work(*args)`` in a daemon thread, joined in :meth:`finish`."""
        thread = threading.Thread(target=work, args=args, name="jaxbox-compile-ahead")
        thread.daemon = True
        thread.start()
        self.background.append(thread)
        return thread

    def finish(self) -> None:
        """Wait for the programs being compiled ahead (a process does not end inside XLA)."""
        for thread in self.background:
            thread.join()

    def judge(self, children: list[tuple[Case, Case | None]]) -> list[Case]:
        """The criterion of every child, the verdict of those that could improve (lazily); the
        improving valid ones, best first."""
        winners: list[Case] = []
        for child, parent in sorted(children, key=lambda cp: _rank(cp[0], self.rule)):
            node = self.nodes[child.name]
            node["criterion"] = self.rule.value(child)
            better, why = self.rule.improves(child, parent)
            if not child.done:
                node.update(status="failed", why="; ".join(child.notes)[-200:])
            elif not better:
                node.update(status="no improvement", why=why)
            elif sum(_lineage(w) == _lineage(child) for w in winners) >= self.beam:
                node.update(status="improves", why=why)  # (its lineage's beam is full)
            else:
                if child.verdict is None:  # judged lazily: only now that it could improve
                    child.assess()
                    if not child.is_valid:
                        self.say(f"  {child.name}: not valid ({child.reasons[0]})")
                if child.is_valid:
                    node.update(status="grown", why=why)
                    winners.append(child)
                elif child.name in self.reduced:
                    node.update(status="reduced", why=self.reduced[child.name])
                else:
                    node.update(status="not valid", why=(child.reasons or ("not valid",))[0])
        return winners

    def reduce(self, children: list[tuple[Case, Case | None]], depth: int) -> list:
        """Each judged, invalid child that :func:`reduction` reduces, declared again as its
        reduced structure (a ``(reduced, reference)`` pair), judged against the same reference."""
        out = []
        for child, ref in children:
            if child.verdict is None or child.is_valid or child.name in self.reduced:
                continue
            try:  # a reduction that cannot be posed is a note, never the end of the search
                cut = reduction(child, self.structure(child), self.grammar)
                if cut is not None and self._back_to_parent(child, cut):
                    continue
                case = None if cut is None else self.declare_reduced(child, cut, depth)
            except ValueError as err:  # (FitError, ModelError too)
                self.say(f"  {child.name}: reduction failed ({err})")
                child.notes.append(f"reduction failed: {err}")
                continue
            if case is not None:
                out.append((case, ref))
        return out

    def _back_to_parent(self, child: Case, cut: Reduction) -> bool:
        """Whether ``cut`` leads ``child`` back to the structure it was grown from: judged
        already (the child adds nothing the data resolve), so no new candidate; a note says so."""
        parent = self.nodes[child.name]["parent"]
        if cut.structure.name != self.nodes.get(parent, {}).get("structure"):
            return False
        text = cut.text(self.nodes[child.name]["structure"])
        self.reduced[child.name] = f"{text}, the structure it was grown from (judged already)"
        child.notes.append(f"reduces to {cut.structure.name}, the structure it was grown from")
        return True

    def declare_reduced(self, child: Case, cut: Reduction, depth: int) -> Case | None:
        """Declare the reduced candidate of ``child`` (``None`` when that problem was declared
        already: the smaller structure was a candidate of its own)."""
        source = self.nodes[child.name]["structure"]
        text = cut.text(source)
        model, fixed, bounds = cut.problem(child, self.grammar)
        start = cut.start(child, model)
        key = cut.structure.name
        if fixed or bounds:
            key += "|" + ",".join(f"{k}={v:.6g}" for k, v in sorted(fixed.items()))
            key += "|" + ",".join(f"{k}={a:.6g}:{b:.6g}" for k, (a, b) in sorted(bounds.items()))
        self.reduced[child.name] = text
        if key in self.seen:
            child.notes.append(f"reduces to {cut.structure.name}, a candidate already")
            return None
        self.seen.add(key)
        self.say(f"  {child.name}: {text}")
        name = cut.structure.name if key == cut.structure.name else None
        if name is None or name in self.gb.cases:
            name = self.gb._unique(f"{cut.structure.name}+reduced")
        node = self.nodes[child.name]
        case = self.declare(
            cut.structure,
            child,
            f"{node['added']}; {text}",
            node["depth"],
            name=name,
            fixed=fixed,
            bounds=bounds,
            tree_parent=node["parent"],
            start=start,
        )
        self.seen.add(source)
        case.notes.append(f"reduced from {child.name}: {text}")
        child.notes.append(f"reduced to {case.name}: {text}")
        return case

    def step(self, children: list[tuple[Case, Case | None]], depth: int, *, ahead: bool = True):
        """Identify and judge ``children`` in one batched call, then reduce what only vanishing
        parameters made invalid (up to :data:`REDUCTION_ROUNDS` batched calls more). Returns
        the winners and every ``(candidate, reference)`` pair of the step. ``ahead``: whether
        the step may compile the next size ahead (a step that grows the beam; not a removal,
        whose candidates are smaller than a step's before, nor a look one component further,
        the search's last try before it stops)."""
        if not children:
            return [], []
        self.identify([c for c, _ in children], depth, ahead=ahead)
        winners, fresh = self.judge(children), children
        for _ in range(REDUCTION_ROUNDS):
            fresh = self.reduce(fresh, depth)
            if not fresh:
                break
            # (the reduced are smaller than the candidates they reduce: nothing to compile ahead)
            self.identify([c for c, _ in fresh], depth, ahead=False)
            children = children + fresh
            winners = self.judge(children)
        return winners, children

    # ---- the loop -------------------------------------------------------------------------------

    def start(self) -> list[Case]:
        """Identify the roots (padded to their children's input columns, so that the first two
        steps share one compiled program); every root is grown, valid or not (the simplest
        structure of a set of zones is often too simple to be valid)."""
        first = roots(self.grammar)
        self.widest = len(
            {
                u
                for s in first
                for _, c in extensions(s, self.grammar)
                for u in c.build(self.grammar).inputs
            }
        )
        self.say(
            f"structure search ({self.rule.criterion}, beam {self.beam}) from "
            + ", ".join(s.name for s in first)
        )
        note = fine_sampling_note(self.gb.ident)
        if note is not None:
            self.say(note)
        pairs = [(self.declare(s, None, "root", 0), None) for s in first]
        # the intervals' program, needed as soon as the first fit ends, compiled beside it
        self.in_background(_compile_sensitivities, pairs[0][0])
        winners, children = self.step(pairs, 0)
        grown = list(winners)
        for c, _ in children:
            node = self.nodes[c.name]
            if c in grown or not c.done or not np.isfinite(self.rule.value(c)):
                continue
            if any(o.parent == c.name for o, _ in children):  # its reduction stands for it
                continue
            why = node.get("why") or "not valid"
            node.update(status="grown", why=f"{why}; a root: grown all the same")
            grown.append(c)
        return grown

    def run(self) -> str:
        """Grow until no step improves; returns why the search stopped."""
        beam_cases = self.start()
        if not beam_cases:
            fitted = [n for n in self.nodes if self.gb.cases[n].done]
            if fitted:
                return (
                    f"no root could be grown: {', '.join(fitted)} fitted with no finite "
                    "simulation error"
                )
            return "no root could be fitted: every fit failed (each case's notes say why)"
        depth = 0
        while True:
            depth += 1
            if depth > self.max_depth:
                return f"reached max_depth={self.max_depth}"
            winners, children = self.step(
                self.extensions([(c, c) for c in beam_cases], depth), depth
            )
            if not children:
                return "the grammar has no further extension the data can drive"
            stuck = _stuck(beam_cases, winners, children)
            stones = _stepping_stones([cr for cr in children if cr[1] in stuck], self.lookahead)
            if stones and depth < self.max_depth:
                depth += 1
                further, more = self.look_further(stones, depth)
                winners += further
                stuck = _stuck(stuck, further, more)
            if stuck and depth < self.max_depth:
                # a component taken early (a facade's sun for what an envelope and a mass explain
                # together) may be worse than none once the others are in: look one back
                depth += 1
                winners += self.step(self.removals(stuck, depth), depth, ahead=False)[0]
            if not winners:
                further = ", one or two components further" if stones else ""
                return f"step {depth}: no extension improves significantly{further}, nor a removal"
            beam_cases = _best_per_lineage(winners, self.rule, self.beam)

    def look_further(self, stones: list[tuple[Case, Case]], depth: int):
        """Grow the stepping stones (the best fits of a stuck case's children) one component
        further, their children judged against the stuck case."""
        for stone, _ in stones:
            node = self.nodes[stone.name]
            node["why"] = f"{node['status']}: {node.get('why', '')}".rstrip(": ")
            node["status"] = "stepping stone"
        self.say(
            f"step {depth - 1}: no extension improves; looking one component further from "
            + ", ".join(s.model.name for s, _ in stones)
        )
        return self.step(self.extensions(stones, depth), depth, ahead=False)

    # ---- choose ---------------------------------------------------------------------------------

    def choose(self) -> Case | None:
        """The accepted model (:func:`_accept`), and every candidate's final status."""
        cases = [self.gb.cases[n] for n in self.nodes]
        accepted = _accept([c for c in cases if c.done and c.is_valid], self.rule)
        for name, node in self.nodes.items():
            node.setdefault("criterion", math.inf)
            node.setdefault("status", "not judged")
            if accepted is not None and name == accepted.name:
                node["status"] = "accepted"
        return accepted


def structure_search(
    greybox,
    *,
    criterion: str = "cv",
    beam: int = 1,
    starts: int = DEFAULT_STARTS,
    seed: int | None = 0,
    margin: float = 0.02,
    alpha: float = 0.05,
    max_depth: int = 10,
    lookahead: int = 2,
    grammar: Grammar | None = None,
    progress: Progress | None = None,
    **settings,
) -> Search:
    """Search the component grammar for the structure the data support (see the module).

    Args:
        greybox: a :class:`~jaxbox.select.GreyBox`, or data (a Dataset, a DataFrame with a time
            index, a CSV path) for a new one with the default periods.
        criterion: ``"cv"``, ``"aic"``, ``"bic"`` or ``"lr"``.
        beam: how many of the best improving structures each step grows.
        starts: starts per candidate (the parent's optimum plus Latin-hypercube samples).
        seed: seed of the Latin hypercubes.
        margin: relative decrease of the validation SE that counts as an improvement (``cv``).
        alpha: significance level of the likelihood-ratio test (``lr``).
        max_depth: most components added to a root.
        lookahead: when no extension improves, how many of them (the best fits on the
            identification data) are grown one component further all the same, as stepping
            stones (components that help only together, such as an envelope and an internal
            mass); 0 stops at once.
        grammar: what the data can drive (default: from the data's columns).
        progress: called with one line of text per step and per candidate.
        settings: solver settings for the fits (``max_steps``…); ``continued=k``: a grown
            candidate's first ``k`` starts (its parent's optimum first) take the continuation
            as well as the output error, the others the output error alone (default: all,
            :data:`GROWN_CONTINUED`; a root's starts take both routes). ``continued=1`` halves
            the fits' time of a search on the twin houses (the same accepted models), at the
            risk of a grown candidate's better optimum that only the continuation from another
            start finds. ``polish=k``: every start of a candidate is solved to a looser
            tolerance, then its ``k`` best on to the fit's own (default
            :data:`SEARCH_POLISH`; ``None``: every start to the fit's tolerance).

    Returns:
        :class:`Search` (the cases are in ``search.greybox.cases``).

    Raises:
        TypeError: an option of the wrong type: ``beam``, ``max_depth`` or ``lookahead`` not a
            whole number (any integral number is one, numpy's too; a bool or ``2.0`` is not),
            a ``grammar`` that is not a :class:`~jaxbox.models.Grammar`, ``starts`` or ``seed``
            that is not a whole number, ``progress`` not a function.
        ValueError: an option out of range, or data the grammar cannot model (no
            ``T_zon``/``T_amb``, more than two zones).
    """
    say = progress or quiet
    gb, grammar, judge, counts, kw = _checked(
        greybox,
        criterion,
        beam,
        starts,
        seed,
        margin,
        alpha,
        max_depth,
        lookahead,
        grammar,
        progress,
        settings,
    )
    t0 = time.perf_counter()
    if grammar.scale > 1.0:  # set by _checked
        say(
            f"a large building: its heat input per kelvin is {grammar.scale:.3g} times "
            f"{REFERENCE_HLC:g} W/K, and so are the conductances, capacities, constant heat "
            "inputs and apertures of every structure (their guesses and bounds)"
        )
    search = _Search(gb, grammar, judge, kw=kw, say=say, **counts)
    try:
        stopped = search.run()
    finally:
        search.finish()
    accepted = search.choose()
    rel = math.inf if accepted is None else _relative_rmse(accepted, set(_lineage(accepted)))
    choice = choose_form(
        gb,
        grammar,
        accepted,
        rel,
        starts=starts,
        seed=seed,
        max_depth=min(counts["max_depth"], 3),
        say=say,
    )
    if choice.form != "temperature" and accepted is not None:
        node = search.nodes[accepted.name]
        node.update(status="grown", why=f"{node.get('why', '')}; the {choice.form} form accepted")
        accepted = None
    elapsed = time.perf_counter() - t0
    nodes = search.nodes
    verdict = verdict_text(gb.cases, nodes, accepted)
    if choice.form != "temperature":
        verdict = f"the {choice.form} form: {choice.model.summary().splitlines()[0]}"
    say(f"accepted: {verdict}; {stopped} ({elapsed:.0f} s, {len(nodes)} candidates)")
    if choice.why:
        say(f"form accepted: {choice.form} ({choice.why})")
    return Search(
        greybox=gb,
        choice=choice,
        accepted=None if accepted is None else accepted.name,
        order=tuple(nodes),
        stopped=stopped,
        skipped=(),
        elapsed_s=elapsed,
        verdict=verdict,
        criterion=criterion,
        tree=tuple(SearchNode(**nodes[n]) for n in nodes),
        margin=float(margin),
        scale=float(grammar.scale),
    )


def _checked(
    greybox,
    criterion,
    beam,
    starts,
    seed,
    margin,
    alpha,
    max_depth,
    lookahead,
    grammar,
    progress,
    settings,
):
    """The options of :func:`structure_search`, checked by name before any case is declared:
    ``(greybox, grammar, judge, counts, fit keywords)``."""
    from ..models import ModelError

    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}")
    # any integral number (numpy's int64 from an array or a table too); a bool, a float or
    # text is refused by name (TypeError), a number out of range too (ValueError)
    counts = dict(
        beam=check_whole(beam, "beam", 1),
        max_depth=check_whole(max_depth, "max_depth", 0),
        lookahead=check_whole(lookahead, "lookahead", 0),
    )
    margin = _fraction(margin, "margin")
    if (
        isinstance(alpha, bool | np.bool_)
        or not isinstance(alpha, numbers.Real)
        or not 0.0 < alpha < 1.0
    ):
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")
    if grammar is not None and not isinstance(grammar, Grammar):
        raise TypeError(
            f"grammar must be a jaxbox.models.Grammar (or None: from the data's columns), got "
            f"{type(grammar).__name__}"
        )
    settings = check_run(starts, seed, {"polish": SEARCH_POLISH, **settings}, progress)
    gb = _as_greybox(greybox, "structure_search")
    try:
        grammar = grammar or Grammar.from_columns(gb.data.columns)
    except ModelError as err:
        raise ValueError(str(err)) from None
    if grammar.scale is None:  # a large building searched as a house is (select/_scale.py)
        grammar = dataclasses.replace(grammar, scale=building_scale(gb.ident, grammar))
    judge = _Judge(criterion, float(margin), float(alpha))
    return gb, grammar, judge, counts, {"starts": starts, "seed": seed, **settings}


def _stuck(cases: list[Case], winners: list[Case], children: list[tuple[Case, Case]]) -> list[Case]:
    """The ``cases`` none of whose children (``(child, case judged against)`` pairs) is among
    the ``winners``."""
    won = {id(ref) for child, ref in children if any(child is w for w in winners)}
    return [c for c in cases if id(c) not in won]


def _best_per_lineage(cases: list[Case], judge: _Judge, beam: int) -> list[Case]:
    """The ``beam`` best of ``cases`` by the criterion in each lineage (a step's winners come
    from its extensions, its stepping stones and its removals: together they may be more)."""
    out: list[Case] = []
    for c in sorted(cases, key=lambda c: _rank(c, judge)):
        if all(c is not o for o in out) and sum(_lineage(o) == _lineage(c) for o in out) < beam:
            out.append(c)
    return out


def _stepping_stones(children: list[tuple[Case, Case]], n: int) -> list[tuple[Case, Case]]:
    """Per case judged against, the ``n`` children that fit the identification data best
    relative to it, among those fitting it clearly better (cost at least 10 % lower), with that
    case."""
    fitted = [
        (c.result.cost / ref.result.cost, c, ref)
        for c, ref in children
        if c.done
        and ref.done
        and np.isfinite(c.result.cost)
        and c.result.cost < 0.9 * ref.result.cost
    ]
    fitted.sort(key=lambda x: x[0])
    out: list[tuple[Case, Case]] = []
    for _, c, ref in fitted:
        if sum(r is ref for _, r in out) < n:
            out.append((c, ref))
    return out
