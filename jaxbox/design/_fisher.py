"""The Fisher information of a planned experiment, as a differentiable function of its heating.

For an experiment with inputs ``U`` [N, m] (the weather and the planned heating) and output noise
of standard deviation σ [K], white and the same on every output, the information about the
estimated parameters is::

    F = Jᵀ J / σ²,        J = ∂ŷ/∂φ  [N·outputs, p],

with ŷ the outputs of the exact first-order-hold simulation (the same simulator as the fit) and
φ the *design coordinates* of the free parameters: ``log θ`` for ratio-scale parameters
(``R_*``, ``C_*``, ``gA*``, ``fra_*``), so that ``√(F⁻¹)_ii`` is a relative standard deviation,
and ``θ`` itself [K] for temperatures (the initial states). J comes from forward-mode autodiff
through the simulator; the criteria below are differentiated once more, in reverse mode, with
respect to the heating.

Criteria (all *minimised*; the initial states are nuisance parameters: they are estimated with
the others, but the criteria look at the marginal covariance ``Σ_s`` of the model parameters)::

    D:    log det Σ_s             (= −log det of the information about them, D_s-optimality)
    A:    log trace Σ_s           (the sum of squared relative standard deviations)
    hlc:  log var(log HLC) = log cᵀ F⁻¹ c,   c = ∂ log HLC / ∂φ  (c-optimality)

The heat-loss coefficient HLC [W/K] is the inverse of the steady-state gain from the heating to
the zone temperature, ``1 / (C (−A)⁻¹ B)_{zone, heating}``, computed from the parameters and
differentiated by autodiff.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .._derivatives import value_and_jacfwd
from ..models import ModelError, RCModel
from ..simulate._exact import discretize_foh_rc
from ..simulate._parallel import normal_equations_auto

__all__ = ["CRITERIA", "Setup", "make_setup", "RATIO_PREFIXES"]

CRITERIA = ("D", "A", "hlc")
"""Design criteria: log det (``D``) or trace (``A``) of the relative parameter covariance, or
the variance of the heat-loss coefficient (``hlc``)."""
#: parameters whose design coordinate is the logarithm (relative precision)
RATIO_PREFIXES = ("R_", "C_", "gA", "fra_")


@dataclasses.dataclass(frozen=True, eq=False)
class Setup:
    """The static side of a design problem: model, free parameters, which input is designed.

    Attributes:
        model: the RC model.
        free: the estimated parameters (model order), initial states included.
        log: per free parameter, True when its coordinate is ``log θ``.
        interest: indices (into ``free``) of the parameters the D and A criteria look at: every
            free parameter that is not an initial state.
        heating: the designed input (a heat flow [W]).
        heat_index: its position in ``model.inputs``.
        hlc_output: the output whose steady-state gain defines the HLC.
        output_states: the state measured by each output.
    """

    model: RCModel
    free: tuple[str, ...]
    log: tuple[bool, ...]
    interest: tuple[int, ...]
    heating: str
    heat_index: int
    hlc_output: int
    output_states: tuple[int, ...]

    @property
    def key(self) -> tuple:
        """What compiled functions of this setup depend on besides array shapes."""
        return (self.model.structure, self.free, self.log, self.heat_index, self.hlc_output)

    @property
    def weather_inputs(self) -> tuple[str, ...]:
        """The inputs taken from the weather (every input but the heating)."""
        return tuple(u for u in self.model.inputs if u != self.heating)

    # ---- coordinates -------------------------------------------------------------------------
    def to_coords(self, theta: Mapping) -> np.ndarray:
        """Design coordinates φ of the free parameters (log for ratio-scale ones)."""
        return np.asarray(
            [
                np.log(float(theta[n])) if lg else float(theta[n])
                for n, lg in zip(self.free, self.log, strict=True)
            ]
        )

    def theta(self, phi, fixed: Mapping) -> dict:
        """θ dict from design coordinates φ [p] and the other parameters' values."""
        out = dict(fixed)
        for i, (n, lg) in enumerate(zip(self.free, self.log, strict=True)):
            out[n] = jnp.exp(phi[i]) if lg else phi[i]
        return out

    # ---- simulation --------------------------------------------------------------------------
    def steady_state(self, theta: Mapping, u):
        """Steady state x [°C] for constant inputs u [m] (held nodes at their value)."""
        A, B, _, held = self.model.rc_form(theta)
        x_held = self.model.initial_state(theta)
        dyn = np.asarray([i for i, h in enumerate(held) if not h])
        hel = np.asarray([i for i, h in enumerate(held) if h], dtype=int)
        rhs = B[dyn] @ u
        if len(hel):
            rhs = rhs + A[np.ix_(dyn, hel)] @ x_held[hel]
        xd = jnp.linalg.solve(-A[np.ix_(dyn, dyn)], rhs)
        return x_held.at[dyn].set(xd)

    def hlc(self, theta: Mapping):
        """Heat-loss coefficient [W/K]: inverse steady-state gain heating → ``hlc_output``."""
        m = len(self.model.inputs)
        e = jnp.zeros((m,)).at[self.heat_index].set(1.0)
        base = self.steady_state({**theta}, jnp.zeros((m,)))
        x = self.steady_state(theta, e)
        s = self.output_states[self.hlc_output]
        return 1.0 / (x[s] - base[s])

    # ---- information -------------------------------------------------------------------------
    def matrices(self, phi, fixed, dt):
        """Discrete first-order-hold matrices ``(Φ, Γ0, Γ1, x0)`` at design coordinates φ."""
        theta = self.theta(phi, fixed)
        A, B, caps, held = self.model.rc_form(theta)
        Phi, G0, G1 = discretize_foh_rc(A, B, caps, dt, held)
        return Phi, G0, G1, self.model.initial_state(theta)

    def linearise(self, phis, fixed, dt):
        """What does not depend on the inputs, per prior sample (rows of ``phis`` [S, p]): the
        matrices, their derivatives ``∂/∂φ`` (forward-mode autodiff, a trailing axis of length
        p), ``c = ∂ log HLC/∂φ`` [S, p] and the HLC [W/K], shape [S]."""

        def one(phi):
            mats, tangents = value_and_jacfwd(self.matrices)(phi, fixed, dt)
            log_hlc = lambda p: jnp.log(self.hlc(self.theta(p, fixed)))  # noqa: E731
            return mats, tangents, jax.grad(log_hlc)(phi), self.hlc(self.theta(phi, fixed))

        return jax.vmap(one)(phis)

    def information(self, mats, tangents, U, sigma):
        """Fisher information ``F = JᵀJ/σ²`` [S, p, p] of inputs U [N, m] for each sample.

        J is propagated with the state by the fit's own sensitivity recursion
        (:func:`~jaxbox.simulate._exact.normal_equations`: ``X_{k+1} = Φ X_k + ∂Φ x_k + ∂Γ0 u_k
        + ∂Γ1 Δu_k``; parallel in time on an accelerator, as the fit), and only ``JᵀJ`` is
        kept; it is differentiable in U.
        """
        n, p = U.shape[0], len(self.output_states)
        zeros = jnp.zeros((n, 1, p), dtype=U.dtype)
        _, _, H = normal_equations_auto(
            mats, tangents, self.output_states, U[:, None, :], zeros, jnp.ones_like(zeros)
        )
        return H / sigma**2

    def simulate(self, mats, U):
        """Outputs [N, p] of one sample's matrices ``(Φ, Γ0, Γ1, x0)`` for inputs U [N, m]."""
        Phi, G0, G1, x0 = mats
        drive = U[:-1] @ G0.T + (U[1:] - U[:-1]) @ G1.T

        def step(x, d):
            x = Phi @ x + d
            return x, x

        _, xs = jax.lax.scan(step, x0, drive)
        xs = jnp.concatenate([x0[None, :], xs], axis=0)
        return xs[:, np.asarray(self.output_states)]

    def covariance(self, F):
        """``F⁻¹`` through a Cholesky factorisation of the Jacobi-scaled (unit-diagonal) F."""
        d = 1.0 / jnp.sqrt(jnp.diagonal(F))
        Fs = F * d[:, None] * d[None, :]
        L = jnp.linalg.cholesky(0.5 * (Fs + Fs.T))
        eye = jnp.eye(F.shape[0], dtype=F.dtype)
        return jax.scipy.linalg.cho_solve((L, True), eye) * d[:, None] * d[None, :]

    def criterion(self, name: str, F, c):
        """The design loss (smaller is better) of information F; c: the HLC gradient."""
        cov = self.covariance(F)
        idx = np.asarray(self.interest)
        sub = cov[np.ix_(idx, idx)]
        if name == "D":
            return jnp.linalg.slogdet(sub)[1]
        if name == "A":
            return jnp.log(jnp.trace(sub))
        if name == "hlc":
            return jnp.log(c @ cov @ c)
        raise ValueError(f"unknown criterion {name!r}; choose one of {', '.join(CRITERIA)}")


