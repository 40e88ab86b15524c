"""Estimation: output-error least squares, bound transforms, multistart Levenberg–Marquardt."""

from ._batch import fit_batch as fit_batch
from ._batch import fit_many as fit_many
from ._batch import fit_model as fit_model
from ._fit import clear_compile_cache as clear_compile_cache
from ._fit import compile_cache_info as compile_cache_info
from ._fit import solve_starts as solve_starts
from ._guess import initial_guess as initial_guess
from ._guess import state_guess as state_guess
from ._guess import state_ranges as state_ranges
from ._problem import FitError as FitError
from ._problem import Problem as Problem
from ._problem import make_problem as make_problem
from ._problem import problem_arrays as problem_arrays
from ._result import FitResult as FitResult
from ._result import StartReport as StartReport
from ._sensitivity import FitSensitivity as FitSensitivity
from ._sensitivity import fit_sensitivity as fit_sensitivity
from ._solver import LevenbergMarquardt as LevenbergMarquardt
from ._solver import LMState as LMState
from ._solver import NielsenDamping as NielsenDamping
from ._solver import ScaledDampedNewton as ScaledDampedNewton
from ._starts import latin_hypercube as latin_hypercube
from ._starts import sample_starts as sample_starts
from ._transforms import Transform as Transform
from ._transforms import make_transform as make_transform
