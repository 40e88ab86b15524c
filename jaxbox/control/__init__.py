"""The identified model put to work: exported for a controller or another tool, and in control.

:func:`to_state_space` gives the exact discrete-time state space of a fit at a chosen step (the
fit's hold of the inputs, names and units, the noise covariances, the last Kalman state
estimate); :class:`StateSpaceModel` saves it as JSON, NPZ, a Modelica model
(:func:`modelica_model`) or a python-control script, and :func:`read_state_space` reads it back.

:class:`LinearMPC` is a linear model-predictive controller of a zone's heating (energy times a
time-varying price plus the price of discomfort, the heater's bounds) solved as a linear program
by HiGHS; :func:`closed_loop` runs it, with the Kalman state at each step
(:class:`KalmanTracker`), or a :class:`PIController`, on a simulated building.
:func:`closed_loop_check` tells whether a fit is fit for control, where the true building is at
hand: its MPC against the true model's in closed loop (the verdict's closed-loop line).
"""

from ._check import MAX_DISCOMFORT as MAX_DISCOMFORT
from ._check import MAX_MODEL_COST as MAX_MODEL_COST
from ._check import ClosedLoopCheck as ClosedLoopCheck
from ._check import closed_loop_check as closed_loop_check
from ._export import FORMATS as FORMATS
from ._export import StateSpaceModel as StateSpaceModel
from ._export import modelica_model as modelica_model
from ._export import python_control_script as python_control_script
from ._export import read_state_space as read_state_space
from ._export import to_state_space as to_state_space
from ._loop import LoopResult as LoopResult
from ._loop import MPCController as MPCController
from ._loop import PIController as PIController
from ._loop import closed_loop as closed_loop
from ._loop import comfort_band as comfort_band
from ._mpc import KalmanTracker as KalmanTracker
from ._mpc import LinearMPC as LinearMPC
from ._mpc import MPCPlan as MPCPlan
