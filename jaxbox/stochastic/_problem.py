"""The maximum-likelihood problem: physical and noise parameters, bounds, priors, likelihood.

The physical side (free/fixed split, bounds, data-derived guesses) is the output-error problem of
:func:`jaxbox.fit.make_problem`; the noise parameters (:mod:`jaxbox.stochastic._noise`) are added
with their own bounds and guesses, and every free parameter shares one bound transform
(:func:`jaxbox.fit.make_transform`), so the Latin-hypercube starts of
:func:`jaxbox.fit.sample_starts` apply unchanged.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from ..data import check_mapping
from ..fit._problem import FitError, Problem, guess_within, make_problem
from ..fit._transforms import Transform, make_transform
from ..models import RCModel
from ._checks import as_data, number, regular_step, x0_stds
from ._kalman import HOLDS, discretize, kalman_scan
from ._noise import diffusion_names, measurement_names, noise_parameters

__all__ = ["StochasticProblem", "make_stochastic_problem", "stochastic_arrays", "DEFAULT_X0_STD"]

#: default standard deviation [K] of every initial state around its mean ``T_*0``
DEFAULT_X0_STD = 1.0


@dataclasses.dataclass(frozen=True, eq=False)
class StochasticProblem:
    """Everything static about a maximum-likelihood problem (no data arrays).

    Attributes:
        base: the output-error problem of the physical parameters (model, guesses, bounds).
        free: estimated parameters: the physical ones (model order), then the noise ones.
        fixed: fixed values (SI) of every other parameter, physical and noise.
        guess: guess of every parameter (SI).
        transform: bound transform of the free parameters.
        hold: ``"foh"`` (inputs linear between samples) or ``"zoh"`` (constant).
        x0_std: standard deviation [K] of each initial state (the initial covariance is
            ``diag(x0_std²)``).
        priors: ``(name, mean, sd)`` Gaussian priors on free parameters (SI), for MAP.
    """

    base: Problem
    free: tuple[str, ...]
    fixed: tuple[tuple[str, float], ...]
    guess: tuple[tuple[str, float], ...]
    transform: Transform
    hold: str
    x0_std: tuple[float, ...]
    priors: tuple[tuple[str, float, float], ...] = ()

    @property
    def model(self) -> RCModel:
        return self.base.model

    @property
    def param_names(self) -> tuple[str, ...]:
        """Every parameter of the stochastic model: physical ones, then noise ones."""
        return self.model.param_names + tuple(p.name for p in noise_parameters(self.model))

    @property
    def fixed_dict(self) -> dict[str, float]:
        return dict(self.fixed)

    @property
    def guess_dict(self) -> dict[str, float]:
        return dict(self.guess)

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        tr = self.transform
        return {
            n: (float(lo), float(hi))
            for n, lo, hi in zip(tr.names, tr.lower, tr.upper, strict=True)
        }

    def spec(self, name: str):
        """The :class:`~jaxbox.models.Parameter` spec of any parameter, physical or noise."""
        for p in noise_parameters(self.model):
            if p.name == name:
                return p
        return self.model.parameter(name)

    @property
    def structure_key(self) -> tuple:
        """What the compiled likelihood depends on besides array shapes."""
        return (
            self.model.structure,
            self.free,
            tuple(n for n, _ in self.fixed),
            self.transform.kinds,
            self.transform.style,
            self.hold,
        )

    def full_transform(self) -> tuple[Transform, np.ndarray, np.ndarray]:
        """The bound transform over *every* parameter (``param_names`` order), the mask of the
        free ones and the values of the fixed ones.

        Free parameters keep their transform; a fixed one gets the transform of its spec's
        bounds (what it would have if it were free with default bounds), so that the compiled
        solve depends on the model structure and the transform kinds only, not on which
        parameters are fixed: a fit with a diffusion fixed reuses the compiled solve of the fit
        that estimates it.
        """
        tr, names = self.transform, self.param_names
        fixed = self.fixed_dict
        kinds, lo, hi, sc = [], [], [], []
        for n in names:
            if n in self.free:
                i = self.free.index(n)
                kinds.append(tr.kinds[i])
                lo.append(tr.lower[i])
                hi.append(tr.upper[i])
                sc.append(tr.scale[i])
            else:
                spec = self.spec(n)
                g = float(np.clip(spec.default, spec.lower, spec.upper))
                one = make_transform([n], [spec.lower], [spec.upper], [g])
                kinds.append(one.kinds[0])
                lo.append(spec.lower)
                hi.append(spec.upper)
                sc.append(one.scale[0])
        full = Transform(
            tuple(names), tuple(kinds), np.asarray(lo), np.asarray(hi), np.asarray(sc), tr.style
        )
        mask = np.asarray([n in self.free for n in names])
        values = np.asarray([fixed.get(n, 0.0) for n in names], dtype=float)
        return full, mask, values

    def prior_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Prior mean and sd per free parameter (sd = inf: no prior)."""
        mean = np.zeros(len(self.free))
        sd = np.full(len(self.free), np.inf)
        for name, mu, s in self.priors:
            i = self.free.index(name)
            mean[i], sd[i] = mu, s
        return mean, sd

    def theta(self, p_free, fixed_values) -> dict:
        """θ dict (physical and noise) from free values and fixed values (``fixed`` order)."""
        theta = {n: p_free[..., i] for i, n in enumerate(self.free)}
        theta.update({n: fixed_values[i] for i, (n, _) in enumerate(self.fixed)})
        return theta

    def system(self, theta, dt):
        """``(mats, C, D, r, m0, P0)`` of the discrete stochastic model for step ``dt`` [s]."""
        return system(self.model, theta, dt, self.hold, self.x0_std)

    def nll_theta(self, theta, dt, u, y, full: bool = False):
        """Negative log-likelihood of one series (or the filter's outputs with ``full``)."""
        mats, C, D, r, m0, P0 = self.system(theta, dt)
        return kalman_scan(mats, C, D, r, m0, P0, u, y, full=full)

    def log_prior(self, p, pm, ps):
        """Negative log prior density up to a constant: ``½ Σ ((p − μ)/s)²`` over priors."""
        return neg_log_prior(p, pm, ps)

    def objective_physical(self, p, fixed_values, pm, ps, dt, u, y):
        """NLL plus the negative log prior at physical free values ``p``."""
        theta = self.theta(p, fixed_values)
        return self.nll_theta(theta, dt, u, y) + self.log_prior(p, pm, ps)


