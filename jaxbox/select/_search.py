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
search; a child that does not improve is not grown further. A child made invalid only by facade
apertures at zero or undetermined (a facade that lets no sun in, or too little to tell) is tried
again without those windows in the same step; so is a child whose unmeasured initial
temperature ended on its bound, with that bound narrowed to the temperatures around the state
(as the forward selection does); so is a child made invalid only by resistances on their
upper bound, with those heat paths cut (the resistances fixed at that bound: the data do not
use them), and a child made invalid only by the interval of a fast node's capacity (own time
constant under two sampling steps) or by that capacity on its lower bound, with that capacity
fixed at its estimate (the data see the node's lag, or no lag at all, not its capacity).

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

Validity is judged lazily: a candidate's intervals and verdict are computed only when its
criterion value could make it improve, which keeps the cost of a step close to the cost of its
batched fits.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time

import numpy as np
from scipy import stats

from ..fit import DEFAULT_STARTS
from ..models._grammar import (
    Grammar,
    Structure,
    extensions,
    parse_structure,
    reductions,
    roots,
)
from ..validate import MAX_REL_CI
from ._cases import Case, Progress, check_whole, quiet, run_cases, verdict_text
from ._forward import (
    Selection,
    _as_greybox,
    _fraction,
    _narrowed_retry,
    _pinned_unmeasured_states,
    _retry_of,
    check_run,
)

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
    """

    criterion: str = "cv"
    tree: tuple[SearchNode, ...] = ()

    def to_dict(self) -> dict:
        d = super().to_dict()
        d.update(criterion=self.criterion, tree=[n.to_dict() for n in self.tree])
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
                retry = " (retried)" if n.case != n.structure else ""
                lines.append(
                    f"{mark} {'  ' * indent}{n.structure}{retry}  [{self.criterion} {value}] "
                    f"{n.status}{why}"
                )
                walk(n.case, indent + 1)

        walk(None, 0)
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
        settings: solver settings for the fits (``max_steps``…).

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
    from ..models import ModelError

    say = progress or quiet
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}")
    # any integral number (numpy's int64 from an array or a table too); a bool, a float or
    # text is refused by name (TypeError), a number out of range too (ValueError)
    beam = check_whole(beam, "beam", 1)
    max_depth = check_whole(max_depth, "max_depth", 0)
    lookahead = check_whole(lookahead, "lookahead", 0)
    margin = _fraction(margin, "margin")
    if (
        isinstance(alpha, bool | np.bool_)
        or not isinstance(alpha, numbers.Real)
        or not 0.0 < alpha < 1.0
    ):
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")
    alpha = float(alpha)
    if grammar is not None and not isinstance(grammar, Grammar):
        raise TypeError(
            f"grammar must be a jaxbox.models.Grammar (or None: from the data's columns), got "
            f"{type(grammar).__name__}"
        )
    settings = check_run(starts, seed, settings, progress)
    gb = _as_greybox(greybox, "structure_search")
    try:
        grammar = grammar or Grammar.from_columns(gb.data.columns)
    except ModelError as err:
        raise ValueError(str(err)) from None
    judge = _Judge(criterion, float(margin), float(alpha))
    kw = {"starts": starts, "seed": seed, **settings}
    t0 = time.perf_counter()
    nodes: dict[str, dict] = {}  # case name -> node fields
    seen: set[str] = set()

    def declare(structure: Structure, parent: Case | None, added: str, depth: int) -> Case:
        model = structure.build(grammar)
        if parent is None:
            case = gb.add_case(model, **kw)
        else:
            case = gb.add_case(model, guess="parent", parent=parent.name, **kw)
        case.settings.setdefault("postsim", "exact")
        seen.add(structure.name)
        nodes[case.name] = dict(
            case=case.name,
            structure=structure.name,
            parent=None if parent is None else parent.name,
            added=added,
            depth=depth,
        )
        return case

    widest = 0  # the most input columns of a step so far: later steps pad to it

    def run(cases: list[Case], step: int) -> None:
        nonlocal widest
        say(f"step {step}: {len(cases)} candidate(s) in one batched call")
        widest = max(widest, len({u for c in cases for u in c.model.inputs}))
        run_cases(cases, say, catch=True, judge=False, inputs=widest)

    def settle(children: list[tuple[Case, Case | None]]) -> list[Case]:
        """Judge a step's children; the improving valid ones, best first."""
        order = sorted(children, key=lambda cp: _rank(cp[0], judge))
        winners: list[Case] = []
        for child, parent in order:
            node = nodes[child.name]
            node["criterion"] = judge.value(child)
            better, why = judge.improves(child, parent)
            if not child.done:
                node.update(status="failed", why="; ".join(child.notes)[-200:])
                continue
            if not better:
                node.update(status="no improvement", why=why)
                continue
            if sum(_lineage(w) == _lineage(child) for w in winners) >= beam:  # (its lineage's)
                node.update(status="improves", why=why)
                continue
            fresh = child.verdict is None  # judged lazily: only now that it could improve
            if fresh:
                child.assess()
            if not child.is_valid:
                first = child.reasons[0] if child.reasons else "not valid"
                node.update(status="not valid", why=first)
                if fresh:
                    say(f"  {child.name}: pruned, not valid ({first})")
                continue
            node.update(status="grown", why=why)
            winners.append(child)
        return winners

    first = [declare(s, None, "root", 0) for s in roots(grammar)]
    # the roots are fitted with as many input columns as their children will have, so that the
    # first two steps share one compiled program
    widest = len(
        {
            u
            for s in roots(grammar)
            for _, c in extensions(s, grammar)
            for u in c.build(grammar).inputs
        }
    )
    say(
        f"structure search ({criterion}, beam {beam}) from "
        + ", ".join(s.name for s in roots(grammar))
    )
    run(first, 0)
    beam_cases = settle([(c, None) for c in first])
    # every lineage is grown from its root, valid or not: the simplest structure of a set of
    # zones is often too simple to be valid (a solar aperture at zero where the envelope is
    # missing), and a component more may make it so
    for c in first:
        if c.done and c not in beam_cases and np.isfinite(judge.value(c)):
            beam_cases.append(c)
            nodes[c.name]["status"] = "grown"
            nodes[c.name]["why"] = (
                f"{nodes[c.name].get('why') or 'not valid'}; a root: grown all the same"
            )
    stopped = ""
    if not beam_cases:
        fitted = [c.name for c in first if c.done]
        stopped = (
            f"no root could be grown: {', '.join(fitted)} fitted with no finite simulation error"
            if fitted
            else "no root could be fitted: every fit failed (each case's notes say why)"
        )

    def grow(pairs: list[tuple[Case, Case]], depth: int) -> tuple[list[Case], list]:
        """Identify every new extension of each ``(case, reference)`` pair in one batched call
        (the repairs in a second); each child starts from ``case`` and is judged against
        ``reference``. Returns the winners and the (child, reference) pairs."""
        children: list[tuple[Case, Case]] = []
        for grown, ref in pairs:
            structure = parse_structure(nodes[grown.name]["structure"])
            for added, child in extensions(structure, grammar):
                if child.name not in seen:
                    children.append((declare(child, grown, added, depth), ref))
        if not children:
            return [], []
        run([c for c, _ in children], depth)
        winners = settle(children)
        repairs = []
        for child, ref in children:
            node = nodes[child.name]
            fix = _without_dead_facades(parse_structure(node["structure"]), child)
            if fix is not None and fix[1].name not in seen:
                what = f"{node['added']}, {fix[0]}"
                repairs.append((declare(fix[1], gb.cases[node["parent"]], what, depth), ref))
                continue
            if child.is_valid or child.verdict is None:
                continue
            try:  # a retry that cannot be posed is a note, never the end of the search
                if cut := _resistances_at_their_top(child):
                    retry = _cut_retry(gb, child, cut, say)
                    how = f"{', '.join(cut)} cut (fixed at the upper bound)"
                elif fast := _fast_capacities(child):
                    retry = _settled_retry(gb, child, fast, say)
                    how = f"{', '.join(fast)} fixed at the estimate (only its lag shows)"
                elif pinned := _pinned_unmeasured_states(child):
                    retry = _narrowed_retry(gb, child, pinned, say)
                    how = f"{', '.join(pinned)} narrowed"
                else:
                    continue
            except ValueError as err:  # (FitError, ModelError too)
                say(f"  {child.name}: retry failed ({err})")
                child.notes.append(f"retry failed: {err}")
                continue
            nodes[retry.name] = dict(
                node, case=retry.name, added=f"{node['added']}; retried with {how}"
            )
            for key in ("criterion", "status", "why"):
                nodes[retry.name].pop(key, None)
            repairs.append((retry, ref))
        if repairs:  # the repaired cases: once more
            run([c for c, _ in repairs], depth)
            winners = settle(children + repairs)
        return winners, children + repairs

    def shrink(cases: list[Case], depth: int) -> list[Case]:
        """Identify every new structure one component smaller than each of ``cases`` in one
        batched call, each starting from (and judged against) the case it comes from. Returns
        the winners."""
        children: list[tuple[Case, Case]] = []
        for case in cases:
            structure = parse_structure(nodes[case.name]["structure"])
            for removed, smaller in reductions(structure, grammar):
                if smaller.name not in seen:
                    children.append((declare(smaller, case, removed, depth), case))
        if not children:
            return []
        say(f"step {depth}: {len(children)} structure(s) one component smaller")
        run([c for c, _ in children], depth)
        return settle(children)

    depth = 0
    while beam_cases and not stopped:
        depth += 1
        if depth > max_depth:
            stopped = f"reached max_depth={max_depth}"
            break
        winners, children = grow([(c, c) for c in beam_cases], depth)
        if not children:
            stopped = "the grammar has no further extension the data can drive"
            break
        # a beam case whose every extension fails to improve looks one component further, from
        # the extensions that fit its identification data best (components that help only
        # together, such as an envelope and an internal mass); stuck is a property of the case,
        # not of its lineage: another beam case that still improves must not hide it
        stuck = _stuck(beam_cases, winners, children)
        stones = _stepping_stones([cr for cr in children if cr[1] in stuck], lookahead)
        if stones and depth < max_depth:
            for stone, _ in stones:
                node = nodes[stone.name]
                node["why"] = f"{node['status']}: {node.get('why', '')}".rstrip(": ")
                node["status"] = "stepping stone"
            say(
                f"step {depth}: no extension improves; looking one component further from "
                + ", ".join(s.model.name for s, _ in stones)
            )
            depth += 1
            further, more = grow(stones, depth)
            winners += further
            stuck = _stuck(stuck, further, more)
        if stuck and depth < max_depth:
            # before a stuck case is given up, the search looks one component back from it: a
            # component taken early (a facade's sun for what an envelope and a mass explain
            # together) may be worse than none once the others are in
            depth += 1
            winners += shrink(stuck, depth)
        if not winners:
            stopped = (
                f"step {depth}: no extension improves significantly"
                + (", one or two components further" if stones else "")
                + ", nor a removal"
            )
            break
        beam_cases = _best_per_lineage(winners, judge, beam)
    elapsed = time.perf_counter() - t0

    valid = [gb.cases[n] for n in nodes if gb.cases[n].done and gb.cases[n].verdict is not None]
    valid = [c for c in valid if c.is_valid]
    accepted = _accept(valid, judge)
    for name, node in nodes.items():
        node.setdefault("criterion", math.inf)
        node.setdefault("status", "not judged")
        if accepted is not None and name == accepted.name:
            node["status"] = "accepted"
    tree = tuple(SearchNode(**nodes[n]) for n in nodes)
    verdict = verdict_text(gb.cases, nodes, accepted)
    say(f"accepted: {verdict}; {stopped} ({elapsed:.0f} s, {len(nodes)} candidates)")
    return Search(
        greybox=gb,
        accepted=None if accepted is None else accepted.name,
        order=tuple(nodes),
        stopped=stopped,
        skipped=(),
        elapsed_s=elapsed,
        criterion=criterion,
        tree=tree,
    )


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


def _resistances_at_their_top(case: Case) -> list[str]:
    """The resistances at their upper bound when nothing else makes ``case`` invalid (but
    intervals, which such a flat direction widens): heat paths the data do not use (their
    conductance wants to vanish)."""
    if case.verdict is None or case.is_valid or not case.done:
        return []
    at_bound = set(case.verdict.flagged("at_bound"))
    pos = case.result.bound_position()
    top = {n for n in at_bound if n.startswith("R_") and pos.get(n, 0.0) > 0.5}
    # the other reasons may only be intervals, which an unused path blurs
    blurred = {n for kind in _BLURRED for n in case.verdict.flagged(kind)}
    if not top or top != at_bound or set(case.verdict.flagged()) - blurred - top:
        return []
    return sorted(top)


#: verdict flags that a parameter on its bound can cause in the others (a flat direction)
_BLURRED = ("wide_interval", "poorly_identifiable", "not_identifiable")


def _fast_capacities(case: Case) -> list[str]:
    """Capacities that only their intervals (or, for a fast node, its lower bound) make
    ``case`` invalid for, of nodes whose lag the data see but not the capacity: a fast node
    (own time constant ``τ = C/ΣG`` below two sampling steps), or a node whose ``τ`` is
    determined (its 95 % interval within :data:`~jaxbox.validate.MAX_REL_CI`) while ``C`` is
    not — a heater seen only through the zone it warms shows ``R·C``, not how it splits."""
    if case.verdict is None or case.is_valid or not case.done:
        return []
    blurred = {n for kind in _BLURRED for n in case.verdict.flagged(kind)}
    pos = case.result.bound_position()
    floored = {  # capacities on their lower bound: a node the data see as instantaneous
        n for n in case.verdict.flagged("at_bound") if n.startswith("C_") and pos.get(n, 1.0) < 0.5
    }
    if set(case.verdict.flagged()) - blurred - floored:
        return []
    params = {k: float(v) for k, v in case.result.params.items()}
    tau = _own_time_constants(case.model, params)
    dt = float(np.median(np.diff(np.asarray(case.ident.t, dtype=float))))
    nodes = case.model.network.nodes
    fast = [
        n.C
        for n, t in zip(nodes, tau, strict=True)
        if (n.C in blurred or n.C in floored) and t < 2.0 * dt
    ]
    if floored - set(fast):  # a slow capacity on its lower bound: not a matter of lag
        return []
    rest = [i for i, n in enumerate(nodes) if n.C in blurred and n.C not in fast]
    if rest:
        rel = _time_constant_intervals(case, params, rest)
        fast += [nodes[i].C for i in rest if rel.get(i, np.inf) <= MAX_REL_CI]
    return sorted(fast)


def _own_time_constants(model, params: dict) -> np.ndarray:
    """``C_i / Σ_j G_ij`` [s] per node (``inf`` for a node with no conductance)."""
    d = -np.diagonal(model.rc_numpy(params)[0])
    with np.errstate(divide="ignore"):
        return np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), np.inf)


