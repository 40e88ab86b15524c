"""The fitting front ends: one problem (:func:`fit`), one model on several datasets
(:func:`fit_many`), any problems at once (:func:`fit_batch`).

Each sets up its estimation problems (guess from each dataset's own first samples, its own
starts) and hands all their starts to the batched solver (:func:`~jaxbox.fit.solve_jobs`), one
compiled call per compatible shape. Two twin houses, the same building in several periods or the
members of a synthetic study then cost one compilation instead of one each.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence

import numpy as np
import optimistix as optx
from jaxtyping import Float

from .._defaults import (
    DEFAULT_CONCENTRATION,
    DEFAULT_HOMOTOPY,
    DEFAULT_MAX_STEPS,
    DEFAULT_STARTS,
)
from .._x64 import require_x64
from ..data import DataError, Dataset, concat_periods, prepare_window
from ..data._gaps import DEFAULT_MAX_GAP, duration_seconds
from ..models import get_model
from ._fit import (
    _problem_key,
    bucket_samples,
    check_continued,
    check_homotopy,
    check_polish,
    make_starts,
    result_from,
    solve_jobs,
    solver_key,
)
from ._problem import FitError, make_problem, problem_arrays
from ._problem import number as problem_number
from ._result import FitResult
from ._solver import LevenbergMarquardt

__all__ = ["fit_model", "fit_many", "fit_batch", "compile_batch", "fit_data"]


def data_columns(data) -> tuple[str, ...] | None:
    """The columns of a Dataset, or of the first of a list of periods (``None`` otherwise):
    what a structure name is built for (:func:`~jaxbox.models.get_model`)."""
    if isinstance(data, list | tuple) and data:
        data = data[0]
    return tuple(data.columns) if isinstance(data, Dataset) else None


def fit_data(
    model, data, max_gap=DEFAULT_MAX_GAP, what: str = "identification data", warn: bool = True
):
    """``(model, data)`` ready for a fit: a list of periods joined
    (:func:`~jaxbox.data.concat_periods`), gaps prepared
    (:func:`~jaxbox.data.prepare_window`: input gaps interpolated up to ``max_gap``, segments
    beyond, output gaps kept for masking) and the model segmented to the data
    (:meth:`~jaxbox.models.RCModel.segmented`). A missing column raises
    :class:`~jaxbox.data.DataError`, a window that gaps leave unusable :class:`FitError`;
    ``warn=False``: no :class:`~jaxbox.data.DataWarning` per gap (a second look at the same
    data)."""
    if isinstance(data, list | tuple):
        data = concat_periods(data)
    if not isinstance(data, Dataset):
        raise FitError(
            f"data must be a jaxbox Dataset or a list of Datasets (periods), got "
            f"{type(data).__name__}"
        )
    data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    try:
        data = prepare_window(
            data, model.inputs, model.outputs, max_gap=max_gap, what=what, warn=warn
        )
    except DataError as err:
        raise FitError(str(err)) from None
    return model.segmented(len(data.segments)), data


def _max_steps(value) -> int:
    """Levenberg–Marquardt steps per start: an integer ≥ 1."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise FitError(f"max_steps must be an integer ≥ 1, got {value!r}")
    return int(value)


def _tolerance(value, name: str) -> float:
    """A convergence tolerance: a number ≥ 0."""
    number = problem_number(value, name)
    if not (np.isfinite(number) and number >= 0):
        raise FitError(f"{name} must be a finite number ≥ 0, got {value!r}")
    return number


