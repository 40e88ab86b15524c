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
import scipy.special

__all__ = ["Transform", "make_transform", "position_in_bounds", "two_sided", "KINDS"]

KINDS = ("log", "linear", "lower", "free")
_LOG, _LIN, _LOWER, _FREE = range(4)
_EDGE = 1e-12


@dataclasses.dataclass(frozen=True, eq=False)
class Transform:
    """Vectorised bound transform for a fixed list of parameters.

    ``kinds`` (tuple of int codes) is static; ``lower``, ``upper``, ``scale`` are float arrays.
    """

    names: tuple[str, ...]
    kinds: tuple[int, ...]
    lower: np.ndarray
    upper: np.ndarray
    scale: np.ndarray
    style: str = "logistic"

    def kind_names(self) -> list[str]:
        return [KINDS[k] for k in self.kinds]

    def to_physical(self, z, lower=None, upper=None, scale=None):
        """Physical values p [SI] from internal coordinates z (any leading batch dims): jnp,
        or NumPy for a NumPy ``z`` (no JAX dispatch, e.g. on a fit's results)."""
        xp = np if isinstance(z, np.ndarray) else jnp
        lo = self.lower if lower is None else lower
        hi = self.upper if upper is None else upper
        s = self.scale if scale is None else scale
        kinds = np.asarray(self.kinds)
        sig = _squash(self.style, z, xp)
        out = []
        lo, hi, s = (xp.asarray(a, dtype=z.dtype) for a in (lo, hi, s))
        for i, k in enumerate(kinds):
            zi, si = z[..., i], sig[..., i]
            loi, hii, sci = lo[..., i], hi[..., i], s[..., i]
            if k == _LOG:
                llo, lhi = xp.log(loi), xp.log(hii)
                out.append(xp.exp(llo + (lhi - llo) * si))
            elif k == _LIN:
                out.append(loi + (hii - loi) * si)
            elif k == _LOWER:
                out.append(loi + sci * xp.exp(zi))
            else:
                out.append(sci * zi)
        return xp.stack(out, axis=-1)

    def at_position(self, fraction: float) -> np.ndarray:
        """Physical values [n] of every parameter at ``fraction`` (0 … 1) of its range, in
        this transform's scale (logarithmic for ``log``); meaningful for the two-sided kinds
        (:func:`two_sided`), e.g. ``1e-3``: next to the lower bounds."""
        z = np.full(len(self.names), _unsquash(self.style, fraction), dtype=float)
        return self.to_physical(z)

    def to_internal(self, p):
        """Internal coordinates z from physical values p (numpy; bound values are nudged in)."""
        p = np.asarray(p, dtype=float)
        z = np.empty_like(p)
        for i, k in enumerate(self.kinds):
            lo, hi, s = self.lower[i], self.upper[i], self.scale[i]
            pi = p[..., i]
            if k == _LOG:
                f = (np.log(pi) - np.log(lo)) / (np.log(hi) - np.log(lo))
                z[..., i] = _unsquash(self.style, f)
            elif k == _LIN:
                z[..., i] = _unsquash(self.style, (pi - lo) / (hi - lo))
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


def to_physical_coded(z, lower, upper, scale, kinds, style: str = "logistic"):
    """:meth:`Transform.to_physical` with the kinds as an array (codes of :data:`KINDS`) instead
    of static: one program for parameters of any kinds (the batched fit of model variants)."""
    sig = _squash(style, z)
    is_log = kinds == _LOG
    llo = jnp.log(jnp.where(is_log, lower, 1.0))
    lhi = jnp.log(jnp.where(is_log, upper, 1.0))
    span = jnp.where(jnp.isfinite(upper - lower), upper - lower, 0.0)
    lo = jnp.where(jnp.isfinite(lower), lower, 0.0)
    low = jnp.where(kinds == _LOWER, z, 0.0)
    return jnp.select(
        [is_log, kinds == _LIN, kinds == _LOWER],
        [jnp.exp(llo + (lhi - llo) * sig), lo + span * sig, lo + scale * jnp.exp(low)],
        scale * z,
    )


STYLES = ("logistic", "algebraic", "sine", "unbounded")


def position_in_bounds(style: str, z):
    """Where a two-sided (``log`` or ``linear``) coordinate stands in its bounds, 0 (lower) …
    1 (upper), from its internal value ``z`` (jnp, any shape)."""
    return _squash(style, z)


def _squash(style, z, xp=jnp):
    """Position in the bounds, 0 … 1, from the internal coordinate (slope 1/4 at the centre);
    ``xp``: ``jax.numpy`` or NumPy."""
    if style == "logistic":
        if xp is np:
            return scipy.special.expit(z)
        return jax.nn.sigmoid(z)  # stable value and derivative for any z
    if style == "algebraic":
        h = 0.5 * z
        return 0.5 * (1.0 + h / xp.sqrt(1.0 + h * h))
    if style == "sine":
        return 0.5 * (1.0 + xp.sin(0.5 * z))
    if style == "unbounded":
        return 0.5 + 0.25 * z
    raise ValueError(f"unknown transform style {style!r}; choose one of {STYLES}")


def _unsquash(style, f):
    if style == "unbounded":
        return 4.0 * (np.asarray(f) - 0.5)
    f = np.clip(f, _EDGE, 1 - _EDGE)
    if style == "logistic":
        return np.log(f) - np.log1p(-f)
    if style == "algebraic":
        c = 2.0 * f - 1.0
        return 2.0 * c / np.sqrt(1.0 - c * c)
    if style == "sine":
        return 2.0 * np.arcsin(2.0 * f - 1.0)
    raise ValueError(f"unknown transform style {style!r}; choose one of {STYLES}")


DEFAULT_STYLE = {"style": "logistic"}


def two_sided(kinds) -> np.ndarray:
    """Which coordinates of these kinds have two finite bounds (``log`` and ``linear``)."""
    return np.isin(np.asarray(kinds, dtype=int), (_LOG, _LIN))


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
    return Transform(
        tuple(names), tuple(kinds), lower, upper, np.asarray(scale), DEFAULT_STYLE["style"]
    )