def _time_constant_intervals(case: Case, params: dict, nodes: list[int]) -> dict[int, float]:
    """Half-width of the 95 % interval of each node's own time constant, relative to it (delta
    method through the covariance of the free parameters, derivatives by central differences
    in the logarithm of the positive ones)."""
    from ..validate import uncertainty

    try:
        unc = uncertainty(case.result)
    except ValueError:
        return {}
    free = list(unc.free)
    cov = np.asarray(unc.cov_free, dtype=float)
    tau0 = _own_time_constants(case.model, params)
    grad = np.zeros((len(nodes), len(free)))
    for k, name in enumerate(free):
        v = params[name]
        if not v > 0 or name.startswith("T_"):
            continue
        h = 1e-5
        up = _own_time_constants(case.model, {**params, name: v * math.exp(h)})
        dn = _own_time_constants(case.model, {**params, name: v * math.exp(-h)})
        grad[:, k] = (up[nodes] - dn[nodes]) / (2 * h * v)  # ∂τ/∂θ_k
    out = {}
    for j, i in enumerate(nodes):
        g = grad[j]
        used = g != 0
        if not np.isfinite(tau0[i]) or not used.any():
            continue
        sub = cov[np.ix_(used, used)]
        if not np.all(np.isfinite(sub)):
            continue
        std = math.sqrt(max(float(g[used] @ sub @ g[used]), 0.0))
        out[i] = unc.t_quantile * std / tau0[i]
    return out