def fit_model(
    model,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    starts: int | Float[np.ndarray, "starts free"] = DEFAULT_STARTS,
    seed: int | None = 0,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    simulator: str = "exact",
    sim_options: Mapping | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
    rtol: float = 1e-6,
    atol: float = 1e-16,
    concentration: float = DEFAULT_CONCENTRATION,
    solver: optx.AbstractLeastSquaresSolver | None = None,
    homotopy: Sequence[float] | None = DEFAULT_HOMOTOPY,
    release: bool = True,
    max_gap: float | str = DEFAULT_MAX_GAP,
    slots: int | None = None,
    method: str = "oe",
    **ml_options,
) -> FitResult:
    """Estimate the parameters of ``model`` from ``data`` by output-error least squares.

    ``method="ml"`` estimates the stochastic form of the model by maximum likelihood instead
    (:func:`jaxbox.stochastic.fit_ml`, which takes ``free``, ``fixed``, ``bounds``, ``guess``,
    ``starts``, ``seed``, ``concentration``, ``max_steps`` (the output-error default becomes the
    BFGS default) and, through ``ml_options``, ``priors``, ``hold``, ``x0_std``) and returns its
    :class:`~jaxbox.stochastic.MLResult`.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        data: the identification :class:`~jaxbox.data.Dataset` (inputs and outputs), or a
            list of Datasets (separate periods of one building, fitted together: see
            :func:`jaxbox.data.concat_periods`). Gaps are handled by
            :func:`jaxbox.data.prepare_window`: output gaps are masked, input gaps up to
            ``max_gap`` interpolated, longer ones split the data into segments that share the
            parameters and have their own initial states (``T_*0_s2``, … for the second, …).
        free: parameters to estimate (default: all that are not ``fixed``; initial states
            included).
        fixed: parameter values held fixed (SI).
        bounds: ``{name: (lower, upper)}`` overriding the naming-convention bounds (SI).
        guess: initial guesses overriding the defaults (SI); initial states default to the
            data (see :func:`~jaxbox.fit.initial_guess`).
        starts: number of starts (the guess plus Latin-hypercube samples around it), or an
            array [S, n_free] of explicit starts in physical units.
        seed: seed of the Latin hypercube.
        weights: output weights q_j (per output name or in ``model.outputs`` order).
        simulator: ``"exact"`` (default, exact for linear models) or ``"diffrax"``.
        sim_options: diffrax options, e.g. ``{"substeps": 2}``.
        max_steps: Levenberg–Marquardt iteration cap per start (rejected trials count).
        rtol, atol: a start has converged when an accepted step reduced the cost, and the
            linear model predicted it to reduce, by at most ``rtol · cost + atol`` [K²].
        concentration: spread of the Latin hypercube around the guess (0: uniform).
        solver: any optimistix least-squares solver (or minimiser). Default:
            :class:`jaxbox.LevenbergMarquardt` with ``rtol`` and ``atol``, driven by the fused,
            slot-refilling multistart; another solver (``optimistix.LevenbergMarquardt``,
            ``optimistix.Dogleg``, ``optimistix.GaussNewton``, …) runs one
            ``optimistix.least_squares`` per start under ``vmap``, with its own tolerances and
            a Jacobian by forward-mode autodiff through the simulator.
        homotopy: observer gains of a continuation (default
            :data:`~jaxbox.fit.DEFAULT_HOMOTOPY`; ``()``: none). Every start is solved along two
            routes, the output error directly and this continuation, and keeps the better end.
            At gain ``κ`` the simulated measured states are pulled towards their measurements
            after every sample, ``x̂ ← x̂ − κ (x̂ − y)``; ``κ = 1`` is one-step-ahead prediction,
            whose cost has far fewer local minima than the simulation error. Each stage starts
            where the previous one ended, so a start follows its optimum as the gain falls to 0.
            With :class:`jaxbox.LevenbergMarquardt` on the exact simulator; other solvers and
            the diffrax simulator fit the output error directly.
        release: a route that ends with parameters within 0.1 % of their bounds (where the
            bound transform freezes them) is solved once more from there with those parameters
            set halfway from their start values to the guess (in the transform's coordinates),
            and ends at the better of the two (jaxbox's solver).
        max_gap: the longest input gap [s] (or text such as ``"2h"``) filled by interpolation.
        slots: starts iterated together (default :func:`default_slots`); a start that has
            terminated hands its slot to the next. Results do not depend on it.

    Returns:
        :class:`FitResult` with the best start's parameters, every start's outcome and timings;
        its ``data`` are the prepared data and its ``model`` the model segmented to them.

    Raises:
        FitError: an ill-posed problem, or every start failed.

    Example:
        ```python
        data = jaxbox.datasets.twinhouse_exp1("N2")
        ident, valid = data.split()
        result = jaxbox.fit_model("ZonWal", ident, starts=16)
        print(result.summary())
        ```
    """
    if method == "ml":
        from ..stochastic._fit import fit_ml_method

        return fit_ml_method(locals())
    if method != "oe" or ml_options:
        raise FitError(
            f"method must be 'oe' (output error) or 'ml' (maximum likelihood), got {method!r}"
            if method != "oe"
            else f"unknown fit argument(s): {', '.join(ml_options)}"
        )
    return fit_batch(
        [
            {
                "model": model,
                "data": data,
                "free": free,
                "fixed": fixed,
                "bounds": bounds,
                "guess": guess,
                "starts": starts,
                "seed": seed,
                "weights": weights,
                "simulator": simulator,
                "sim_options": sim_options,
                "max_steps": max_steps,
                "rtol": rtol,
                "atol": atol,
                "concentration": concentration,
                "solver": solver,
                "homotopy": homotopy,
                "release": release,
                "max_gap": max_gap,
            }
        ],
        slots=slots,
    )[0]


