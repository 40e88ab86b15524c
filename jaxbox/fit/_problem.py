"""The estimation problem: free/fixed parameters, bounds, guesses, weights, and its residuals.

Output-error least squares: the residual of output ``j`` at sample ``k`` is
``sqrt(q_j / N_j) · (ŷ_jk(θ) − y_jk)``, so the cost ``Σ r²`` is the weighted mean squared
simulation error [K²] and ``sqrt(cost)`` an RMSE when there is one output with weight 1.
``N_j`` counts the measured samples of output ``j``: a sample of an output gap (NaN) has
weight 0. Data in segments (gaps cut out, separate periods) are fitted with a model that has
initial states per segment (:meth:`~jaxbox.models.RCModel.segmented`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import jax
import numpy as np

from .._derivatives import value_and_jacfwd
from ..data._args import check_mapping
from ..models import RCModel, get_model
from ..simulate import simulate_arrays
from ..simulate._exact import discretize_foh_rc, normal_equations
from ._guess import initial_guess
from ._transforms import Transform, make_transform

__all__ = ["Problem", "FitError", "make_problem"]


class FitError(ValueError):
    """The estimation problem is ill-posed or every start failed; the message says why."""


def guess_within(name: str, value: float, lower: float, upper: float, given: bool) -> float:
    """The guess ``value`` of parameter ``name`` within its bounds ``[lower, upper]``.

    A default guess outside them is clipped onto them; so is a ``given`` one that lies outside
    by no more than the rounding of a value that went through a bound transform (relative 1e-9
    of the bound, plus 1e-12 of the range): an estimate on its bound, handed back as a guess (a
    parent's optimum, a retry's start), reads ``9.999999999999999e-06`` for a floor of
    ``1e-05``. A given guess further out is refused (``FitError``, naming the parameter)."""
    if lower <= value <= upper:
        return value
    slack = 1e-12 * (upper - lower)
    near = lower - (1e-9 * abs(lower) + slack) <= value <= upper + (1e-9 * abs(upper) + slack)
    if given and not near:
        raise FitError(
            f"guess of {name} = {value:g} lies outside its bounds [{lower:g}, {upper:g}]; give "
            "a guess within them or widen the bounds"
        )
    return float(np.clip(value, lower, upper))


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
    """Everything static about an estimation problem (no data arrays).

    Attributes:
        model: the RC model.
        free: names of the estimated parameters, in model order.
        fixed: fixed parameter values (SI).
        guess: initial guess for every parameter (SI).
        transform: bounds transform of the free parameters.
        weights: output weights q_j (≥ 0), in ``model.outputs`` order.
        simulator: ``"exact"`` or ``"diffrax"``.
        sim_options: options for the diffrax simulator (sorted tuple of items).
    """

    model: RCModel
    free: tuple[str, ...]
    fixed: tuple[tuple[str, float], ...]
    guess: tuple[tuple[str, float], ...]
    transform: Transform
    weights: tuple[float, ...]
    simulator: str = "exact"
    sim_options: tuple = ()

    @property
    def structure_key(self) -> tuple:
        """What a compiled function of this problem depends on besides array shapes: the model
        structure and the free/fixed split (the key of the caches of compiled functions)."""
        return (self.model.structure, self.free, tuple(n for n, _ in self.fixed))

    @property
    def simulation_key(self) -> tuple:
        """:attr:`structure_key` plus the simulator and its options: the key of compiled
        functions that simulate the problem (sensitivities, uncertainty)."""
        return (*self.structure_key, self.simulator, self.sim_options)

    @property
    def fixed_dict(self) -> dict[str, float]:
        return dict(self.fixed)

    @property
    def guess_dict(self) -> dict[str, float]:
        return dict(self.guess)

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        return {
            n: (float(lo), float(hi))
            for n, lo, hi in zip(
                self.transform.names, self.transform.lower, self.transform.upper, strict=True
            )
        }

    def theta(self, p_free, fixed_values) -> dict:
        """θ dict from free values (jnp [p]) and fixed values (jnp [q], in ``fixed`` order)."""
        theta = {n: p_free[..., i] for i, n in enumerate(self.free)}
        theta.update({n: fixed_values[i] for i, (n, _) in enumerate(self.fixed)})
        return theta

    def simulate(self, p_free, fixed_values, t, u):
        """Outputs [N, p] for free parameter values (physical)."""
        theta = self.theta(p_free, fixed_values)
        opts = dict(self.sim_options)
        if self.simulator == "diffrax":
            import diffrax

            opts.setdefault("adaptive", False)
            opts.setdefault("adjoint", diffrax.ForwardMode())
            opts.setdefault("throw", False)
        return simulate_arrays(self.model, theta, t, u, method=self.simulator, **opts)[0]

    def residuals(self, z, args):
        """Weighted residual vector for internal coordinates z (the LM objective)."""
        fixed_values, t, u, y, sqrt_w, lo, hi, sc = args
        p = self.transform.to_physical(z, lo, hi, sc)
        ysim = self.simulate(p, fixed_values, t, u)
        return ((ysim - y) * sqrt_w).ravel()

    # ---- the batched route of the fit --------------------------------------------------------
    def matrices(self, z, fixed_values, lo, hi, sc, dt):
        """Discrete first-order-hold matrices of one parameter set (internal coordinates z).

        Returns ``(Φ, Γ0, Γ1, x0)`` for the sample step ``dt`` [s], through the symmetric
        eigendecomposition of the RC network (:func:`~jaxbox.simulate._exact.discretize_foh_rc`).
        The outputs of an RC network are node temperatures: see :attr:`output_states`.
        """
        p = self.transform.to_physical(z, lo, hi, sc)
        theta = self.theta(p, fixed_values)
        A, B, caps, held = self.model.rc_form(theta)
        Phi, G0, G1 = discretize_foh_rc(A, B, caps, dt, held)
        if self.model.segments > 1:
            return Phi, G0, G1, self.model.initial_states(theta)
        return Phi, G0, G1, self.model.initial_state(theta)

    @property
    def output_states(self) -> tuple[int, ...]:
        """Index of the state measured by each output (outputs of RC networks are nodes)."""
        nodes = self.model.network.nodes
        return tuple(
            next(i for i, m in enumerate(nodes) if m.output == o) for o in self.model.outputs
        )

    def normal_equations(self, Z, members, data, chunk=None):
        """Cost ``Σ r²``, gradient ``Jᵀr`` and Gram matrix ``JᵀJ`` for a batch of coordinates.

        Args:
            Z: internal coordinates [B, p].
            members: per-member arrays ``(fixed [B, q], lo [B, p], hi [B, p], sc [B, p],
                dt [B])``.
            data: ``(t [N, Bd], u [N, Bd, m], y [N, Bd, ny], w [N, Bd, ny])`` with ``Bd`` 1
                (shared) or B; ``w`` holds ``sqrt(q_j/N)`` and 0 for masked samples.

        The exact simulator propagates forward sensitivities with the state in one pass over
        the data (memory independent of its length); the diffrax simulator goes through
        ``jax.jacfwd`` of :meth:`residuals`.
        """
        fixed, lo, hi, sc, dt = members
        t, u, y, w = data
        if self.simulator == "exact":
            args = (Z, fixed, lo, hi, sc, dt)
            primal, tangents = jax.vmap(value_and_jacfwd(self.matrices))(*args)
            return normal_equations(primal, tangents, self.output_states, u, y, w, chunk=chunk, t=t)
        shared = u.shape[1] == 1 and Z.shape[0] != 1
        d_axis = None if shared else 1

        def one(z, f, a, b, c, tt, uu, yy, ww):
            def res(zz):
                p = self.transform.to_physical(zz, a, b, c)
                return ((self.simulate(p, f, tt, uu) - yy) * ww).ravel()

            r, J = value_and_jacfwd(res)(z)
            return r @ r, J.T @ r, J.T @ J

        if shared:
            t, u, y, w = t[:, 0], u[:, 0], y[:, 0], w[:, 0]
        return jax.vmap(one, in_axes=(0, 0, 0, 0, 0, d_axis, d_axis, d_axis, d_axis))(
            Z, fixed, lo, hi, sc, t, u, y, w
        )


def _positive(name: str) -> bool:
    """Resistances [K/W] and capacities [J/K] are positive by the naming convention."""
    return name.startswith(("R_", "C_"))


def _physical(spec, lower: float, upper: float) -> bool | str:
    """True when bounds [lower, upper] keep the parameter ``spec`` physical (the rules of
    :class:`jaxbox.models.Parameter`: resistances and capacities positive, fractions within
    [0, 1]), else the reason, in words."""
    from ..models import ModelError

    try:
        spec.replace(lower=lower, upper=upper, default=min(max(spec.default, lower), upper))
    except ModelError as err:
        return str(err).split(": ", 1)[-1]
    return True


def number(value, what: str) -> float:
    """A real number given for ``what`` (``"fixed value of R_wal"``): a Python or NumPy scalar,
    not a bool, a string, ``None`` or a list, which are a :class:`FitError` naming ``what``."""
    if isinstance(value, bool | np.bool_ | str | bytes) or value is None or np.ndim(value) != 0:
        raise FitError(f"{what} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise FitError(f"{what} must be a number, got {value!r}") from None


def _names(value, what: str) -> list[str]:
    """Parameter names given as one name or a sequence of names."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, Mapping) or not isinstance(value, Sequence | set | frozenset):
        raise FitError(f"{what} must be a parameter name or a list of them, got {value!r}")
    bad = [v for v in value if not isinstance(v, str)]
    if bad:
        raise FitError(f"{what} must hold parameter names, got {bad[0]!r}")
    return list(value)


