"""Bounds as smooth reparametrisations: the optimiser works on unbounded, O(1) coordinates z.

Per parameter, chosen from its bounds ``[lo, hi]``:

* ``log``    — ``0 < lo`` and ``hi/lo ≥ 20`` (resistances, capacities spanning decades):
  ``p = exp(log lo + (log hi − log lo)·σ(z))``;
* ``linear`` — finite bounds otherwise (temperatures, fractions, apertures):
  ``p = lo + (hi − lo)·σ(z)``;
* ``lower``  — finite ``lo``, ``hi = ∞``: ``p = lo + s·exp(z)``;
* ``free``   — both infinite: ``p = s·z``.

σ is the logistic function. Bounds are never violated; a parameter that wants to leave them ends
close to its bound, which the result flags (``at_bound``). Kinds are static (they shape the
computation); bounds and scales are arrays, so changing bounds does not recompile.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["Transform", "make_transform", "KINDS"]

KINDS = ("log", "linear", "lower", "free")
_LOG, _LIN, _LOWER, _FREE = range(4)
_EDGE = 1e-12


@dataclasses.dataclass(frozen=True)
class Transform:
    """Vectorised bound transform for a fixed list of parameters.

    ``kinds`` (tuple of int codes) is static; ``lower``, ``upper``, ``scale`` are float arrays.
    """

    names: tuple[str, ...]
    kinds: tuple[int, ...]
    lower: np.ndarray
    upper: np.ndarray
    scale: np.ndarray

    def kind_names(self) -> list[str]:
        return [KINDS[k] for k in self.kinds]

    def to_physical(self, z, lower=None, upper=None, scale=None):
        """Physical values p [SI] from internal coordinates z (jnp, any leading batch dims)."""
        lo = self.lower if lower is None else lower
        hi = self.upper if upper is None else upper
        s = self.scale if scale is None else scale
        kinds = np.asarray(self.kinds)
        sig = jax.nn.sigmoid(z)  # stable value and derivative for any z
        out = []
        for i, k in enumerate(kinds):
            zi, si = z[..., i], sig[..., i]
            if k == _LOG:
                llo, lhi = jnp.log(lo[i]), jnp.log(hi[i])
                out.append(jnp.exp(llo + (lhi - llo) * si))
            elif k == _LIN:
                out.append(lo[i] + (hi[i] - lo[i]) * si)
            elif k == _LOWER:
                out.append(lo[i] + s[i] * jnp.exp(zi))
            else:
                out.append(s[i] * zi)
        return jnp.stack(out, axis=-1)

    def to_internal(self, p):
        """Internal coordinates z from physical values p (numpy; bound values are nudged in)."""
        p = np.asarray(p, dtype=float)
        z = np.empty_like(p)
        for i, k in enumerate(self.kinds):
            lo, hi, s = self.lower[i], self.upper[i], self.scale[i]
            pi = p[..., i]
            if k == _LOG:
                f = (np.log(pi) - np.log(lo)) / (np.log(hi) - np.log(lo))
                f = np.clip(f, _EDGE, 1 - _EDGE)
                z[..., i] = np.log(f) - np.log1p(-f)
            elif k == _LIN:
                f = np.clip((pi - lo) / (hi - lo), _EDGE, 1 - _EDGE)
                z[..., i] = np.log(f) - np.log1p(-f)
            elif k == _LOWER:
                z[..., i] = np.log(np.maximum(pi - lo, _EDGE * s) / s)
            else:
                z[..., i] = pi / s
        return z

    def relative_position(self, p):
        """Position of p within its bounds in the transform's own scale: 0 at lower, 1 at upper.

        ``nan`` for one-sided or unbounded parameters on the open side.
        """
        p = np.asarray(p, dtype=float)
        out = np.full(p.shape, np.nan)
        for i, k in enumerate(self.kinds):
            lo, hi = self.lower[i], self.upper[i]
            if k == _LOG:
                out[..., i] = (np.log(p[..., i]) - np.log(lo)) / (np.log(hi) - np.log(lo))
            elif k == _LIN:
                out[..., i] = (p[..., i] - lo) / (hi - lo)
            elif k == _LOWER:
                out[..., i] = np.where(p[..., i] - lo <= 1e-9 * self.scale[i], 0.0, np.nan)
        return out


def make_transform(names, lower, upper, guess) -> Transform:
    """Choose a transform per parameter from its bounds; ``guess`` sets scales for open bounds."""
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    guess = np.asarray(guess, dtype=float)
    kinds, scale = [], []
    for lo, hi, g in zip(lower, upper, guess, strict=True):
        if np.isfinite(lo) and np.isfinite(hi):
            kinds.append(_LOG if lo > 0 and hi / lo >= 20 else _LIN)
            scale.append(1.0)
        elif np.isfinite(lo):
            kinds.append(_LOWER)
            scale.append(max(abs(g - lo), 1e-3 * max(abs(g), 1.0)))
        elif np.isfinite(hi):
            raise ValueError("a parameter bounded above only is not supported; give a lower bound")
        else:
            kinds.append(_FREE)
            scale.append(max(abs(g), 1.0))
    return Transform(tuple(names), tuple(kinds), lower, upper, np.asarray(scale))
