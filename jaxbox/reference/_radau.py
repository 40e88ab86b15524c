"""Radau IIA collocation: nodes, quadrature weights, Runge–Kutta matrix and differentiation matrix.

For ``n_c`` collocation points on the normalised element ``τ ∈ [0, 1]`` the Radau IIA nodes
``c_1 < … < c_{n_c} = 1`` are the zeros of ``P_{n_c}(2τ − 1) − P_{n_c − 1}(2τ − 1)`` (``P_k`` the
Legendre polynomials). Everything else follows from the Lagrange polynomials:

* ``A[i, j] = ∫_0^{c_i} ℓ_j(τ) dτ`` and ``b[j] = ∫_0^1 ℓ_j(τ) dτ`` with ``ℓ_j`` the Lagrange basis
  through the collocation points (Butcher tableau; ``b`` is the last row of ``A``);
* ``D[i, l] = L_l'(c_i)`` (barycentric formula) with ``L_l`` the Lagrange basis through
  ``τ_0 = 0`` and the collocation points (``l = 0 … n_c``): a state polynomial
  ``x(τ) = Σ_l L_l(τ) x_l`` satisfies ``dx/dt(c_i) = (1/h) Σ_l D[i, l] x_l`` on an element of
  length ``h``.

The method has stage order ``n_c`` and order ``2 n_c − 1`` at the element ends; the quadrature
``Σ_j b_j g(c_j)`` is exact for polynomials of degree ``2 n_c − 2``. Everything is computed in
float64 numpy from these definitions (nothing is tabulated); the nodes are polished by Newton
steps on the defining polynomial.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
from jaxtyping import Float
from numpy.polynomial import legendre as leg

__all__ = ["RadauIIA", "radau_iia", "MAX_POINTS"]

#: Largest supported number of collocation points per element.
MAX_POINTS = 5


@dataclasses.dataclass(frozen=True, eq=False)
class RadauIIA:
    """Radau IIA collocation scheme with ``n_c`` points (arrays are read-only float64).

    Attributes:
        n_c: number of collocation points per element.
        c: nodes ``c_1 … c_{n_c}`` in ``(0, 1]`` (``c_{n_c} = 1``).
        b: quadrature weights (sum 1).
        A: Runge–Kutta matrix ``[n_c, n_c]``.
        D: differentiation matrix ``[n_c, n_c + 1]`` on the points ``(0, c_1, …, c_{n_c})``.
        order: classical order at the element ends, ``2 n_c − 1``.
        stage_order: ``n_c``.
    """

    n_c: int
    c: Float[np.ndarray, " points"]
    b: Float[np.ndarray, " points"]
    A: Float[np.ndarray, "points points"]
    D: Float[np.ndarray, "points points+1"]

    @property
    def order(self) -> int:
        return 2 * self.n_c - 1

    @property
    def stage_order(self) -> int:
        return self.n_c

    @property
    def tau(self) -> Float[np.ndarray, " points+1"]:
        """The interpolation points of the state polynomial: ``(0, c_1, …, c_{n_c})``."""
        return np.concatenate([[0.0], self.c])


def _nodes(n_c: int) -> np.ndarray:
    # P_n - P_{n-1} in the Legendre basis, on ξ = 2τ − 1 ∈ [−1, 1]
    coef = np.zeros(n_c + 1)
    coef[n_c] = 1.0
    coef[n_c - 1] -= 1.0
    xi = np.sort(np.real(leg.legroots(coef)))
    dcoef = leg.legder(coef)
    for _ in range(3):  # Newton polish (ξ = 1 is exact already)
        step = leg.legval(xi, coef) / leg.legval(xi, dcoef)
        xi = np.where(np.isclose(xi, 1.0), 1.0, xi - step)
    c = 0.5 * (xi + 1.0)
    c[-1] = 1.0
    return c


def _lagrange_values(points: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``ℓ_j(x)`` [len(x), len(points)] for the Lagrange basis through ``points`` (product form)."""
    out = np.ones((len(x), len(points)))
    for j, pj in enumerate(points):
        for k, pk in enumerate(points):
            if k != j:
                out[:, j] *= (x - pk) / (pj - pk)
    return out


def _integrals(points: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``∫_0^{u_i} ℓ_j(τ) dτ`` [len(upper), len(points)], by (exact) Gauss–Legendre quadrature."""
    xg, wg = leg.leggauss(len(points))
    out = np.empty((len(upper), len(points)))
    for i, ui in enumerate(upper):
        out[i] = 0.5 * ui * (wg @ _lagrange_values(points, 0.5 * ui * (xg + 1.0)))
    return out


def _differentiation(points: np.ndarray) -> np.ndarray:
    """Lagrange differentiation matrix ``L_l'(τ_i)`` in barycentric form (rows sum to zero)."""
    diff = points[:, None] - points[None, :]
    np.fill_diagonal(diff, 1.0)
    w = 1.0 / np.prod(diff, axis=1)
    D = (w[None, :] / w[:, None]) / diff
    np.fill_diagonal(D, 0.0)
    np.fill_diagonal(D, -D.sum(axis=1))
    return D


@cache
def radau_iia(n_c: int = 3) -> RadauIIA:
    """The Radau IIA scheme with ``n_c`` (1 … 5) collocation points per element."""
    if not isinstance(n_c, int | np.integer) or not 1 <= n_c <= MAX_POINTS:
        raise ValueError(f"n_c must be an integer from 1 to {MAX_POINTS}, got {n_c!r}")
    n_c = int(n_c)
    c = _nodes(n_c)
    A = _integrals(c, c)
    b = A[-1].copy()
    D = _differentiation(np.concatenate([[0.0], c]))[1:]
    for arr in (c, b, A, D):
        arr.setflags(write=False)
    return RadauIIA(n_c=n_c, c=c, b=b, A=A, D=D)