#: the keyword arguments of a request (see :func:`fit_batch`) and their defaults: those of fit
_DEFAULTS = {
    name: p.default
    for name, p in inspect.signature(fit_model).parameters.items()
    if p.kind is inspect.Parameter.KEYWORD_ONLY and name not in ("slots", "method")
}
#: a request's own: how many of its starts (the first ones) take the continuation as well as
#: the output error (``None``: all; see :func:`~jaxbox.fit.solve_jobs`)
_DEFAULTS["continued"] = None
#: a request's own: how many of its best starts are polished to ``rtol`` after every start was
#: solved to :data:`~jaxbox.fit._fit.POLISH_RTOL` (``None``: every start to ``rtol``; see
#: :func:`~jaxbox.fit.solve_jobs`)
_DEFAULTS["polish"] = None
#: the problem arguments, the solver settings (requests solved together share them) and the
#: start arguments of a request
_PROBLEM = ("free", "fixed", "bounds", "guess", "weights", "simulator", "sim_options")


def _release(value) -> bool:
    """``release=``: True or False (numpy's bool too); anything else is refused by name."""
    if not isinstance(value, bool | np.bool_):
        raise FitError(f"release must be True or False, got {value!r}")
    return bool(value)


_SOLVER = ("max_steps", "rtol", "atol", "solver", "homotopy", "release")
_STARTS = ("starts", "seed", "concentration")


