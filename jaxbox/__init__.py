"""jaxbox: grey-box RC thermal models of buildings, identified and validated with JAX.

Data → models → simulate → fit → validate → select → report. Call :func:`enable_x64` once after
import (the command line does it for you): every computation runs in float64.
"""

from . import data as data
from . import datasets as datasets
from . import models as models
from . import reference as reference
from . import report as report
from . import select as select
from . import validate as validate
from ._cache import enable_compilation_cache as enable_compilation_cache
from ._x64 import PrecisionError as PrecisionError
from ._x64 import enable_x64 as enable_x64
from .data import DataError as DataError
from .data import Dataset as Dataset
from .data import load as load
from .fit import FitError as FitError
from .fit import FitResult as FitResult
from .fit import LevenbergMarquardt as LevenbergMarquardt
from .fit import fit_batch as fit_batch
from .fit import fit_many as fit_many
from .fit import fit_model as fit_model
from .models import ModelError as ModelError
from .models import Parameter as Parameter
from .models import RCModel as RCModel
from .models import RCNetwork as RCNetwork
from .models import get_model as get_model
from .models import list_models as list_models
from .select import GreyBox as GreyBox
from .select import forward_selection as forward_selection
from .select import forward_selection_many as forward_selection_many
from .simulate import Simulation as Simulation
from .simulate import simulate_model as simulate_model

__version__ = "0.1.0"
