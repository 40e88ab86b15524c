"""Initial guesses: defaults from the data, and Latin-hypercube starts from beta distributions.

For each free parameter a univariate beta distribution on its bounds (in the transform's own
scale: logarithmic for resistances and capacities, linear otherwise) has its mode at the guess:
``Beta(1 + κ f, 1 + κ (1 − f))`` with ``f`` the guess's relative position in the bounds —
symmetric when the guess is central, skewed towards the guess otherwise. ``n`` stratified samples
are drawn per parameter (one in each of ``n`` equal-probability strata, by
:class:`scipy.stats.qmc.LatinHypercube`) and combined at random, so the ``n`` starts cover every
parameter's range evenly.

:func:`sample_starts` is the one sampler of starts: the guess plus ``n − 1`` such samples, with
initial temperatures drawn within their data-derived range (:func:`~jaxbox.fit.state_ranges`)
instead of the wide default bounds of ``T_*0``. ``fit_model(starts=n)`` and a selection case with
``n`` starts both use it, so they draw the same starts for the same seed and guess.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from jaxtyping import Float
from scipy import stats
from scipy.stats import qmc

from .._defaults import DEFAULT_CONCENTRATION
from ._guess import state_ranges
from ._problem import FitError, number
from ._transforms import _FREE, _LIN, _LOG, _LOWER, Transform

__all__ = ["latin_hypercube", "sample_starts"]

_EPS = 1e-6


def _check_sampling(seed, concentration) -> None:
    """A seed NumPy takes (None or an integer ≥ 0) and a concentration κ ≥ 0, finite."""
    integer = isinstance(seed, int | np.integer) and not isinstance(seed, bool | np.bool_)
    if seed is not None and not (integer and seed >= 0):
        raise FitError(f"seed must be an integer ≥ 0 or None, got {seed!r}")
    concentration = number(concentration, "concentration")
    if not (np.isfinite(concentration) and concentration >= 0):
        raise FitError(
            f"concentration must be a finite number ≥ 0 (0: uniform strata; the fit's default "
            f"{DEFAULT_CONCENTRATION:g}), got {concentration!r}"
        )


def latin_hypercube(
    transform: Transform,
    guess,
    n: int,
    seed: int | None = 0,
    concentration: float = DEFAULT_CONCENTRATION,
) -> Float[np.ndarray, "n free"]:
    """``n`` Latin-hypercube starts [n, p] (physical values) around ``guess`` within the bounds.

    Args:
        transform: bounds and scale kinds of the free parameters.
        guess: physical guess per parameter, shape [p].
        n: number of starts.
        seed: random seed (reproducible for a seed).
        concentration: κ ≥ 0; 0 gives uniform strata, larger values cluster near the guess.
    """
    if n < 1:
        raise ValueError(f"the number of starts must be at least 1, got {n}")
    _check_sampling(seed, concentration)
    guess = np.asarray(guess, dtype=float)
    p = len(guess)
    strata = qmc.LatinHypercube(d=max(p, 1), seed=np.random.default_rng(seed)).random(n)
    out = np.empty((n, p))
    for i, k in enumerate(transform.kinds):
        u = strata[:, i]
        if k in (_LOG, _LIN):
            lo, hi = transform.lower[i], transform.upper[i]
            if k == _LOG:
                lo, hi, g = np.log(lo), np.log(hi), np.log(guess[i])
            else:
                g = guess[i]
            f = float(np.clip((g - lo) / (hi - lo), 0.0, 1.0))
            a, b = 1 + concentration * f, 1 + concentration * (1 - f)
            x = np.clip(stats.beta.ppf(u, a, b), _EPS, 1 - _EPS)
            v = lo + (hi - lo) * x
            out[:, i] = np.exp(v) if k == _LOG else v
        elif k == _LOWER:
            lo, s = transform.lower[i], transform.scale[i]
            z = np.log(max(guess[i] - lo, _EPS * s) / s) + 4 * (stats.beta.ppf(u, 3, 3) - 0.5)
            out[:, i] = lo + s * np.exp(z)
        elif k == _FREE:
            s = transform.scale[i]
            out[:, i] = guess[i] + 4 * s * (stats.beta.ppf(u, 3, 3) - 0.5)
    return out


def sample_starts(
    problem, data, n: int, seed: int | None = 0, concentration: float = DEFAULT_CONCENTRATION
) -> Float[np.ndarray, "starts free"]:
    """The guess plus ``n − 1`` Latin-hypercube starts [n, n_free] (physical values).

    Initial temperatures are sampled within their data-derived range (:func:`state_ranges`),
    intersected with their bounds, when the guess lies inside it; every other parameter within
    its bounds (:func:`latin_hypercube`). Reproducible for a seed.
    """
    if n < 1:
        raise ValueError(f"the number of starts must be at least 1, got {n}")
    _check_sampling(seed, concentration)
    tr = problem.transform
    g = np.asarray([problem.guess_dict[k] for k in problem.free])
    if n == 1:
        return g[None, :]
    ranges = state_ranges(problem.model, data)
    lo, hi = np.array(tr.lower, dtype=float), np.array(tr.upper, dtype=float)
    for i, name in enumerate(problem.free):
        if name in ranges:
            a, _, b = ranges[name]
            a, b = max(a, lo[i]), min(b, hi[i])
            if a < g[i] < b:
                lo[i], hi[i] = a, b
    sampling = dataclasses.replace(tr, lower=lo, upper=hi)
    lhs = latin_hypercube(sampling, g, n - 1, seed, concentration)
    return np.concatenate([g[None, :], lhs], axis=0)