def _fixed_retry(gb, case: Case, fixed: dict, suffix: str, why: str, say: Progress) -> Case:
    """Declare (not run) a retry of ``case`` from its optimum with the parameters ``fixed``
    (name -> value) fixed; the others are estimated and judged again."""
    fixed = {**case.fixed, **fixed}
    free = tuple(n for n in case.result.free if n not in fixed)
    told = ", ".join(f"{n} = {v:.4g}" for n, v in fixed.items() if n not in case.fixed)
    say(f"  {case.name}: retry with {told} fixed ({why})")
    retry = _retry_of(
        gb,
        case,
        suffix,
        guess={k: float(case.result.params[k]) for k in free},
        free=free,
        fixed=fixed,
        bounds={k: v for k, v in case.bounds.items() if k in free},
    )
    retry.notes.append(f"retry of {case.name}: {told} fixed ({why})")
    case.notes.append(f"retried as {retry.name} ({why})")
    return retry


def _cut_retry(gb, case: Case, names: list[str], say: Progress) -> Case:
    """A retry of ``case`` with the resistances ``names`` fixed at their upper bound: the heat
    paths the data do not use are cut (as a facade that lets no sun in is dropped), and the
    other parameters are judged without them."""
    fixed = {n: float(case.result.bounds[n][1]) for n in names}
    return _fixed_retry(gb, case, fixed, "cut", "unused heat path cut", say)


