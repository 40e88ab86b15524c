"""Post-simulation validation: the fitted model re-simulated with an adaptive stiff solver.

Validation never reuses the estimation's simulator: the optimised parameters are simulated again
with diffrax (Kvaerno3, PID step control, steps clipped to the samples) so that any
discretisation error of the estimation shows up in the validation error. The run covers the
identification data (auto-validation) and continues over the validation data (cross-validation),
which therefore starts from the model state at the end of the identification period. Data in
segments are simulated segment by segment (a validation segment after a long gap from initial
states estimated on it), and output gaps are left out of the metrics.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._x64 import require_x64
from ..simulate import diffrax_runs_numpy
from ..simulate._diffrax import ADAPTIVE_ATOL, ADAPTIVE_RTOL
from ..simulate._exact import discretize_foh_numpy, exact_runs_numpy
from ._metrics import rmse, simulation_error

__all__ = ["Validation", "validate", "ValidationError", "CARRY_GAP"]

#: The longest gap [s] (missing time) before a validation segment across which the model state
#: is carried (one exact step, the inputs interpolated linearly). After a longer gap the
#: interpolated inputs miss what drove the building (a day's sun, the heating), so the segment's
#: unmeasured initial states are estimated from its own outputs instead (a linear least-squares
#: fit, as MATLAB's ``compare`` does by default).
CARRY_GAP = 6 * 3600.0


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
        step: sampling step [s] (the time stamps jump over gaps cut out of the data).

    A missing measurement (an output gap) is NaN in ``y_*`` and in the residuals.
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
    step: float | None = None

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
        index = self.index_auto if which == "auto" else self.index_cross
        e, u = _separated(e, u, index, self.step, options.get("max_lag"))
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


def _separated(e, u, index, step, max_lag):
    """Residuals (and inputs) of data in segments with ``L`` rows of NaN between segments
    (``L`` the largest lag of the residual tests), so that no lagged pair spans a cut."""
    from ..data._gaps import segment_slices
    from ._residuals import _lags, default_max_lag

    if step is None or index is None:
        return e, u
    pieces = segment_slices(index, step)
    if len(pieces) == 1:
        return e, u
    lag = _lags(max_lag, "max_lag", default_max_lag(len(e)))
    parts_e, parts_u = [], []
    for k, (a, b) in enumerate(pieces):
        if k:
            parts_e.append(np.full((lag,) + e.shape[1:], np.nan))
            if u is not None:
                parts_u.append(np.full((lag,) + u.shape[1:], np.nan))
        parts_e.append(e[a:b])
        if u is not None:
            parts_u.append(u[a:b])
    return np.concatenate(parts_e), (None if u is None else np.concatenate(parts_u))


def _contiguous(ident, valid) -> None:
    if abs(valid.step - ident.step) > 1e-6 * ident.step:
        raise ValidationError(
            f"the validation data has a step of {valid.step:g} s but the identification data "
            f"{ident.step:g} s; resample both to the same step"
        )
    if valid.start <= ident.end:
        raise ValidationError(
            f"the validation data must start after the identification data ends ({ident.end}), "
            f"so that the simulation runs on from the identified state; it starts at "
            f"{valid.start}. Pass the two halves of Dataset.split(), or Dataset.windows()"
        )


def _zone(tz) -> str:
    return "naive (no time zone)" if tz is None else f"in time zone {tz}"


def _same_zone(ident, valid):
    """``valid`` with its time stamps in the time zone of ``ident`` (the same instants): naive
    and zone-aware time stamps cannot be compared, so that mix is refused."""
    tz_id, tz_va = ident.index.tz, valid.index.tz
    if (tz_id is None) != (tz_va is None):
        raise ValidationError(
            f"the validation data's time stamps are {_zone(tz_va)} but the identification "
            f"data's are {_zone(tz_id)}; load both with the same tz (jaxbox.data.load(..., "
            "tz=...)) or localize both"
        )
    if tz_id is None or str(tz_id) == str(tz_va):
        return valid
    return valid._new(valid._frame.tz_convert(tz_id), valid.step)


def validation_window(result, valid, max_gap=None):
    """The validation :class:`~jaxbox.data.Dataset` checked to follow the identification data of
    ``result`` (a Dataset, the same step, the same time zone: one in another zone is converted,
    later in time) and prepared for its gaps as the fit's were."""
    from ._args import check_dataset

    valid = _same_zone(result.data, check_dataset(valid, "valid (the validation data)"))
    _contiguous(result.data, valid)
    return _prepared(result, valid, max_gap)


def _prepared(result, valid, max_gap):
    """The validation window with its gaps prepared as the fit's were."""
    from ..data import DataError, prepare_window
    from ..data._gaps import DEFAULT_MAX_GAP

    model = result.model
    gap = result.settings.get("max_gap", DEFAULT_MAX_GAP) if max_gap is None else max_gap
    try:
        valid.require(list(model.inputs) + list(model.outputs), what=f"model {model.name}")
        return prepare_window(
            valid, model.inputs, model.outputs, max_gap=gap, what="validation data"
        )
    except DataError as err:
        raise ValidationError(str(err)) from None


