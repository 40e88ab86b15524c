"""The simulation entry point: a model, its parameters and input data → outputs and states."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import require_x64
from ..models import ModelError, RCModel
from ._diffrax import diffrax_runs_numpy, simulate_diffrax
from ._exact import discretize_foh, exact_runs_numpy, simulate_exact, simulate_foh_segments
from ._parallel import simulate_parallel

__all__ = ["Simulation", "simulate_model", "simulate_arrays", "check_theta", "METHODS"]

METHODS = ("exact", "diffrax", "parallel")
"""Simulators: exact discretisation (sequential scan), diffrax, exact parallel in time."""


class Simulation(NamedTuple):
    """Simulated trajectories at the sample instants.

    Attributes:
        t: sample times [s] since the first sample, shape [N].
        y: outputs [°C], shape [N, p], columns in ``model.outputs`` order.
        x: states [°C], shape [N, n], columns in ``model.states`` order.
    """

    t: np.ndarray
    y: np.ndarray
    x: np.ndarray


def check_theta(model: RCModel, theta: Mapping | None) -> dict:
    """Complete θ from the model's defaults when None; reject unknown or missing names."""
    if theta is None:
        return model.defaults()
    if not (isinstance(theta, Mapping) or callable(getattr(theta, "items", None))):
        raise TypeError(
            f"parameters of model {model.name} must be a mapping name -> value (SI units), got "
            f"{type(theta).__name__}; model.defaults() holds default values"
        )
    theta = dict(theta.items())
    unknown = [k for k in theta if k not in model.param_names]
    missing = [k for k in model.param_names if k not in theta]
    if unknown:
        raise ModelError(
            f"model {model.name} has no parameter(s) {', '.join(unknown)}; its parameters are "
            f"{', '.join(model.param_names)}"
        )
    if missing:
        raise ModelError(
            f"model {model.name}: no value for parameter(s) {', '.join(missing)}; give every "
            "parameter (model.defaults() holds default values)"
        )
    net = model.network
    splits = {v for e in net.edges for _, v in e.factors}  # shares of a resistance
    shares = {v for src in net.sources for k, v in src.gain if k == "compl"}  # of a heat input
    for name, value in list(theta.items()):
        v = _scalar(model, name, value)
        if v is None:
            continue  # traced (under jit or grad): checked where it is used
        theta[name] = v
        if not np.isfinite(v):
            raise ModelError(f"model {model.name}: parameter {name} is {v}; give a finite value")
        if name.startswith(("R_", "C_")) and not v > 0:
            kind = "resistance [K/W]" if name.startswith("R_") else "capacity [J/K]"
            raise ModelError(
                f"model {model.name}: parameter {name} = {v:g} is not positive; a {kind} must "
                "be greater than zero"
            )
        if model.parameter(name).is_initial_state and v > KELVIN_ABOVE:
            raise ModelError(
                f"model {model.name}: initial temperature {name} = {v:g} looks like kelvin; "
                "give it in °C (subtract 273.15)"
            )
        if name in splits and not 0.0 < v < 1.0:
            raise ModelError(
                f"model {model.name}: fraction {name} = {v:g} must lie strictly between 0 and 1; "
                "it splits a resistance in two, and a share of 0, 1 or outside leaves one part "
                "zero or negative"
            )
        if name in shares and not 0.0 <= v <= 1.0:
            raise ModelError(
                f"model {model.name}: fraction {name} = {v:g} lies outside [0, 1]; it splits a "
                "heat input in two, and a share outside [0, 1] makes one part negative"
            )
    return theta


#: an initial temperature [°C] above this is taken for kelvin (as the data's columns)
KELVIN_ABOVE = 150.0


