"""Model declaration: linear RC networks, parameters by naming convention, components, library."""

from . import _components as components  # noqa: F401  (the namespace jaxbox.models.components)
from . import _grammar as grammar  # noqa: F401  (the namespace jaxbox.models.grammar)
from ._grammar import Grammar as Grammar
from ._grammar import Structure as Structure
from ._grammar import extensions as extensions
from ._grammar import parse_structure as parse_structure
from ._grammar import random_structure as random_structure
from ._grammar import reductions as reductions
from ._grammar import roots as roots
from ._library import describe_models as describe_models
from ._library import families as families
from ._library import get_model as get_model
from ._library import library_models as library_models
from ._library import list_models as list_models
from ._library import model_families as model_families
from ._library import register as register
from ._network import RCModel as RCModel
from ._network import RCNetwork as RCNetwork
from ._parameters import REFERENCE_HLC as REFERENCE_HLC
from ._parameters import ModelError as ModelError
from ._parameters import Parameter as Parameter
from ._parameters import parameter_for as parameter_for
from ._parameters import scaled_parameter as scaled_parameter
