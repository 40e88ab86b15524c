"""Post-simulation validation: the fitted model re-simulated with an adaptive stiff solver.

Validation never reuses the estimation's simulator: the optimised parameters are simulated again
with diffrax (Kvaerno5, PID step control, steps clipped to the samples) so that any
discretisation error of the estimation shows up in the validation error. The run covers the
identification data (auto-validation) and continues over the validation data (cross-validation),
which therefore starts from the model state at the end of the identification period.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._x64 import require_x64
from ..simulate import simulate_arrays
from ._metrics import rmse, simulation_error

__all__ = ["Validation", "validate", "ValidationError"]


class ValidationError(ValueError):
    """The validation data does not fit the identification data; the message says why."""


@dataclasses.dataclass(frozen=True, eq=False)
class Validation:
    """Post-simulation of a fit on identification (auto) and validation (cross) data.

    Attributes:
        model: model name.
        outputs: output names (columns of the y arrays).
        weights: output weights q_j.
        method: simulator used (``diffrax`` adaptive by default).
        index_auto, index_cross: time stamps of the samples.
        y_auto, y_cross: measured outputs [°C], shape [N, p].
        sim_auto, sim_cross: simulated outputs [°C].
        x_auto, x_cross: simulated states [°C], shape [N, n].
        rmse_auto, rmse_cross: RMSE per output [K].
        se_auto, se_cross: weighted simulation error Σ q_j RMSE_j [K].
        inputs: input names (columns of the u arrays).
        u_auto, u_cross: measured inputs, shape [N, m] (°C, W, W/m²).
    """

    model: str
    outputs: tuple[str, ...]
    weights: tuple[float, ...]
    method: str
    index_auto: object
    y_auto: np.ndarray
    sim_auto: np.ndarray
    x_auto: np.ndarray
    rmse_auto: dict
    se_auto: float
    index_cross: object = None
    y_cross: np.ndarray | None = None
    sim_cross: np.ndarray | None = None
    x_cross: np.ndarray | None = None
    rmse_cross: dict | None = None
    se_cross: float | None = None
    inputs: tuple[str, ...] = ()
    u_auto: np.ndarray | None = None
    u_cross: np.ndarray | None = None

    @property
    def residuals_auto(self) -> np.ndarray:
        """Measured minus simulated outputs on the identification data [K]."""
        return self.y_auto - self.sim_auto

    @property
    def residuals_cross(self) -> np.ndarray | None:
        return None if self.y_cross is None else self.y_cross - self.sim_cross

    def residual_analysis(self, which: str = "auto", **options):
        """Residual analysis (:func:`~jaxbox.validate.analyse_residuals`) of one period.

        Args:
            which: ``"auto"`` (identification data) or ``"cross"`` (validation data).
            options: passed on (``max_lag``, ``lb_lags``, ``alpha``).
        """
        from ._residuals import analyse_residuals

        if which not in ("auto", "cross"):
            raise ValueError(f"which must be 'auto' or 'cross', got {which!r}")
        e = self.residuals_auto if which == "auto" else self.residuals_cross
        if e is None:
            raise ValueError("no validation data: call validate(result, valid) for 'cross'")
        u = self.u_auto if which == "auto" else self.u_cross
        return analyse_residuals(
            e,
            u,
            output_names=self.outputs,
            input_names=self.inputs if u is not None else None,
            **options,
        )

    @property
    def x_end(self) -> np.ndarray:
        """Model state at the end of the identification period [°C]."""
        return self.x_auto[-1]

    def to_dict(self) -> dict:
        return {
            "rmse_auto": dict(self.rmse_auto),
            "rmse_cross": None if self.rmse_cross is None else dict(self.rmse_cross),
            "se_auto": self.se_auto,
            "se_cross": self.se_cross,
            "method": self.method,
        }


def _contiguous(ident, valid) -> None:
    if abs(valid.step - ident.step) > 1e-6 * ident.step:
        raise ValidationError(
            f"the validation data has a step of {valid.step:g} s but the identification data "
            f"{ident.step:g} s; resample both to the same step"
        )
    gap = (valid.start - ident.end).total_seconds()
    if abs(gap - ident.step) > 1e-6 * ident.step:
        raise ValidationError(
            f"the validation data must start one step after the identification data ends "
            f"({ident.end}), so that the simulation runs on from the identified state; it starts "
            f"at {valid.start}. Pass the two halves of Dataset.split(), or slice the validation "
            "period to follow the identification period"
        )


def joined_arrays(result, valid=None):
    """Inputs u [N, m] and outputs y [N, p] of the identification data followed by the
    validation data (checked to follow directly), and the number of identification samples."""
    model = result.model
    ident = result.data
    names_in, names_out = list(model.inputs), list(model.outputs)
    u = ident.array(names_in)
    y = ident.array(names_out)
    n_id = len(u)
    if valid is not None:
        valid.require(names_in + names_out, what=f"model {model.name}")
        _contiguous(ident, valid)
        u = np.concatenate([u, valid.array(names_in)])
        y = np.concatenate([y, valid.array(names_out)])
    return u, y, n_id


def validate(
    result,
    valid=None,
    *,
    method: str = "diffrax",
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> Validation:
    """Post-simulate a fit on its identification data and, optionally, on validation data.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        valid: validation :class:`~jaxbox.data.Dataset` directly following the identification
            data (same step); ``None`` for auto-validation only.
        method: ``"diffrax"`` (adaptive Kvaerno5, default) or ``"exact"``.
        rtol, atol: tolerances of the adaptive solver.

    Returns:
        :class:`Validation` with RMSE per output and SE on both periods.
    """
    require_x64()
    model = result.model
    ident = result.data
    names_in, names_out = list(model.inputs), list(model.outputs)
    u, y, n_id = joined_arrays(result, valid)
    t = np.arange(len(u)) * ident.step
    opts = {"rtol": rtol, "atol": atol} if method == "diffrax" else {}
    ysim, xs = _simulate(model, result.params, t, u, method, tuple(sorted(opts.items())))
    if not (np.all(np.isfinite(ysim)) and np.all(np.isfinite(xs))):
        raise FloatingPointError(
            f"post-simulation of {model.name} produced non-finite values with the fitted "
            "parameters; the fit is not usable"
        )
    q = result.problem.weights
    r_auto = rmse(ysim[:n_id], y[:n_id])
    out = dict(
        model=model.name,
        outputs=tuple(names_out),
        weights=tuple(q),
        method=method,
        index_auto=ident.index,
        y_auto=y[:n_id],
        sim_auto=ysim[:n_id],
        x_auto=xs[:n_id],
        rmse_auto=dict(zip(names_out, map(float, r_auto), strict=True)),
        se_auto=simulation_error(r_auto, q),
        inputs=tuple(names_in),
        u_auto=u[:n_id],
    )
    if valid is not None:
        r_cross = rmse(ysim[n_id:], y[n_id:])
        out.update(
            index_cross=valid.index,
            y_cross=y[n_id:],
            sim_cross=ysim[n_id:],
            x_cross=xs[n_id:],
            rmse_cross=dict(zip(names_out, map(float, r_cross), strict=True)),
            se_cross=simulation_error(r_cross, q),
            u_cross=u[n_id:],
        )
    return Validation(**out)


def _simulate(model, params, t, u, method, options):
    import jax
    import jax.numpy as jnp

    fn = _JIT.get((model, method, options))
    if fn is None:

        def run(theta, t, u):
            return simulate_arrays(model, theta, t, u, method=method, **dict(options))

        fn = _JIT[(model, method, options)] = jax.jit(run)
    theta = {k: jnp.asarray(v, dtype=float) for k, v in params.items()}
    y, x = fn(theta, jnp.asarray(t), jnp.asarray(u))
    return np.asarray(y), np.asarray(x)


_JIT: dict = {}