def make_setup(model: RCModel, free, heating: str | None = None) -> Setup:
    """Check the model and the free parameters; find the heating input and the HLC output."""
    names = model.param_names
    bad = [n for n in free if n not in names]
    if bad:
        raise ModelError(
            f"model {model.name} has no parameter(s) {', '.join(bad)}; its parameters are "
            f"{', '.join(names)}"
        )
    free = tuple(n for n in names if n in set(free))
    if not free:
        raise ModelError("nothing to estimate: give at least one free parameter")
    if heating is None:
        candidates = [u for u in model.inputs if u.startswith("Q_hea")]
        if len(candidates) != 1:
            raise ModelError(
                f"model {model.name} has {len(candidates)} heating inputs "
                f"({', '.join(candidates) or 'none'}); name the designed one with heating="
            )
        heating = candidates[0]
    if heating not in model.inputs:
        raise ModelError(
            f"model {model.name} has no input {heating!r}; its inputs are {', '.join(model.inputs)}"
        )
    if not heating.startswith("Q_"):
        heat = [u for u in model.inputs if u.startswith("Q_")]
        raise ModelError(
            f"heating={heating!r} is not a heat flow input of {model.name} (Q_*, [W]); name one "
            f"of {', '.join(heat) or 'none'}"
        )
    log = tuple(n.startswith(RATIO_PREFIXES) for n in free)
    interest = tuple(i for i, n in enumerate(free) if not model.parameter(n).is_initial_state)
    if not interest:
        raise ModelError("only initial states are free: there is nothing to design for")
    nodes = model.network.nodes
    output_states = tuple(
        next(i for i, m in enumerate(nodes) if m.output == o) for o in model.outputs
    )
    return Setup(
        model=model,
        free=free,
        log=log,
        interest=interest,
        heating=heating,
        heat_index=model.inputs.index(heating),
        hlc_output=0,
        output_states=output_states,
    )