def make_problem(
    model: RCModel | str,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    weights: Mapping[str, float] | Sequence[float] | None = None,
    simulator: str = "exact",
    sim_options: Mapping | None = None,
) -> Problem:
    """Check and assemble an estimation problem. Every misuse raises :class:`FitError` (a
    ``fixed``, ``bounds`` or ``guess`` that is not a mapping: :class:`TypeError`).

    ``model`` is an :class:`~jaxbox.models.RCModel` or a library model name; ``free`` one
    parameter name or a list of them; ``fixed`` and ``guess`` map names to numbers, ``bounds``
    names to pairs ``(lower, upper)``, in the parameters' units.
    """
    model = get_model(model, getattr(data, "columns", None)) if isinstance(model, str) else model
    if not isinstance(model, RCModel):
        raise TypeError(
            f"model must be an RCModel or a library model name, got {type(model).__name__}"
        )
    names = model.param_names
    fixed = check_mapping(fixed, "fixed", "{'R_wal': 0.01}")
    bounds = check_mapping(bounds, "bounds", "{'R_wal': (1e-4, 1.0)}")
    user_guess = check_mapping(guess, "guess", "{'C_zon': 1e6}")
    for label, d in (("fixed", fixed), ("bounds", bounds), ("guess", user_guess)):
        bad = [k for k in d if k not in names]
        if bad:
            raise FitError(
                f"{label}: model {model.name} has no parameter(s) {', '.join(bad)}; its "
                f"parameters are {', '.join(names)}"
            )
    if free is None:
        free = [n for n in names if n not in fixed]
    else:
        free = _names(free, "free")
        bad = [k for k in free if k not in names]
        if bad:
            raise FitError(
                f"free: model {model.name} has no parameter(s) {', '.join(bad)}; its parameters "
                f"are {', '.join(names)}"
            )
        clash = [k for k in free if k in fixed]
        if clash:
            raise FitError(f"parameter(s) {', '.join(clash)} are both free and fixed")
    free = tuple(n for n in names if n in set(free))
    if not free:
        raise FitError(f"nothing to estimate: every parameter of {model.name} is fixed")
    full_guess = initial_guess(model, data)
    full_guess.update({k: number(v, f"guess of {k}") for k, v in user_guess.items()})
    # parameters neither free nor explicitly fixed are held at their guess
    for n in names:
        if n not in free and n not in fixed:
            fixed[n] = full_guess[n]
    fixed = {n: number(fixed[n], f"fixed value of {n}") for n in names if n in fixed}
    for n, v in fixed.items():
        if not np.isfinite(v):
            raise FitError(f"fixed value of {n} is {v}; give a finite number")
        if _positive(n) and not v > 0:
            raise FitError(f"fixed value of {n} is {v:g}; resistances and capacities must be > 0")
        spec = model.parameter(n)
        if _physical(spec, min(v, spec.lower), max(v, spec.upper)) is not True:
            raise FitError(
                f"fixed value of {n} is {v:g}; a fraction fra_* lies within [0, 1] (fra_ele, a "
                "share of the electricity use, within [0, ∞))"
            )
    lo, hi, g = [], [], []
    for n in free:
        spec = model.parameter(n)
        b = bounds.get(n, (spec.lower, spec.upper))
        if isinstance(b, str | bytes | Mapping) or not isinstance(b, Sequence | np.ndarray):
            raise FitError(f"bounds of {n} must be a pair (lower, upper), got {b!r}")
        if len(b) != 2:
            raise FitError(f"bounds of {n} must be a pair (lower, upper), got {len(b)} values")
        blo, bhi = (number(b[0], f"lower bound of {n}"), number(b[1], f"upper bound of {n}"))
        if not blo < bhi:
            raise FitError(f"bounds of {n}: lower {blo:g} must be below upper {bhi:g}")
        why = _physical(spec, blo, bhi)  # resistances and capacities > 0, fractions in [0, 1]
        if why is not True:
            raise FitError(f"bounds of {n}: {why}")
        gn = full_guess[n]
        if not np.isfinite(gn):
            raise FitError(f"guess of {n} is {gn}; give a finite number")
        gn = full_guess[n] = guess_within(n, gn, blo, bhi, n in user_guess)
        lo.append(blo)
        hi.append(bhi)
        g.append(gn)
    try:
        transform = make_transform(free, lo, hi, g)
    except ValueError as err:
        raise FitError(str(err)) from None
    outs = model.outputs
    if weights is None:
        w = [1.0] * len(outs)
    elif isinstance(weights, Mapping):
        bad = [k for k in weights if k not in outs]
        if bad:
            raise FitError(
                f"weights given for {', '.join(bad)}, which are not outputs of {model.name} "
                f"(outputs: {', '.join(outs)})"
            )
        w = [number(weights.get(o, 1.0), f"weight of {o}") for o in outs]
    elif isinstance(weights, str | bytes) or not isinstance(weights, Sequence | np.ndarray):
        raise FitError(
            f"weights must map outputs to numbers ({{'T_zon': 1.0}}) or hold one number per "
            f"output {', '.join(outs)}; got {weights!r}"
        )
    else:
        w = [number(x, "weight") for x in np.asarray(weights, dtype=object).ravel()]
        if len(w) != len(outs):
            raise FitError(f"{len(w)} weights for {len(outs)} outputs {', '.join(outs)}")
    if any((not np.isfinite(x)) or x < 0 for x in w) or sum(w) == 0:
        raise FitError(f"output weights must be finite, ≥ 0 and not all zero, got {w}")
    if simulator not in ("exact", "diffrax"):
        raise FitError(f"unknown simulator {simulator!r}; choose 'exact' or 'diffrax'")
    if simulator != "exact" and model.segments > 1:
        raise FitError(
            f"the data hold {model.segments} segments (gaps or separate periods), which only the "
            "exact simulator fits; use simulator='exact'"
        )
    return Problem(
        model=model,
        free=free,
        fixed=tuple(fixed.items()),
        guess=tuple((n, float(full_guess[n])) for n in names),
        transform=transform,
        weights=tuple(w),
        simulator=simulator,
        sim_options=tuple(sorted((sim_options or {}).items())),
    )