def _settled_retry(gb, case: Case, names: list[str], say: Progress) -> Case:
    """A retry of ``case`` with the capacities ``names`` of fast nodes fixed at their estimates:
    the lag ``R·C`` the data see is then carried by the resistance alone."""
    fixed = {n: float(case.result.params[n]) for n in names}
    return _fixed_retry(gb, case, fixed, "settled", "capacity of a fast node", say)


def _without_dead_facades(structure: Structure, case: Case) -> tuple[str, Structure] | None:
    """The structure without the facade windows whose apertures alone made ``case`` invalid
    (at or near zero, or undetermined: that facade lets no sun in, or too little to tell), as
    ``(what was dropped, structure)``;
    ``None`` when that is not why it is invalid, or no window would be left."""
    verdict = case.verdict
    if verdict is None or verdict.valid:
        return None
    severe = [f for f in verdict.flags if f.severe]
    if not severe or any(not f.parameters for f in severe):
        return None
    flagged = set(verdict.flagged())
    tokens, dropped, covered = set(structure.tokens), [], set()
    for z in structure.states:
        win = structure.window(z)
        if win is None:
            continue
        suffix = "" if z == 0 else str(z)
        dead = [x for x in win[3:] if f"gA_{x.lower()}{suffix}" in flagged]
        covered |= {f"gA_{x.lower()}{suffix}" for x in dead}
        keep = "".join(x for x in win[3:] if x not in dead)
        if dead:
            if not keep:
                return None
            tokens = (tokens - {(z, win)}) | {(z, "Win" + keep)}
            dropped += dead
    if not dropped or flagged - covered:
        return None
    what = f"without the window(s) {', '.join(dropped)} (aperture at zero or undetermined)"
    return what, dataclasses.replace(structure, tokens=frozenset(tokens))