def _scalar(model: RCModel, name: str, value) -> float | None:
    """The float value of parameter ``name``, or None while traced; TypeError for text, None,
    booleans or complex numbers, ModelError for an array of more than one value."""
    if isinstance(value, jax.core.Tracer):
        return None
    if value is None or isinstance(value, str | bytes | bool | complex | np.bool_):
        raise TypeError(
            f"model {model.name}: parameter {name} is {value!r}; give a number in "
            f"{model.parameter(name).unit}"
        )
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        array = None
    if array is None or not (
        np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)
    ):
        raise TypeError(
            f"model {model.name}: parameter {name} is {value!r}; give a number in "
            f"{model.parameter(name).unit}"
        )
    if array.size != 1:
        raise ModelError(
            f"model {model.name}: parameter {name} has shape {array.shape}; give one number "
            "(simulate several parameter sets with jax.vmap over simulate_arrays)"
        )
    return float(array.reshape(()))


def simulate_arrays(
    model: RCModel,
    theta: Mapping,
    t,
    u,
    *,
    method: str = "exact",
    x0=None,
    **options,
):
    """Pure-JAX simulation (jit/vmap/grad friendly): returns (y [N, p], x [N, n]).

    Args:
        model: the RC model.
        theta: parameter values (SI), every model parameter.
        t: sample times [s], regular for ``method="exact"``.
        u: inputs [N, m] in ``model.inputs`` order.
        method: ``"exact"`` (first-order-hold matrix exponential, sequential scan),
            ``"parallel"`` (the same, parallel in time: an associative scan; on a GPU faster
            than the sequential scan at every length, on a CPU slower) or ``"diffrax"``.
        x0: initial state [°C]; default from the ``T_*0`` parameters.
        options: passed to :func:`~jaxbox.simulate._diffrax.simulate_diffrax`.

    A model for data in segments (:meth:`RCModel.segmented`) restarts each segment from its own
    initial states; the segments are read from ``t`` (a time step longer than the first starts
    a new one). ``method="exact"`` handles them in one scan; ``"diffrax"`` needs concrete
    ``t`` (not traced) and simulates the segments one by one.
    """
    _check_arrays(model, t, u, x0, method)
    A, B, C, D = model.state_space(theta)
    if model.segments > 1 and x0 is None:
        X0 = model.initial_states(theta)
        u = jnp.asarray(u, dtype=float)
        if method == "exact":
            Phi, G0, G1 = discretize_foh(A, B, t[1] - t[0])
            return simulate_foh_segments(Phi, G0, G1, C, D, X0, u, jnp.asarray(t, dtype=float))
        try:
            times = np.asarray(t, dtype=float)
        except jax.errors.TracerArrayConversionError:
            raise ValueError(
                f"method {method!r} simulates data in segments one by one and needs concrete "
                "times; use method='exact', or call it outside jit"
            ) from None
        parts = _segments(times)
        if len(parts) > model.segments:
            raise ModelError(
                f"the data hold {len(parts)} segments but model {model.name} has initial states "
                f"for {model.segments}"
            )
        ys, xs = [], []
        for k, (a, b) in enumerate(parts):
            y, x = simulate_arrays(
                model, theta, times[a:b] - times[a], u[a:b], method=method, x0=X0[k], **options
            )
            ys.append(y)
            xs.append(x)
        return jnp.concatenate(ys), jnp.concatenate(xs)
    x0 = model.initial_state(theta) if x0 is None else jnp.asarray(x0, dtype=float)
    t = jnp.asarray(t, dtype=float)
    u = jnp.asarray(u, dtype=float)
    if method == "exact":
        return simulate_exact(A, B, C, D, x0, u, t[1] - t[0])
    if method == "parallel":
        return simulate_parallel(A, B, C, D, x0, u, t[1] - t[0])
    if method == "diffrax":
        return simulate_diffrax(A, B, C, D, x0, t, u, **options)
    raise ValueError(f"unknown simulation method {method!r}; choose one of {METHODS}")


def _concrete(x) -> np.ndarray | None:
    """``x`` as a numpy array, or None while it is traced."""
    if isinstance(x, jax.core.Tracer):
        return None
    return np.asarray(x, dtype=float)


