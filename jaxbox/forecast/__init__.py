"""Forecasts with uncertainty from a fitted model, and the heat demand for a setpoint.

:func:`stochastic_form` turns a fit into a stochastic state-space model (an output-error fit's
noise estimated from its residuals); :func:`forecast` filters the history and propagates the
state over a horizon with future inputs, with 50 % and 95 % bands; :func:`backtest` scores
forecasts from many origins against measured data (RMSE and band coverage per horizon);
:func:`plot_forecast` draws one; :func:`heat_demand` inverts the model for the heating power
that holds a zone at a setpoint (clipped to the heater's range, the zone floating where it is
saturated), with the energy over the horizon and its band.
"""

from ._demand import SetpointWarning as SetpointWarning
from ._demand import heat_demand as heat_demand
from ._demand import parse_setback as parse_setback
from ._demand import setpoint_schedule as setpoint_schedule
from ._forecast import BANDS as BANDS
from ._forecast import backtest as backtest
from ._forecast import forecast as forecast
from ._forecast import parameter_covariance as parameter_covariance
from ._forecast import propagate as propagate
from ._form import DiscreteSystem as DiscreteSystem
from ._form import FilterRun as FilterRun
from ._form import StochasticForm as StochasticForm
from ._form import noise_from_residuals as noise_from_residuals
from ._form import stochastic_form as stochastic_form
from ._plot import plot_forecast as plot_forecast