def fit_many(
    model,
    datasets: Sequence | Mapping,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    starts: int | Float[np.ndarray, "starts free"] = DEFAULT_STARTS,
    seed: int | None = 0,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    simulator: str = "exact",
    sim_options: Mapping | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
    rtol: float = 1e-6,
    atol: float = 1e-16,
    concentration: float = DEFAULT_CONCENTRATION,
    solver: optx.AbstractLeastSquaresSolver | None = None,
    homotopy: Sequence[float] | None = DEFAULT_HOMOTOPY,
    release: bool = True,
    max_gap: float | str = DEFAULT_MAX_GAP,
    slots: int | None = None,
) -> list[FitResult] | dict[str, FitResult]:
    """Fit ``model`` to each of several datasets of the same step in one batched call.

    Datasets of different lengths are padded at their end with samples of weight 0 (results
    the same to rounding, see :func:`~jaxbox.fit.solve_jobs`) as long as their lengths are
    neighbours (:func:`~jaxbox.fit._fit.bucket_samples`: within a sixteenth of an octave);
    lengths further apart go in calls of their own.

    Takes the arguments of :func:`~jaxbox.fit.fit_model`; they apply to every dataset. Initial
    states are guessed from each dataset's own first samples, and each dataset gets ``starts``
    starts
    (the guess plus Latin-hypercube samples around it, with the same ``seed``), or the same
    explicit starts [S, n_free]. ``slots`` counts the starts iterated together over all
    datasets.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or a library model name.
        datasets: a sequence of :class:`~jaxbox.data.Dataset`, or a mapping ``name -> Dataset``;
            all with the same step.

    Returns:
        One :class:`~jaxbox.fit.FitResult` per dataset: a list, or a dict with the same keys.
        Their ``timing`` is that of the whole batch (``batch`` holds the number of datasets;
        ``slots``, the starts iterated together in each of ``parts`` queues).

    Raises:
        FitError: no dataset, datasets of different steps, a problem that differs in its
            free/fixed split between datasets, or every start of one dataset failed.
    """
    require_x64()
    keys = list(datasets) if isinstance(datasets, Mapping) else None
    items = [datasets[k] for k in keys] if keys is not None else list(datasets)
    if not items:
        raise FitError("fit_many needs at least one dataset")
    model = get_model(model, data_columns(items[0]))
    step = items[0].step
    for i, data in enumerate(items):
        label = keys[i] if keys is not None else i
        if abs(data.step - step) > 1e-9 * step:
            raise FitError(
                f"dataset {label!r} has a sample every {data.step:g} s but the first every "
                f"{step:g} s; batched datasets need the same step (resample them), or fit them "
                "one by one"
            )
    common = {
        "free": free,
        "fixed": fixed,
        "bounds": bounds,
        "guess": guess,
        "starts": starts,
        "seed": seed,
        "weights": weights,
        "simulator": simulator,
        "sim_options": sim_options,
        "concentration": concentration,
        "max_steps": max_steps,
        "rtol": rtol,
        "atol": atol,
        "solver": solver,
        "homotopy": homotopy,
        "release": release,
        "max_gap": max_gap,
    }
    outcomes = fit_batch(
        [{"model": model, "data": data, **common} for data in items], slots=slots, errors="return"
    )
    results = []
    for i, outcome in enumerate(outcomes):
        if isinstance(outcome, Exception):
            label = keys[i] if keys is not None else i
            raise FitError(f"dataset {label!r}: {outcome}") from None
        results.append(outcome)
    return dict(zip(keys, results, strict=True)) if keys is not None else results


def request_problem(request: Mapping, *, warn: bool = True) -> tuple:
    """The :class:`~jaxbox.fit.Problem` of a :func:`fit_batch` request and its data prepared
    for the fit (:func:`fit_data`; ``warn``: its warnings per gap), as the batch sets them up
    (the defaults where the request is silent). Raises as :func:`fit_batch` refuses a
    request."""
    arg = {k: request.get(k, _DEFAULTS[k]) for k in (*_PROBLEM, "max_gap")}
    model = get_model(request["model"], data_columns(request["data"]))
    model, data = fit_data(model, request["data"], arg["max_gap"], warn=warn)
    return make_problem(model, data, **{k: arg[k] for k in _PROBLEM}), data