def problem_arrays(problem: Problem, data):
    """(t, u, y, sqrt_w) arrays of a dataset for a problem: the data side of the residuals.

    ``sqrt_w`` holds ``sqrt(q_j / N_j)`` with ``N_j`` the number of measured samples of output
    ``j``: shape [p] when every output sample is measured, [N, p] with 0 at the samples of an
    output gap (NaN in ``data``, replaced by 0 in ``y``), which the cost then ignores. The
    inputs must be complete (see :func:`jaxbox.data.prepare_window`).
    """
    model = problem.model
    what = f"model {model.name}"
    data.require(list(model.inputs) + list(model.outputs), what=what)
    t = np.asarray(data.t, dtype=float)
    u = data.array(list(model.inputs))
    y = data.array(list(model.outputs))
    n = len(t)
    if n < 3:
        raise FitError(f"the identification data has {n} samples; at least 3 are needed")
    holes = ~np.isfinite(u)
    if holes.any():
        j = int(np.flatnonzero(holes.any(axis=0))[0])
        times = data.index[holes[:, j]]
        raise FitError(
            f"input {model.inputs[j]!r} is missing in {int(holes[:, j].sum())} sample(s) between "
            f"{times[0]} and {times[-1]}; inputs cannot be masked: fill or cut the gaps with "
            "jaxbox.data.prepare_window (fit_model does it, see max_gap)"
        )
    mask = np.isfinite(y)
    counts = mask.sum(axis=0)
    if np.any(counts < 3):
        j = int(np.flatnonzero(counts < 3)[0])
        raise FitError(
            f"output {model.outputs[j]!r} is measured in {int(counts[j])} sample(s) of the "
            "identification data; at least 3 are needed"
        )
    if segments := len(data.segments) if model.segments > 1 else 0:
        if segments > model.segments:
            raise FitError(
                f"the data hold {segments} segments but model {model.name} has initial states "
                f"for {model.segments}; use model.segmented({segments})"
            )
    q = np.asarray(problem.weights, dtype=float)
    if mask.all():
        return t, u, y, np.sqrt(q / n)
    sqrt_w = np.where(mask, np.sqrt(q / np.maximum(counts, 1)), 0.0)
    return t, u, np.where(mask, y, 0.0), sqrt_w
