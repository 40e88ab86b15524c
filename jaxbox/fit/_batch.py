"""Several datasets of the same length fitted with one model in one compiled call.

Every dataset (two twin houses, the same building in several periods, the members of a
synthetic study…) gets its own estimation problem — guess from its own first samples, its own
starts — and all their starts run together in one batch of the solver used by
:func:`~jaxbox.fit.fit`, compiled once for the model structure and the data shape. Fitting two
buildings then costs one compilation instead of two, and ten buildings barely more than one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .._x64 import require_x64
from ..models import get_model
from ._fit import make_starts, result_from, solve_jobs
from ._problem import FitError, make_problem, problem_arrays
from ._result import FitResult

__all__ = ["fit_many"]


def fit_many(
    model,
    datasets: Sequence | Mapping,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    starts: int | np.ndarray = 1,
    seed: int | None = 0,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    simulator: str = "exact",
    sim_options: Mapping | None = None,
    max_steps: int = 100,
    rtol: float = 1e-6,
    atol: float = 1e-16,
    concentration: float = 4.0,
    slots: int | None = None,
) -> list[FitResult] | dict[str, FitResult]:
    """Fit ``model`` to each of several datasets of the same length in one batched call.

    Takes the arguments of :func:`~jaxbox.fit.fit`; they apply to every dataset. Initial states
    are guessed from each dataset's own first samples, and each dataset gets ``starts`` starts
    (the guess plus Latin-hypercube samples around it, with the same ``seed``), or the same
    explicit starts [S, n_free]. ``slots`` counts the starts iterated together over all
    datasets.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        datasets: a sequence of :class:`~jaxbox.data.Dataset`, or a mapping ``name -> Dataset``;
            all with the same number of samples and the same step.

    Returns:
        One :class:`~jaxbox.fit.FitResult` per dataset: a list, or a dict with the same keys.
        Their ``timing`` is that of the whole batch (``batch`` holds the number of datasets).

    Raises:
        FitError: no dataset, datasets of different lengths or steps, a problem that differs
            in its free/fixed split between datasets, or every start of one dataset failed.
    """
    require_x64()
    model = get_model(model)
    keys = list(datasets) if isinstance(datasets, Mapping) else None
    items = [datasets[k] for k in keys] if keys is not None else list(datasets)
    if not items:
        raise FitError("fit_many needs at least one dataset")
    n, step = len(items[0]), items[0].step
    for i, data in enumerate(items):
        label = keys[i] if keys is not None else i
        if len(data) != n or abs(data.step - step) > 1e-9 * step:
            raise FitError(
                f"dataset {label!r} has {len(data)} samples every {data.step:g} s but the first "
                f"has {n} every {step:g} s; batched datasets need the same length and step "
                "(slice or resample them), or fit them one by one"
            )
    jobs, problems, x0s = [], [], []
    for data in items:
        problem = make_problem(
            model,
            data,
            free=free,
            fixed=fixed,
            bounds=bounds,
            guess=guess,
            weights=weights,
            simulator=simulator,
            sim_options=sim_options,
        )
        x0 = make_starts(problem, starts, seed, concentration)
        jobs.append((problem, x0, problem_arrays(problem, data)))
        problems.append(problem)
        x0s.append(x0)
    out = solve_jobs(jobs, max_steps=max_steps, rtol=rtol, atol=atol, slots=slots)
    timing = {"compile_s": out["compile_s"], "fit_s": out["fit_s"], "batch": len(items)}
    settings = {"max_steps": max_steps, "rtol": rtol, "atol": atol, "seed": seed, "slots": slots}
    results, first = [], 0
    for i, (problem, data, x0) in enumerate(zip(problems, items, x0s, strict=True)):
        sl = slice(first, first + len(x0))
        first += len(x0)
        try:
            results.append(result_from(problem, data, x0, out, sl, settings, timing))
        except FitError as err:
            label = keys[i] if keys is not None else i
            raise FitError(f"dataset {label!r}: {err}") from None
    return dict(zip(keys, results, strict=True)) if keys is not None else results