def _batches(requests: Sequence[Mapping], errors: str) -> tuple[list, dict]:
    """The requests prepared (problem, data, starts, arrays, solver settings) and grouped into
    the batches :func:`fit_batch` solves together; a request that cannot be set up is its
    :class:`FitError` in ``outcomes`` (``errors="return"``) or raises it."""
    unknown = sorted({k for r in requests for k in r} - {"model", "data", *_DEFAULTS})
    if unknown:
        raise FitError(f"unknown fit argument(s) in a request: {', '.join(unknown)}")
    outcomes: list = [None] * len(requests)
    prepared = []  # (index, problem, data, starts, arrays, solver settings)
    for i, req in enumerate(requests):
        try:
            if "model" not in req or "data" not in req:
                raise FitError(f"request {i} needs 'model' and 'data'")
            arg = {k: req.get(k, _DEFAULTS[k]) for k in _DEFAULTS}
            problem, data = request_problem(req)
            x0 = make_starts(problem, data, *(arg[k] for k in _STARTS))
            solver = (
                _max_steps(arg["max_steps"]),
                _tolerance(arg["rtol"], "rtol"),
                _tolerance(arg["atol"], "atol"),
                arg["solver"],
                check_homotopy(arg["homotopy"]),
                _release(arg["release"]),
            )
            continued = check_continued(arg["continued"], 1)[0]
            polish = check_polish(arg["polish"], 1)[0]
            prepared.append(
                (i, problem, data, x0, problem_arrays(problem, data), solver, continued, polish)
            )
        except FitError as err:
            if errors == "raise":
                raise
            outcomes[i] = err
    groups: dict = {}
    for item in prepared:
        _, problem, _, x0, arrays, solver, _, _ = item
        shape = (
            x0.shape[1],
            len(problem.fixed),
            len(problem.model.states),
            problem.model.segments,
            tuple(problem.output_states),
            # the weights broadcast to the outputs' shape (solve_jobs): data with an output gap
            # (weights [N, p]) batch with data without one (weights [p])
            *(np.shape(a) for a in arrays[:3]),
        )
        fused = solver[3] is None or isinstance(solver[3], LevenbergMarquardt)
        structure = None if problem.simulator == "exact" and fused else _problem_key(problem)
        if structure is None:  # variants of any size share a compiled solve (padded), and
            # records of neighbouring lengths (padded with samples of weight 0, see solve_jobs)
            t, _, y, _ = arrays
            shape = (
                problem.model.segments,
                tuple(problem.output_states),
                bucket_samples(len(t)),
                np.shape(y)[1:],
            )
        key = (*solver[:3], solver_key(solver[3]), *solver[4:])
        groups.setdefault((key, shape, problem.simulator, structure), []).append(item)
    return outcomes, groups


def _solve(members: list, slots, bucket, compile_only: bool = False) -> dict:
    """:func:`~jaxbox.fit.solve_jobs` for one batch of :func:`_batches` (its members share the
    solver settings)."""
    max_steps, rtol, atol, solver, homotopy, release = members[0][5]
    return solve_jobs(
        [(problem, x0, arrays) for _, problem, _, x0, arrays, *_ in members],
        max_steps=max_steps,
        rtol=rtol,
        atol=atol,
        slots=slots,
        solver=solver,
        homotopy=homotopy,
        release=release,
        bucket=bucket,
        continued=[m[6] for m in members],
        polish=[m[7] for m in members],
        compile_only=compile_only,
    )


