"""Example data sets shipped with jaxbox (small, derived from measured open data).

:func:`twinhouse_exp1` gives one of the two IEA EBC Annex 58 twin houses (Holzkirchen, summer
2013) as a :class:`jaxbox.data.Dataset`; :func:`bundled` gives a bundled dataset by its exact
name (``twinhouse_exp1:N2``, ``twinhouse_exp1:O5``, ``twinhouse_exp1:N2@10min``…, see
:data:`NAMES`), as the command line addresses them.
"""

from ._fleet import FLEET_MODELS as FLEET_MODELS
from ._fleet import TRUTH_FILE as TRUTH_FILE
from ._fleet import make_fleet as make_fleet
from ._names import NAMES as NAMES
from ._names import bundled as bundled
from ._names import is_bundled as is_bundled
from ._twinhouse import CITATION as CITATION
from ._twinhouse import TWINHOUSE_EXP1_PHASES as TWINHOUSE_EXP1_PHASES
from ._twinhouse import twinhouse_exp1 as twinhouse_exp1