def neg_log_prior(p, pm, ps):
    """Negative log density of Gaussian priors up to a constant, ``½ Σ ((p − μ)/s)²``, over the
    entries with a finite standard deviation ``s`` (``inf``: no prior); traceable."""
    has = jnp.isfinite(ps)
    d = jnp.where(has, (p - pm) / jnp.where(has, ps, 1.0), 0.0)
    return 0.5 * jnp.sum(d * d)


def system(model: RCModel, theta, dt, hold: str = "foh", x0_std=None):
    """``(mats, C, D, r, m0, P0)``: the discrete stochastic model for parameters θ (physical and
    noise, SI) and step ``dt`` [s]: ``mats = (Φ, Γ0, Γ1, Q)``, output matrices, measurement
    noise standard deviations ``r`` [K], initial mean ``m0`` [°C] and covariance ``P0`` [K²]."""
    A, B, caps, held = model.rc_form(theta)
    sig = jnp.stack(
        [jnp.asarray(0.0 if n is None else theta[n], dtype=float) for n in diffusion_names(model)]
    )
    mats = discretize(A, B, caps, held, sig, dt, hold)
    _, _, C, D = model.state_space(theta)
    r = jnp.stack([jnp.asarray(theta[n], dtype=float) for n in measurement_names(model)])
    m0 = model.initial_state(theta)
    x0 = (DEFAULT_X0_STD,) * model.n_states if x0_std is None else x0_std
    P0 = jnp.diag(jnp.asarray(x0, dtype=float) ** 2)
    return mats, C, D, r, m0, P0


def _split(d: Mapping | None, noise: set, what: str, names: Sequence[str], model) -> tuple:
    """``(physical, noise)``: the entries of the mapping ``d`` (the argument ``what``) split
    by kind, every name checked against the parameters ``names`` of the stochastic form."""
    d = check_mapping(d, what, _EXAMPLES[what])
    bad = [k for k in d if k not in names]
    if bad:
        raise FitError(
            f"{what}: the stochastic form of {model.name} has no parameter(s) {', '.join(bad)}; "
            f"its parameters are {', '.join(names)}"
        )
    return {k: v for k, v in d.items() if k not in noise}, {
        k: v for k, v in d.items() if k in noise
    }


