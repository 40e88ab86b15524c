"""Stochastic grey-box models: the SDE form of every RC model, the continuous–discrete Kalman
filter, maximum-likelihood / MAP estimation, state estimation and likelihood-ratio tests.

``dx = (A x + B u) dt + σ dω``, ``y_k = C x_k + D u_k + e_k``: a diffusion ``sigma_<node>``
[K/√s] per state and a measurement noise ``sigma_y_<output>`` [K] per output
(:mod:`jaxbox.stochastic._noise`), exact (Van Loan) discretisation for zero- or first-order hold
of the inputs, a Joseph-form Kalman filter in ``lax.scan`` giving the negative log-likelihood,
BFGS from batched Latin-hypercube starts, intervals from the exact Hessian.
"""

from ._fit import DEFAULT_ML_MAX_STEPS as DEFAULT_ML_MAX_STEPS
from ._fit import DEFAULT_ML_STARTS as DEFAULT_ML_STARTS
from ._fit import fit_ml as fit_ml
from ._fit import fit_ml_many as fit_ml_many
from ._fit import solve_ml as solve_ml
from ._kalman import discretize as discretize
from ._kalman import kalman_scan as kalman_scan
from ._kalman import process_noise as process_noise
from ._kalman import process_noise_van_loan as process_noise_van_loan
from ._kalman import rts_scan as rts_scan
from ._noise import diffusion_names as diffusion_names
from ._noise import measurement_names as measurement_names
from ._noise import noise_names as noise_names
from ._noise import noise_parameters as noise_parameters
from ._problem import StochasticProblem as StochasticProblem
from ._problem import make_stochastic_problem as make_stochastic_problem
from ._problem import stochastic_arrays as stochastic_arrays
from ._problem import system as system
from ._result import MLResult as MLResult
from ._result import innovation_tests as innovation_tests
from ._result import likelihood_ratio_test as likelihood_ratio_test
from ._sample import simulate_sde as simulate_sde
from ._select import forward_selection_lr as forward_selection_lr
from ._select import parent_guess as parent_guess
from ._select import parent_starts as parent_starts
from ._states import StateEstimate as StateEstimate
from ._states import estimate_states as estimate_states
from ._states import k_step_errors as k_step_errors
