"""The identified model put to work: exported for a controller or another tool.

:func:`to_state_space` gives the exact discrete-time state space of a fit at a chosen step (the
fit's hold of the inputs, names and units, the noise covariances, the last Kalman state
estimate); :class:`StateSpaceModel` saves it as JSON, NPZ, a Modelica model
(:func:`modelica_model`) or a python-control script, and :func:`read_state_space` reads it back.
"""

from ._export import FORMATS as FORMATS
from ._export import StateSpaceModel as StateSpaceModel
from ._export import modelica_model as modelica_model
from ._export import python_control_script as python_control_script
from ._export import read_state_space as read_state_space
from ._export import to_state_space as to_state_space