#: an example of each mapping argument, for the message of a misuse
_EXAMPLES = {
    "fixed": "{'sigma_zon': 0.0}",
    "bounds": "{'sigma_zon': (1e-6, 1e-2)}",
    "guess": "{'sigma_y_zon': 0.1}",
    "priors": "{'gA': (2.0, 0.5)}",
}


def _numbers(d: dict, what: str) -> dict:
    """The values of ``fixed`` or ``guess`` as floats (NaN kept for the range checks); a value
    that is not a number is named: ``fixed value of sigma_zon must be a number, got 'abc'``."""
    return {n: number(v, f"{what} of {n}") for n, v in d.items()}


def _pairs(d: dict, what: str) -> dict:
    """The values of ``bounds`` or ``priors``: each a pair of numbers (a third entry, a string
    or a scalar is named, not cut to its first two items or left to float())."""
    out = {}
    for n, v in d.items():
        shape = "(lower, upper)" if what == "bounds" else "(mean, sd) in SI"
        if isinstance(v, str | bytes | Mapping) or not hasattr(v, "__len__") or len(v) != 2:
            raise FitError(f"{what} of {n} must be a pair {shape}, got {v!r}")
        out[n] = tuple(number(x, f"{what} of {n}") for x in v)
    return out


def _free_names(free) -> list | None:
    """``free`` as a list of names: one name given as a string is that name (not its
    letters); anything but a string or a sequence of strings is a ``TypeError``."""
    if free is None or isinstance(free, str):
        return None if free is None else [free]
    if isinstance(free, Mapping) or not isinstance(free, Sequence | set | frozenset):
        raise TypeError(f"free must be a list of parameter names, got {free!r}")
    return list(free)


