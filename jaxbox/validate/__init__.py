"""Validation: post-simulation, error metrics (RMSE, SE)."""

from ._metrics import rmse as rmse
from ._metrics import simulation_error as simulation_error
from ._postsim import Validation as Validation
from ._postsim import ValidationError as ValidationError
from ._postsim import validate as validate
