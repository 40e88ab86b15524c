"""What an identified model is for, shared by the output-error and the maximum-likelihood
results: forecasts with bands, heat demand for a setpoint, the discrete state space."""

from __future__ import annotations

from ..data._gaps import DEFAULT_MAX_GAP

__all__ = ["ModelUses"]


class ModelUses:
    """Methods of a fitted result that use the identified model (each imports its module when
    called, so that the fit does not import forecasting or control)."""

    def stochastic_form(self):
        """The fit as a stochastic state-space model (:func:`jaxbox.forecast.stochastic_form`;
        an output-error fit's noise estimated from its residuals, once per result)."""
        from ..forecast import stochastic_form

        return stochastic_form(self)

    def forecast(
        self,
        history,
        future,
        *,
        horizon="24h",
        x0=None,
        parameters=False,
        calibrate=True,
        max_gap=DEFAULT_MAX_GAP,
    ):
        """Forecast of the outputs with 50 % and 95 % bands from the state the Kalman filter
        estimates at the end of ``history``, driven by the inputs of ``future`` over ``horizon``
        (samples or a duration such as ``"24h"``; ``parameters``: the bands also hold the
        uncertainty of the estimate; ``calibrate``: the bands scaled to the model's own
        multi-step errors over the history; ``max_gap``: the longest gap of the history's
        inputs bridged without reopening the filter): :func:`jaxbox.forecast.forecast`."""
        from ..forecast import forecast

        return forecast(
            self,
            history,
            future,
            horizon=horizon,
            x0=x0,
            parameters=parameters,
            calibrate=calibrate,
            max_gap=max_gap,
        )

    def heat_demand(self, history, future, *, setpoint, q_max, **options):
        """The heating power [W] that holds the zone at ``setpoint`` [°C] over the horizon,
        clipped to the heater's range, with the energy and its band:
        :func:`jaxbox.forecast.heat_demand` (``q_min``, ``setback``, ``horizon``, …)."""
        from ..forecast import heat_demand

        return heat_demand(self, history, future, setpoint=setpoint, q_max=q_max, **options)

    def to_state_space(self, step=None, *, data=None):
        """The exact discrete-time state space at ``step`` (seconds or ``"15min"``; default the
        fit's), with names, units, noise covariances and the last Kalman state estimate over
        ``data`` (default the fit's): :func:`jaxbox.control.to_state_space`."""
        from ..control._export import to_state_space

        return to_state_space(self, step, data=data)