def fit_batch(
    requests: Sequence[Mapping],
    *,
    slots: int | None = None,
    errors: str = "raise",
    bucket: bool | Mapping[str, int] = False,
) -> list[FitResult | FitError]:
    """Several estimation problems solved together: one compiled call per compatible group.

    A request is a mapping with ``model`` and ``data`` and any of the keyword arguments of
    :func:`~jaxbox.fit.fit_model` (``free``, ``fixed``, ``bounds``, ``guess``, ``starts``, ``seed``,
    ``weights``, ``simulator``, ``sim_options``, ``concentration``, ``max_steps``, ``rtol``,
    ``atol``, ``solver``, ``homotopy``, ``release``, ``max_gap``) and ``continued``, how many of
    its starts (the first ones) are solved along the continuation as well (``None``: all; the
    others along the output-error route alone), and ``polish``, how many of its best starts are
    solved on to ``rtol`` after every start was solved to a looser tolerance (``None``: every
    start to ``rtol``; see :func:`~jaxbox.fit.solve_jobs`). Requests with the same number
    of free parameters, data of the same shape and the same solver settings are solved in one
    batch (with the exact simulator even when their model structures, numbers of states,
    parameters and inputs differ, provided they measure the same states: the smaller ones are
    padded, and so are records of neighbouring lengths, see :func:`~jaxbox.fit.solve_jobs`;
    with diffrax only for the same structure and length); the others in batches of their own.
    Each result is the one :func:`~jaxbox.fit.fit_model` would return for its request (to
    rounding, where its record was padded or batched with others).

    Args:
        requests: the problems, in order.
        slots: starts iterated together in each batch (default: from the batch size).
        errors: ``"raise"`` (default) raises the first :class:`FitError` (a problem that cannot
            be set up, or every start of a request failed); ``"return"`` puts it in the
            request's place in the returned list and solves the others.
        bucket: round each batch's sizes up (see :func:`~jaxbox.fit.solve_jobs`), so that
            later calls with batches of neighbouring sizes reuse its compiled program (the steps
            of a structure search). The results are the same, to rounding. A mapping sets
            sizes to pad to at least (``{"inputs": 12}``; a result's ``timing["sizes"]``, the
            sizes its bucketed batch was padded to, makes a later call reuse that program).

    Returns:
        One :class:`FitResult` (or :class:`FitError`) per request, in order; ``timing`` is that
        of the request's batch (``batch``: the number of requests in it; ``sizes``, where the
        batch was bucketed: the sizes it was padded to).
    """
    require_x64()
    if errors not in ("raise", "return"):
        raise FitError(f"errors must be 'raise' or 'return', got {errors!r}")
    outcomes, groups = _batches(requests, errors)
    for members in groups.values():
        max_steps, rtol, atol, _, homotopy, release = members[0][5]
        out = _solve(members, slots, bucket)
        timing = {
            "compile_s": out["compile_s"],
            "fit_s": out["fit_s"],
            "batch": len(members),
            "slots": out["slots"],
            "parts": out["parts"],
        }
        if out["sizes"] is not None:  # a bucketed batch: the sizes a later call may pad to
            timing["sizes"] = dict(out["sizes"])
        first = 0
        for i, problem, data, x0, _, _, continued, polish in members:
            sl = slice(first, first + len(x0))
            first += len(x0)
            settings = {
                "max_steps": max_steps,
                "rtol": rtol,
                "atol": atol,
                "homotopy": homotopy,
                "release": release,
                "continued": continued,
                "polish": polish,
                "seed": requests[i].get("seed", _DEFAULTS["seed"]),
                "slots": slots,
                "max_gap": duration_seconds(requests[i].get("max_gap", _DEFAULTS["max_gap"])),
            }
            try:
                outcomes[i] = result_from(problem, data, x0, out, sl, settings, dict(timing))
            except FitError as err:
                if errors == "raise":
                    raise
                outcomes[i] = err
    return outcomes


def compile_batch(
    requests: Sequence[Mapping],
    *,
    slots: int | None = None,
    bucket: bool | Mapping[str, int] = True,
) -> list[dict]:
    """The compiled programs :func:`fit_batch` would run for ``requests``, built and kept for
    the calls to come, without solving anything (a structure search compiles the size it is
    about to grow to in a background thread while it fits the current one).

    Args: as :func:`fit_batch` (a request that cannot be set up raises its :class:`FitError`).

    Returns:
        Per batch: ``compile_s`` [s], ``built`` (whether this call compiled the program: not
        where it was compiled or loaded before) and ``sizes`` (with ``bucket``: the sizes the
        batch was padded to).
    """
    require_x64()
    _, groups = _batches(requests, "raise")
    return [_solve(members, slots, bucket, compile_only=True) for members in groups.values()]
