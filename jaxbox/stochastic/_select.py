"""Forward selection by likelihood-ratio tests (Bacher & Madsen 2011)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence

import numpy as np

from .._defaults import DEFAULT_CONCENTRATION
from ..fit._starts import sample_starts
from ..fit._transforms import two_sided
from ..models import get_model
from ._checks import as_data
from ._fit import DEFAULT_ML_STARTS, fit_ml
from ._problem import StochasticProblem, make_stochastic_problem
from ._result import MLResult, likelihood_ratio_test

__all__ = ["forward_selection_lr", "parent_guess", "parent_starts"]


def forward_selection_lr(
    models: Sequence,
    data,
    *,
    alpha: float = 0.05,
    **fit_options,
) -> dict:
    """Fit a sequence of nested models from simple to complex by maximum likelihood and keep
    the last one that is a significant improvement.

    Each model is compared with the model currently accepted by a likelihood-ratio test
    (:func:`likelihood_ratio_test`); it replaces it when it has more free parameters and the
    test's p-value is below ``alpha``. Besides its own starts (the guess and the Latin
    hypercube of :func:`fit_ml`), a model is started from the accepted model's estimates
    (:func:`parent_starts`: the accepted model embedded in it, its new parameters next to
    their lower or their upper bounds, and its new parameters at their guesses), so that a
    richer model begins where the model it extends ended and its likelihood is not far below
    that model's for want of a start. These starts take the place of the last Latin-hypercube
    starts: every model has as many starts, and they share one compiled solve. The models must
    be nested in that order (each extends the one before, as the ``bacher-madsen`` family does
    from ``BM_Ti``); the test is not valid otherwise.

    Args:
        models: model names or :class:`~jaxbox.models.RCModel`, simplest first; an entry may
            be a pair ``(model, options)`` whose options (e.g. ``{"fixed": {"sigma_wal": 0}}``)
            update ``fit_options`` for that model: a model nested in the next by fixed
            parameters (a diffusion that may not be needed).
        data: the identification dataset.
        alpha: significance level.
        fit_options: passed to :func:`fit_ml` (``starts``, ``seed``, ``fixed``…).

    Returns:
        ``{"accepted": name, "table": [row per model], "fits": {name: MLResult}}`` (a model
        with options is named with them, ``"BM_Ti (sigma_zon=0)"``); a row holds
        ``model``, ``n_free``, ``loglik``, ``aic``, ``bic``, the LR ``statistic``, ``df`` and
        ``pvalue`` against the model accepted before it, and ``accepted``.
    """
    entries = _entries(models, fit_options)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    data = as_data(data)
    current: MLResult | None = None
    accepted = ""
    table, fits = [], {}
    for i, (model, extra) in enumerate(entries):
        options = {**fit_options, **extra}
        if current is not None:
            options["starts"] = _with_parent_start(model, data, current, options)
        fit = fit_ml(model, data, **options)
        name = model.name if not extra else f"{model.name} {_describe(extra)}"
        if name in fits:
            name = f"{name} #{i + 1}"
        fits[name] = fit
        row = {
            "model": name,
            "n_free": fit.n_free,
            "loglik": fit.loglik,
            "aic": fit.aic,
            "bic": fit.bic,
            "statistic": None,
            "df": None,
            "pvalue": None,
            "accepted": False,
        }
        if current is None:
            row["accepted"] = True
        elif fit.n_free > current.n_free:
            test = likelihood_ratio_test(current, fit)
            row.update(statistic=test["statistic"], df=test["df"], pvalue=test["pvalue"])
            row["accepted"] = test["pvalue"] < alpha
        if row["accepted"]:
            current, accepted = fit, name
        table.append(row)
    return {"accepted": accepted, "table": table, "fits": fits}


def _entries(models, fit_options: dict) -> list[tuple]:
    """``[(model, options), …]`` of :func:`forward_selection_lr`, every entry checked before
    the first fit: a model (name or :class:`~jaxbox.models.RCModel`) or a pair ``(model,
    {option: value})``, and only options :func:`fit_ml` takes (here and in ``fit_options``)."""
    if isinstance(models, str) or not isinstance(models, Sequence):
        raise TypeError(
            f"models must be a list of models, simplest first (e.g. ['BM_Ti', 'BM_TiTe']), got "
            f"{models!r}"
        )
    if not models:
        raise ValueError("forward_selection_lr needs at least one model")
    known = set(inspect.signature(fit_ml).parameters) - {"model", "data"}
    bad = sorted(set(fit_options) - known)
    if bad:
        raise TypeError(
            f"unknown fit option(s) {', '.join(bad)}; fit_ml takes {', '.join(sorted(known))}"
        )
    out = []
    for i, entry in enumerate(models):
        if isinstance(entry, tuple) and (len(entry) != 2 or not isinstance(entry[1], Mapping)):
            raise TypeError(
                f"models[{i}] must be a model or a pair (model, {{option: value}}), e.g. "
                f"('BM_Ti', {{'fixed': {{'sigma_zon': 0}}}}), got {entry!r}"
            )
        m, extra = entry if isinstance(entry, tuple) else (entry, {})
        bad = sorted(set(extra) - known)
        if bad:
            raise TypeError(
                f"models[{i}]: unknown fit option(s) {', '.join(map(str, bad))}; fit_ml takes "
                f"{', '.join(sorted(known))}"
            )
        out.append((get_model(m), dict(extra)))
    return out


def parent_guess(problem: StochasticProblem, parent: MLResult) -> dict[str, float]:
    """The parent's estimates for the free parameters of ``problem`` (a richer model's
    maximum-likelihood problem; ``parent``: the fit of a model it extends): every free
    parameter that ``parent`` also has and whose estimate lies within its bounds in
    ``problem``; the others are left out (they keep their guess)."""
    bounds = problem.bounds
    return {
        n: float(v)
        for n, v in parent.params.items()
        if n in bounds and bounds[n][0] <= v <= bounds[n][1]
    }


#: where the embedding starts put a new parameter: this fraction of its range (in the bounds
#: transform's scale, logarithmic for resistances and capacities) from a bound
EMBED_POSITION = 1e-3


def parent_starts(
    problem: StochasticProblem, parent: MLResult, position: float = EMBED_POSITION
) -> np.ndarray:
    """Starts of a richer model from the estimates of a model it extends [k, n_free] (physical
    values, columns in ``problem.free`` order, 1 ≤ k ≤ 3 distinct rows).

    Every row holds the parent's estimates (:func:`parent_guess`); the parameters it does not
    give (the parent does not have them, or holds them outside their bounds here, as a
    diffusion the parent fixed at zero) are, row by row: next to their lower bounds; next to
    their upper bounds (``position`` of their range from the bound, in the bounds transform's
    scale); at their guesses.
    A new node with its resistance and capacity at their floors merges into its neighbour, a
    new aperture or gain at its floor adds nothing, a new resistance at its ceiling leaves its
    node unconnected, a new diffusion at its floor is silent: one of the two embedding rows is
    then the parent itself, up to the ``position``, and a richer model starts at (nearly) the
    parent's likelihood. Initial temperatures and parameters with an open bound keep their
    guesses; rows that coincide are given once.
    """
    if not 0.0 < position < 0.5:
        raise ValueError(f"position must lie in (0, 0.5), got {position}")
    inherited = parent_guess(problem, parent)
    base = {**problem.guess_dict, **inherited}
    row = np.asarray([base[n] for n in problem.free], dtype=float)
    tr = problem.transform
    new = two_sided(tr.kinds) & np.asarray(
        [n not in inherited and not problem.spec(n).is_initial_state for n in problem.free]
    )
    rows: list[np.ndarray] = []
    for candidate in (
        np.where(new, tr.at_position(position), row),
        np.where(new, tr.at_position(1.0 - position), row),
        row,
    ):
        if not any(np.array_equal(r, candidate) for r in rows):
            rows.append(candidate)
    return np.stack(rows)


def _with_parent_start(model, data, parent: MLResult, options: dict) -> np.ndarray:
    """The starts of ``model``: those :func:`fit_ml` draws for ``options`` but the last ``k``
    (so that their number, and the compiled solve, stay those of the other models), or the
    explicit ones, then ``k`` starts from the parent (:func:`parent_starts`, the first ``k``:
    all of them, but no more than ``starts − 1`` when the number of starts is given)."""
    names = ("free", "fixed", "bounds", "guess", "priors", "hold", "x0_std")
    sp = make_stochastic_problem(model, data, **{k: options[k] for k in names if k in options})
    rows = parent_starts(sp, parent)
    starts = options.get("starts", DEFAULT_ML_STARTS)
    if isinstance(starts, int | np.integer):
        rows = rows[: max(int(starts) - 1, 1)]
        seed = options.get("seed", 0)
        concentration = options.get("concentration", DEFAULT_CONCENTRATION)
        starts = sample_starts(sp, data, max(int(starts) - len(rows), 1), seed, concentration)
    return np.vstack([np.atleast_2d(np.asarray(starts, dtype=float)), rows])


def _describe(options) -> str:
    fixed = options.get("fixed") or {}
    if fixed and len(options) == 1:
        return "(" + ", ".join(f"{k}={v:g}" for k, v in fixed.items()) + ")"
    return "(" + ", ".join(f"{k}={v!r}" for k, v in options.items()) + ")"