def _check_arrays(model: RCModel, t, u, x0, method: str) -> None:
    """Shapes of ``t`` [N], ``u`` [N, m] and ``x0`` [n] (also when traced); with concrete
    values, at least two samples, times increasing (at a regular step for the exact routes of a
    model in one segment) and finite inputs."""
    m, n = len(model.inputs), model.n_states
    t_shape, u_shape = np.shape(t), np.shape(u)
    if len(t_shape) != 1:
        raise ModelError(f"t must be a 1-D array of sample times [s], got shape {t_shape}")
    if u_shape != (t_shape[0], m):
        raise ModelError(
            f"u has shape {u_shape} but model {model.name} needs ({t_shape[0]}, {m}): one row per "
            f"sample time, one column per input ({', '.join(model.inputs)})"
        )
    if x0 is not None and np.shape(x0) != (n,):
        raise ModelError(
            f"x0 has shape {np.shape(x0)} but model {model.name} has {n} states "
            f"({', '.join(model.states)})"
        )
    if t_shape[0] < 2:
        raise ModelError(f"simulation of {model.name} needs at least two samples, got {t_shape[0]}")
    times = _concrete(t)
    if times is not None:
        steps = np.diff(times)
        if not (np.all(np.isfinite(times)) and np.all(steps > 0)):
            i = int(np.flatnonzero(~(steps > 0))[0]) if np.any(~(steps > 0)) else 0
            raise ModelError(
                f"sample times must be finite and increasing; t[{i}] = {times[i]:g} s, "
                f"t[{i + 1}] = {times[i + 1]:g} s"
            )
        if method in ("exact", "parallel") and model.segments == 1:
            off = np.flatnonzero(np.abs(steps - steps[0]) > 1e-6 * steps[0] + 1e-6)
            if off.size:
                i = int(off[0])
                raise ModelError(
                    f"method={method!r} needs a regular time step: t[1] - t[0] = {steps[0]:g} s "
                    f"but t[{i + 1}] - t[{i}] = {steps[i]:g} s; resample the data, or simulate "
                    "data in segments with model.segmented(k)"
                )
    values = _concrete(u)
    if values is not None and not np.all(np.isfinite(values)):
        j = int(np.flatnonzero(~np.isfinite(values).all(axis=0))[0])
        i = int(np.flatnonzero(~np.isfinite(values[:, j]))[0])
        raise ModelError(
            f"input {model.inputs[j]!r} of model {model.name} is {values[i, j]} at sample {i}; "
            "the simulation needs every input at every sample"
        )


