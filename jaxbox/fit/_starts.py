"""Initial guesses: defaults from the data, and Latin-hypercube starts from beta distributions.

For each free parameter a univariate beta distribution on its bounds (in the transform's own
scale: logarithmic for resistances and capacities, linear otherwise) has its mode at the guess:
``Beta(1 + κ f, 1 + κ (1 − f))`` with ``f`` the guess's relative position in the bounds —
symmetric when the guess is central, skewed towards the guess otherwise. ``n`` stratified samples
are drawn per parameter (one in each of ``n`` equal-probability strata) and the columns are
shuffled independently, so the ``n`` starts cover every parameter's range evenly.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ._transforms import _FREE, _LIN, _LOG, _LOWER, Transform

__all__ = ["latin_hypercube"]

_EPS = 1e-6


def latin_hypercube(
    transform: Transform,
    guess,
    n: int,
    seed: int | None = 0,
    concentration: float = 4.0,
) -> np.ndarray:
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
    rng = np.random.default_rng(seed)
    guess = np.asarray(guess, dtype=float)
    p = len(guess)
    out = np.empty((n, p))
    for i, k in enumerate(transform.kinds):
        u = (rng.permutation(n) + rng.random(n)) / n
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