def joined_arrays(result, valid=None):
    """Inputs u [N, m] and outputs y [N, p] of the identification data followed by the
    validation data (checked to follow it, already prepared for its gaps), and the number of
    identification samples."""
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


def segment_starts(result, valid=None) -> list[tuple[int, int, np.ndarray | None]]:
    """``[(start, stop, x0), …]`` over the identification data followed by ``valid``: each
    segment with its initial state [°C], or ``None`` for a segment of the validation data that
    does not follow the identification data directly (it starts from the data rule of
    :func:`jaxbox.fit.state_guess`)."""
    from ..data._gaps import segment_slices

    ident = result.data
    index = ident.index if valid is None else ident.index.append(valid.index)
    pieces = segment_slices(index, ident.step)
    model = result.model
    theta = {k: np.asarray(v) for k, v in result.params.items()}
    X0 = np.asarray(model.initial_states(theta)).reshape(-1, model.n_states)
    n_id = len(ident)
    return [(a, b, X0[k] if a < n_id else None) for k, (a, b) in enumerate(pieces)]


def validate(
    result,
    valid=None,
    *,
    method: str = "diffrax",
    rtol: float = ADAPTIVE_RTOL,
    atol: float = ADAPTIVE_ATOL,
    max_gap: float | str | None = None,
) -> Validation:
    """Post-simulate a fit on its identification data and, optionally, on validation data.

    Args:
        result: a :class:`~jaxbox.fit.FitResult`.
        valid: validation :class:`~jaxbox.data.Dataset` after the identification data (same
            step; time stamps in another time zone are converted to the identification
            data's, naive and zone-aware ones are not mixed); ``None`` for auto-validation only.
        method: ``"diffrax"`` (adaptive Kvaerno3, default) or ``"exact"``.
        rtol, atol: tolerances of the adaptive solver (> 0; atol in K).
        max_gap: the longest input gap of the validation data filled by interpolation [s]
            (default: the fit's, see :func:`jaxbox.data.prepare_window`).

    Data in segments are simulated segment by segment: each segment of the identification data
    from its estimated initial states; the validation data from the model state at the end of
    the identification data when they follow it directly. A segment of theirs after a gap of at
    most :data:`CARRY_GAP` (missing time) starts from the model state carried across the gap
    (one exact step with the inputs interpolated linearly over it), measured states restarting at
    their measurement. After a longer gap, or one with an input missing at its edges, the
    measured states start at their measurement and the unmeasured ones are estimated from the
    segment's outputs (linear least squares; the data rule of :func:`jaxbox.fit.state_guess`
    where the segment does not observe them): interpolated inputs over a day miss what drove
    the building, and a slow envelope state guessed wrong would dominate the validation error.
    Output gaps are left out of the RMSE and SE.

    Returns:
        :class:`Validation` with RMSE per output and SE on both periods.

    Raises:
        TypeError: ``result`` is not a FitResult (a stochastic fit included) or ``valid`` not a
            Dataset.
        ValidationError: the validation data do not follow the identification data (step, time
            zone, start), lack a column of the model, or leave no usable segment.
        ValueError: an unknown ``method`` or a tolerance that is not a positive number.

    Example:
        ```python
        v = validate(result, valid)          # result from jaxbox.fit_model on the first half
        print(v.rmse_auto, v.rmse_cross)     # RMSE per output [K]
        fig = plot_fit(v)
        ```
    """
    from ..fit import state_guess
    from ._args import check_fit, check_positive

    require_x64()
    result = check_fit(result, needs=("problem", "model", "data", "params", "settings"))
    if method not in ("diffrax", "exact"):
        raise ValueError(f"unknown post-simulation method {method!r}; use 'diffrax' or 'exact'")
    rtol = check_positive(rtol, "rtol (relative tolerance of the adaptive solver)")
    atol = check_positive(atol, "atol (absolute tolerance of the adaptive solver)", "K")
    model = result.model
    ident = result.data
    names_in, names_out = list(model.inputs), list(model.outputs)
    if valid is not None:
        valid = validation_window(result, valid, max_gap)
    u, y, n_id = joined_arrays(result, valid)
    opts = {"rtol": rtol, "atol": atol} if method == "diffrax" else {}
    base = model.segmented(1)
    theta = {k: result.params[k] for k in base.param_names}
    pieces, starts, carried = [], [], []
    for a, b, x0 in segment_starts(result, valid):
        if x0 is None:
            part = valid._new(valid._frame.iloc[a - n_id : b - n_id], valid.step)
            guess = state_guess(base, part)
            x0 = np.asarray([guess[m.T0] for m in base.network.nodes])
            for i, m in enumerate(base.network.nodes):
                if m.constant:  # a constant node keeps its estimated value
                    x0[i] = result.params[m.T0]
        carried.append(a >= n_id and bool(pieces))
        pieces.append((a, b))
        starts.append(np.asarray(x0, dtype=float))
    # every segment in one call: padded to the longest (inputs held), simulated under vmap
    length = max(b - a for a, b in pieces)
    U = np.stack([np.pad(u[a:b], ((0, length - (b - a)), (0, 0)), mode="edge") for a, b in pieces])
    t = np.arange(length) * ident.step
    X0 = np.stack(starts)
    key = tuple(sorted(opts.items()))
    Y, X = _simulate(base, theta, t, U, X0, method, key)
    if any(carried):  # validation segments after a gap, in order: each from the one before
        index = ident.index if valid is None else ident.index.append(valid.index)
        measured = result.problem.output_states
        free = [i for i, m in enumerate(base.network.nodes) if i not in measured and not m.constant]
        sqrt_q = np.sqrt(np.asarray(result.problem.weights, dtype=float))
        for k, (a, b) in enumerate(pieces):
            if not carried[k]:
                continue
            pa, pb = pieces[k - 1]
            gap = float((index[a] - index[a - 1]).total_seconds())
            x = None
            if gap - float(ident.step) <= CARRY_GAP * (1 + 1e-9):  # its missing time
                x = _across_gap(base, theta, X[k - 1, pb - pa - 1], u[a - 1], u[a], gap)
            if x is None:  # a long gap, or inputs missing at its edges: from its own outputs
                x = _estimated_start(
                    base, theta, float(ident.step), X0[k], free, Y[k, : b - a], y[a:b], sqrt_q
                )
            else:
                for j, i in enumerate(measured):  # a measured state restarts at its measurement
                    x[i] = y[a, j] if np.isfinite(y[a, j]) else x[i]
            X0[k] = x
            Y, X = _simulate(base, theta, t, U, X0, method, key)
    ysim = np.concatenate([Y[k, : b - a] for k, (a, b) in enumerate(pieces)])
    xs = np.concatenate([X[k, : b - a] for k, (a, b) in enumerate(pieces)])
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
        step=float(ident.step),
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