def _segments(t: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), …]`` of the segments of sample times ``t`` (see ``segment_index``)."""
    dt = t[1] - t[0]
    cuts = np.flatnonzero(np.diff(t) > dt * (1 + 1e-6) + 1e-6) + 1
    edges = [0, *cuts.tolist(), len(t)]
    return [(edges[i], edges[i + 1]) for i in range(len(edges) - 1)]


@functools.partial(jax.jit, static_argnames=("model", "method", "options"))
def _simulate_jit(model, theta, t, u, x0, method, options):
    return simulate_arrays(model, theta, t, u, method=method, x0=x0, **dict(options))


def simulate_model(
    model: RCModel,
    theta: Mapping | None,
    data,
    *,
    method: str = "exact",
    x0=None,
    **options,
) -> Simulation:
    """Simulate ``model`` with parameters θ over the inputs of ``data``.

    Args:
        model: an :class:`~jaxbox.models.RCModel` (or a library model name).
        theta: parameter values in SI units (``None``: the model's defaults).
        data: a :class:`~jaxbox.data.Dataset` holding the model's inputs at a regular step.
        method: ``"exact"`` (default; run in NumPy, so no program is compiled for a new
            structure or length: :func:`simulate_arrays` is the JAX route), ``"parallel"``
            (exact, parallel in time: the choice on a GPU, where it is 5× faster at 500 samples
            and 240× at 50 000 than the sequential scan; slower on a CPU) or ``"diffrax"``
            (adaptive Kvaerno3, ``rtol``/``atol``; with no other option, one compiled program
            serves every model of a padded size: :func:`~jaxbox.simulate.diffrax_runs_numpy`).
        x0: initial state [°C] overriding the ``T_*0`` parameters.

    Returns:
        :class:`Simulation` with times [s], outputs and states [°C] as numpy arrays.
    """
    from ..models import get_model

    require_x64()
    model = get_model(model)
    if method not in METHODS:
        raise ValueError(f"unknown simulation method {method!r}; choose one of {METHODS}")
    _check_options(method, options)
    theta = check_theta(model, theta)
    u, t = _inputs(model, data)
    x0 = _initial(model, x0)
    if method == "diffrax" and set(options) <= {"rtol", "atol"}:
        # adaptive, the default step control: the padded program that models of the same
        # padded size share (no compilation per structure); data in segments one by one, each
        # from its own initial states
        values = {k: float(np.asarray(v)) for k, v in theta.items()}
        A, B, C, D = model.state_space_numpy(values)
        if x0 is None:
            starts = np.asarray(model.initial_states(values), float)
        else:
            starts = np.asarray(x0, float)[None]
        parts = data.segments if x0 is None else ((0, len(t)),)
        x = np.concatenate(
            [
                diffrax_runs_numpy(A, B, t[a:b] - t[a], u[None, a:b], starts[k][None], **options)[0]
                for k, (a, b) in enumerate(parts)
            ]
        )
        return _checked(model, t, x @ C.T + u @ D.T, x)
    if method == "exact":
        # in NumPy (the same Van Loan exponential and recursion as the compiled route, to
        # rounding): a simulation compiles nothing, whatever its structure or length
        values = {k: float(np.asarray(v)) for k, v in theta.items()}
        A, B, C, D = model.state_space_numpy(values)
        dt = float(t[1] - t[0])
        if x0 is None:
            starts = np.asarray(model.initial_states(values), float)
            parts = _segments(np.asarray(t, float)) if model.segments > 1 else [(0, len(t))]
        else:
            starts, parts = np.asarray(x0, float)[None], [(0, len(t))]
        u = np.asarray(u, float)
        x = np.concatenate(
            [
                exact_runs_numpy(
                    A, B, C, D, dt, u[None, a:b], starts[min(k, len(starts) - 1)][None]
                )[1][0]
                for k, (a, b) in enumerate(parts)
            ]
        )
        return _checked(model, t, x @ C.T + u @ D.T, x)
    if method == "diffrax" and model.segments > 1 and x0 is None:
        # segment by segment, outside jit (the segments are read from the concrete times)
        y, x = simulate_arrays(model, theta, t, u, method=method, **options)
        return _checked(model, t, y, x)
    theta = {k: jnp.asarray(v, dtype=float) for k, v in theta.items()}
    try:
        y, x = _simulate_jit(
            model,
            theta,
            t,
            u,
            None if x0 is None else jnp.asarray(x0, float),
            method,
            tuple(sorted(options.items())),
        )
    except jax.errors.JaxRuntimeError as err:
        if "maximum number of solver steps" not in str(err):
            raise
        raise FloatingPointError(
            f"simulation of {model.name}: diffrax took max_steps="
            f"{options.get('max_steps')} steps before the last sample; raise max_steps (or "
            "leave it out: the default grows with the samples and the tolerances)"
        ) from None
    return _checked(model, t, y, x)


#: the options of method="diffrax" (:func:`~jaxbox.simulate.integrate_diffrax`)
DIFFRAX_OPTIONS = ("adaptive", "rtol", "atol", "substeps", "max_steps", "adjoint", "throw", "norm")


def _check_options(method: str, options: Mapping) -> None:
    """Options are diffrax's only: named among :data:`DIFFRAX_OPTIONS`, tolerances finite and
    positive, ``substeps`` and ``max_steps`` positive integers."""
    if options and method != "diffrax":
        raise TypeError(
            f"option(s) {', '.join(options)} apply to method='diffrax' only; method={method!r} "
            "takes none"
        )
    bad = [k for k in options if k not in DIFFRAX_OPTIONS]
    if bad:
        raise TypeError(
            f"method='diffrax' has no option(s) {', '.join(bad)}; its options are "
            f"{', '.join(DIFFRAX_OPTIONS)}"
        )
    for name in ("rtol", "atol"):
        if name in options:
            value = options[name]
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise TypeError(f"diffrax option {name} must be a number, got {value!r}")
            if not (np.isfinite(value) and value > 0):
                raise ValueError(
                    f"diffrax option {name} = {value!r} must be a finite number above zero "
                    "(e.g. 1e-6)"
                )
    for name in ("substeps", "max_steps"):
        value = options.get(name)
        if value is None and name == "max_steps":
            continue
        if name in options and (
            isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1
        ):
            raise ValueError(f"diffrax option {name} = {value!r} must be a whole number >= 1")


def _inputs(model: RCModel, data) -> tuple[np.ndarray, np.ndarray]:
    """``(u [N, m], t [N] s)`` of ``data`` for ``model``: a Dataset holding every input, finite
    at every sample, at least two samples, in one segment unless the model has initial states
    for more (:meth:`~jaxbox.models.RCModel.segmented`)."""
    from ..data import DataError, Dataset

    if not isinstance(data, Dataset):
        raise TypeError(
            f"data must be a jaxbox.data.Dataset, got {type(data).__name__}; wrap a frame with "
            "jaxbox.data.Dataset(frame), arrays with Dataset.from_arrays(t, signals), or read a "
            "file with jaxbox.data.load"
        )
    model.check_data(data, outputs=False)
    if len(data) < 2:
        raise ModelError(f"simulation of {model.name} needs at least two samples, got {len(data)}")
    u = data.array(list(model.inputs))
    bad = ~np.isfinite(u)
    if bad.any():
        j = int(np.flatnonzero(bad.any(axis=0))[0])
        rows = np.flatnonzero(bad[:, j])
        raise DataError(
            f"input {model.inputs[j]!r} of model {model.name} is NaN or infinite at "
            f"{len(rows)} sample(s), first at {data.index[rows[0]]}; the simulation needs every "
            "input at every sample: fill or cut the gaps with jaxbox.data.prepare_window"
        )
    parts = len(data.segments)
    if parts > model.segments:
        raise ModelError(
            f"the data hold {parts} segments (their time stamps jump over gaps) but model "
            f"{model.name} has initial states for {model.segments}; simulate "
            f"model.segmented({parts})"
        )
    return u, np.asarray(data.t, dtype=float)


def _initial(model: RCModel, x0):
    """``x0`` as a finite float array of one temperature [°C] per state, or None."""
    if x0 is None:
        return None
    try:
        x = np.asarray(x0, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(
            f"x0 must be one initial temperature [°C] per state ({', '.join(model.states)}), "
            f"got {x0!r}"
        ) from None
    if x.shape != (model.n_states,):
        raise ModelError(
            f"x0 has shape {x.shape} but model {model.name} has {model.n_states} states "
            f"({', '.join(model.states)}); give one initial temperature [°C] each"
        )
    if not np.all(np.isfinite(x)):
        raise ModelError(f"x0 = {x.tolist()} is not finite; give a temperature [°C] per state")
    return x


def _checked(model, t, y, x) -> Simulation:
    y, x = np.asarray(y), np.asarray(x)
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(x))):
        raise FloatingPointError(
            f"simulation of {model.name} produced non-finite values; check the parameters "
            "(capacities and resistances must be positive)"
        )
    return Simulation(t, y, x)