def make_stochastic_problem(
    model: RCModel,
    data,
    *,
    free: Sequence[str] | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    guess: Mapping[str, float] | None = None,
    priors: Mapping[str, tuple[float, float]] | None = None,
    hold: str = "foh",
    x0_std: float | Mapping[str, float] | None = None,
) -> StochasticProblem:
    """Check and assemble a maximum-likelihood problem. Every misuse raises ``FitError``.

    Args are those of :func:`jaxbox.stochastic.fit_ml`.
    """
    data = as_data(data)
    specs = {p.name: p for p in noise_parameters(model)}
    noise = set(specs)
    names = model.param_names + tuple(specs)
    split = {
        what: _split(arg, noise, what, names, model)
        for what, arg in (("fixed", fixed), ("bounds", bounds), ("guess", guess))
    }
    fixed_p, fixed_n = (_numbers(d, "fixed value") for d in split["fixed"])
    bounds_p, bounds_n = (_pairs(d, "bounds") for d in split["bounds"])
    guess_p, guess_n = (_numbers(d, "guess") for d in split["guess"])
    _split(priors, noise, "priors", names, model)
    priors = _pairs(check_mapping(priors, "priors"), "priors")
    free = _free_names(free)
    free_p = None
    free_n = [n for n in specs if n not in fixed_n]
    if free is not None:
        bad = [k for k in free if k not in names]
        if bad:
            raise FitError(
                f"free: the stochastic form of {model.name} has no parameter(s) "
                f"{', '.join(bad)}; its parameters are {', '.join(names)}"
            )
        free_p = [k for k in free if k not in noise]
        free_n = [k for k in specs if k in set(free)]
        clash = [k for k in free if k in fixed_n]
        if clash:
            raise FitError(f"parameter(s) {', '.join(clash)} are both free and fixed")
        for k in specs:  # noise parameters neither free nor fixed are held at their guess
            if k not in free_n and k not in fixed_n:
                fixed_n[k] = float(guess_n.get(k, specs[k].default))
    if (
        free_p is not None
        and not free_p
        or (free_p is None and all(n in fixed_p for n in model.param_names))
    ):
        raise FitError(
            f"no physical parameter of {model.name} is free; maximum likelihood estimates "
            "physical and noise parameters together (free at least one physical parameter)"
        )
    if hold not in HOLDS:
        raise FitError(f"unknown hold {hold!r}; choose one of {', '.join(HOLDS)}")
    base = make_problem(model, data, free=free_p, fixed=fixed_p, bounds=bounds_p, guess=guess_p)
    # noise parameters: fixed values, bounds and guesses checked
    for n, v in fixed_n.items():
        v = float(v)
        if not np.isfinite(v) or v < 0:
            raise FitError(f"fixed value of {n} is {v:g}; noise parameters must be finite and ≥ 0")
        if n.startswith("sigma_y_") and not v > 0:
            raise FitError(
                f"fixed value of {n} is {v:g}; a measurement noise must be > 0 (else the "
                "likelihood is singular)"
            )
        fixed_n[n] = v
    lo, hi, g = [], [], []
    for n in free_n:
        spec = specs[n]
        b = bounds_n.get(n, (spec.lower, spec.upper))
        try:
            blo, bhi = float(b[0]), float(b[1])
        except (TypeError, ValueError, IndexError):
            raise FitError(f"bounds of {n} must be a pair (lower, upper), got {b!r}") from None
        if not 0 < blo < bhi:
            raise FitError(
                f"bounds of {n}: need 0 < lower < upper, got ({blo:g}, {bhi:g}); fix a "
                "diffusion to 0 with fixed= instead of a zero lower bound"
            )
        gn = float(guess_n.get(n, spec.default))
        if not np.isfinite(gn):
            raise FitError(f"guess of {n} is {gn}; give a finite number")
        gn = guess_within(n, gn, blo, bhi, n in guess_n)
        lo.append(blo)
        hi.append(bhi)
        g.append(gn)
    tr = base.transform
    free_all = base.free + tuple(free_n)
    transform = make_transform(
        free_all,
        np.concatenate([tr.lower, lo]),
        np.concatenate([tr.upper, hi]),
        np.concatenate([[base.guess_dict[n] for n in base.free], g]),
    )
    fixed_all = tuple(base.fixed) + tuple((n, fixed_n[n]) for n in specs if n in fixed_n)
    guess_all = tuple(base.guess) + tuple(
        (n, float(fixed_n[n]) if n in fixed_n else g[free_n.index(n)]) for n in specs
    )
    # initial covariance
    x0 = x0_stds(model, x0_std, DEFAULT_X0_STD)
    pri = []
    for n, ms in (priors or {}).items():
        if n not in free_all:
            raise FitError(f"prior given for {n}, which is not estimated")
        try:
            mu, s = float(ms[0]), float(ms[1])
        except (TypeError, ValueError, IndexError):
            raise FitError(f"prior of {n} must be a pair (mean, sd) in SI, got {ms!r}") from None
        if not (np.isfinite(mu) and np.isfinite(s) and s > 0):
            raise FitError(f"prior of {n}: need a finite mean and an sd > 0, got ({mu}, {s})")
        pri.append((n, mu, s))
    return StochasticProblem(
        base=base,
        free=free_all,
        fixed=fixed_all,
        guess=guess_all,
        transform=transform,
        hold=hold,
        x0_std=x0,
        priors=tuple(pri),
    )


def stochastic_arrays(model: RCModel, data) -> tuple[float, np.ndarray, np.ndarray]:
    """``(dt [s], u [N, m], y [N, p])`` of a dataset for a model; y may hold NaN (missing).
    The data must be sampled at one regular step (:func:`~._checks.regular_step`)."""
    data = as_data(data)
    data.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
    u = np.asarray(data.array(list(model.inputs)), dtype=float)
    y = np.asarray(data.array(list(model.outputs)), dtype=float)
    if len(u) < 3:
        raise FitError(f"the data has {len(u)} samples; at least 3 are needed")
    bad = ~np.isfinite(u)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise FitError(
            f"input {model.inputs[col]} is missing (NaN) at {data.index[row]} (row {row}); the "
            "Kalman filter needs every input (outputs may be missing): interpolate short gaps "
            "(jaxbox.data.prepare_window, command line --max-gap) or use the data on one side "
            "of a long one"
        )
    if not np.isfinite(y).any():
        raise FitError("every output value is missing (NaN); nothing to estimate from")
    return regular_step(data), u, y