def _estimated_start(model, params, dt, x0, free, sim, meas, sqrt_q):
    """The initial state ``x0`` [°C] of a validation segment after a long gap, its unmeasured
    states ``free`` (indices) estimated from the segment's outputs, as MATLAB's ``compare`` does
    by default: the weighted linear least-squares fit of the run ``sim`` [N, p] from ``x0`` to
    the measured ``meas`` [N, p] (output gaps left out), through the zero-input responses of the
    exact recursion at the step ``dt`` [s] (the outputs are linear in the initial state).
    Directions the segment hardly observes keep their value in ``x0``, and so does every state
    when the fit is not finite."""
    x0 = np.asarray(x0, dtype=float).copy()
    if not free or len(sim) < 2:
        return x0
    A, B, C, D = model.state_space_numpy({k: float(v) for k, v in params.items()})
    n = len(free)
    unit = np.zeros((n, A.shape[0]))
    unit[np.arange(n), free] = 1.0
    zeros = np.zeros((n, len(sim), B.shape[1]))
    resp, _ = exact_runs_numpy(A, B, C, D, dt, zeros, unit)  # [n, N, p]
    ok = np.isfinite(meas) & np.isfinite(sim)
    S = (resp * sqrt_q)[:, ok].T  # [measured samples, n]
    r = ((np.asarray(meas) - sim) * sqrt_q)[ok]
    if len(r) < n:
        return x0
    delta, *_ = np.linalg.lstsq(S, r, rcond=1e-9)
    if not np.all(np.isfinite(delta)):
        return x0
    x0[free] += delta
    return x0


def _across_gap(model, params, x, u0, u1, gap):
    """The state ``x`` [°C] carried across a gap of ``gap`` seconds: one exact first-order-hold
    step, the inputs interpolated linearly from ``u0`` (before) to ``u1`` (after); ``None`` when
    an input is missing at either edge."""
    if not (np.all(np.isfinite(u0)) and np.all(np.isfinite(u1)) and np.all(np.isfinite(x))):
        return None
    A, B, _, _ = model.state_space_numpy({k: float(v) for k, v in params.items()})
    Phi, G0, G1 = discretize_foh_numpy(A, B, gap)
    return Phi @ np.asarray(x) + G0 @ u0 + G1 @ (u1 - u0)


def _simulate(model, params, t, u, x0, method, options):
    """Outputs [S, N, p] and states [S, N, n] of S runs: inputs u [S, N, m] from x0 [S, n].

    Both routes take the state-space matrices evaluated in NumPy: the exact route runs in NumPy
    (:func:`exact_runs_numpy`), with no compilation per structure or data size, which a
    structure search that post-simulates dozens of candidates would pay; the diffrax route
    (:func:`~jaxbox.simulate.diffrax_runs_numpy`) compiles one program per padded size, which
    the models of a selection share."""
    A, B, C, D = model.state_space_numpy({k: float(v) for k, v in params.items()})
    u = np.asarray(u, float)
    if method == "exact":
        return exact_runs_numpy(A, B, C, D, float(t[1] - t[0]), u, x0)
    xs = diffrax_runs_numpy(A, B, t, u, x0, **dict(options))
    return xs @ C.T + u @ D.T, xs
