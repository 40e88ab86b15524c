"""Prior parameter values for a design: from an earlier fit's JSON, a mapping, or the defaults;
and prior samples for a robust design."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from ..models import ModelError, RCModel, get_model

__all__ = ["Prior", "load_prior", "prior_samples"]


class Prior:
    """Model, prior parameter values [SI], the estimated parameters and, from a fit, the
    covariance of the model parameters in log coordinates.

    Attributes:
        model: the RC model.
        theta: every parameter's prior value [SI].
        free: the parameters the planned experiment will estimate (initial states included).
        log_cov: covariance of ``log θ`` of the ratio-scale free parameters (from the standard
            deviations and correlations of a fit JSON), or None.
        log_names: the parameters of ``log_cov``.
        source: where the values came from.
    """

    def __init__(self, model, theta, free, log_cov=None, log_names=(), source="defaults"):
        self.model = model
        self.theta = dict(theta)
        self.free = tuple(free)
        self.log_cov = log_cov
        self.log_names = tuple(log_names)
        self.source = source


def _from_json(path: Path, model: RCModel | None) -> Prior:
    try:
        doc = json.loads(Path(path).read_text())
    except json.JSONDecodeError as err:
        raise ModelError(
            f"{path}: not a JSON document ({err.msg}); give the output of `jaxbox fit --json`"
        ) from None
    except UnicodeDecodeError:
        raise ModelError(
            f"{path}: not a text file; give the output of `jaxbox fit --json`"
        ) from None
    if not isinstance(doc, dict) or "params" not in doc or "model" not in doc:
        raise ModelError(f"{path}: no 'model' and 'params'; give the output of `jaxbox fit --json`")
    fitted = get_model(doc["model"])
    if model is not None and model.name != fitted.name:
        raise ModelError(f"{path} holds a fit of {fitted.name}, not of {model.name}")
    model = model or fitted
    params = doc["params"]
    if not isinstance(params, dict):
        raise ModelError(
            f"{path}: 'params' is not an object; give the output of `jaxbox fit --json`"
        )
    missing = [
        n
        for n in model.param_names
        if not isinstance(params.get(n), dict) or "value" not in params[n]
    ]
    if missing:
        raise ModelError(f"{path}: no value for parameter(s) {', '.join(missing)}")
    theta = {n: _value(params[n]["value"], n, f"{path}: ") for n in model.param_names}
    free = doc.get("free", model.param_names)
    if not isinstance(free, list):
        raise ModelError(f"{path}: 'free' is not a list of parameter names")
    free = [n for n in free if n in theta]
    # covariance of log θ from the fit's standard deviations and correlations
    names = [
        n
        for n in free
        if n.startswith(("R_", "C_", "gA", "fra_"))
        and isinstance(params[n].get("std"), int | float)
        and theta[n] > 0
        and math.isfinite(params[n]["std"])
    ]
    log_cov = None
    if names:
        rel = np.asarray([params[n]["std"] / theta[n] for n in names])
        corr = np.eye(len(names))
        table = doc.get("correlation") or {}
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                v = (table.get(a) or {}).get(b)
                if i != j and isinstance(v, int | float) and math.isfinite(v):
                    corr[i, j] = v
        log_cov = corr * np.outer(rel, rel)
    return Prior(model, theta, free, log_cov, names, source=str(path))


def _value(v, name: str, where: str = "") -> float:
    """A prior value as a float, or a ModelError naming the parameter."""
    if isinstance(v, bool):
        v = None
    try:
        return float(v)
    except (TypeError, ValueError):
        raise ModelError(f"{where}prior value of {name} is {v!r}; give a number [SI]") from None


def _check_values(prior: Prior) -> None:
    """Every value finite, resistances and capacities > 0, and every free parameter whose
    design coordinate is ``log θ`` > 0."""
    from ._fisher import RATIO_PREFIXES

    for n, v in prior.theta.items():
        if not math.isfinite(v):
            raise ModelError(f"prior value of {n} is {v}; give a finite number")
        if n.startswith(("R_", "C_")) and not v > 0:
            raise ModelError(f"prior value of {n} is {v:g}; resistances and capacities are > 0")
        if n in prior.free and n.startswith(RATIO_PREFIXES) and not v > 0:
            raise ModelError(
                f"prior value of {n} is {v:g}; a free {n} is designed for in relative terms "
                f"(log {n}) and needs a value > 0; give one, or leave {n} out of the free "
                "parameters"
            )


def load_prior(model=None, params=None, free=None) -> Prior:
    """The prior of a design.

    Args:
        model: an :class:`~jaxbox.models.RCModel` or library name (optional with a fit JSON).
        params: ``None`` (the model's defaults), a mapping ``name -> value`` [SI] (the others
            from the defaults), or the path of a fit JSON written by ``jaxbox fit --json``
            (its estimates, free parameters, standard deviations and correlations).
        free: the parameters the experiment will estimate (default: the fit's free parameters,
            or every parameter).
    """
    model = None if model is None else get_model(model)
    if isinstance(params, str | Path):
        prior = _from_json(Path(params), model)
    elif params is not None and not isinstance(params, Mapping):
        raise TypeError(
            "params must be a mapping name -> value [SI], the path of a fit JSON, or None, got "
            f"{type(params).__name__}"
        )
    else:
        if model is None:
            raise ModelError("give a model (or the JSON of a fit, which names it)")
        theta = model.defaults()
        if params is not None:
            bad = [str(k) for k in params if k not in theta]
            if bad:
                raise ModelError(
                    f"model {model.name} has no parameter(s) {', '.join(bad)}; its parameters "
                    f"are {', '.join(model.param_names)}"
                )
            theta.update({k: _value(v, k) for k, v in params.items()})
        prior = Prior(model, theta, model.param_names, source="values" if params else "defaults")
    if free is not None:
        if isinstance(free, str) or not isinstance(free, Iterable):
            raise TypeError(
                f"free must be a list of parameter names, got {free!r}; e.g. free=['R_wal', "
                "'C_zon']"
            )
        free = tuple(free)
        bad = [str(n) for n in free if n not in prior.theta]
        if bad:
            raise ModelError(
                f"model {prior.model.name} has no parameter(s) {', '.join(bad)}; its parameters "
                f"are {', '.join(prior.model.param_names)}"
            )
        prior.free = free
    _check_values(prior)
    return prior


def prior_samples(prior: Prior, names, n: int, spread: float | None, seed: int = 0) -> np.ndarray:
    """``n`` samples of ``log θ`` of ``names`` [n, len(names)]; the first is the prior value.

    ``spread``: standard deviation of ``log θ`` of every parameter (a log-normal prior, e.g.
    0.3 for about ±30 %), or ``None`` for the fit's covariance (which must be known).
    """
    bad = [str(k) for k in names if k not in prior.theta]
    if bad:
        raise ModelError(
            f"model {prior.model.name} has no parameter(s) {', '.join(bad)}; its parameters are "
            f"{', '.join(prior.model.param_names)}"
        )
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ModelError(f"prior_samples needs n, an integer ≥ 1 (samples), got {n!r}")
    mean = np.log([prior.theta[k] for k in names])
    if n <= 1:
        return mean[None, :]
    if spread is None:
        if prior.log_cov is None:
            raise ModelError(
                "a robust design from the fit's covariance needs the JSON of a fit with "
                "standard deviations; give a spread (e.g. 0.3) instead"
            )
        cov = np.zeros((len(names), len(names)))
        idx = {k: i for i, k in enumerate(prior.log_names)}
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                if a in idx and b in idx:
                    cov[i, j] = prior.log_cov[idx[a], idx[b]]
    else:
        if isinstance(spread, bool) or not isinstance(spread, int | float | np.number):
            raise TypeError(f"spread must be a number ≥ 0 (std of log θ), got {spread!r}")
        if not (math.isfinite(spread) and spread >= 0):
            raise ModelError(f"spread must be a finite number ≥ 0, got {spread}")
        cov = np.eye(len(names)) * spread**2
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ModelError(f"seed must be an integer ≥ 0, got {seed!r}")
    rng = np.random.default_rng(seed)
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    L = V * np.sqrt(np.clip(w, 0.0, None))
    draws = mean + rng.standard_normal((n - 1, len(names))) @ L.T
    return np.concatenate([mean[None, :], draws], axis=0)
