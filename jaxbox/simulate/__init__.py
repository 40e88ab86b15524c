"""Simulation: exact first-order-hold discretisation and diffrax implicit integration."""

from ._diffrax import RMSOver as RMSOver
from ._diffrax import diffrax_runs_numpy as diffrax_runs_numpy
from ._diffrax import integrate_diffrax as integrate_diffrax
from ._diffrax import simulate_diffrax as simulate_diffrax
from ._exact import discretize_foh as discretize_foh
from ._exact import simulate_exact as simulate_exact
from ._parallel import simulate_parallel as simulate_parallel
from ._simulate import METHODS as METHODS
from ._simulate import Simulation as Simulation
from ._simulate import simulate_arrays as simulate_arrays
from ._simulate import simulate_model as simulate_model
