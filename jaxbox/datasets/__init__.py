"""Example data sets shipped with jaxbox (small, derived from measured open data).

:func:`twinhouse_exp1` gives one of the two IEA EBC Annex 58 twin houses (Holzkirchen, summer
2013) as a :class:`jaxbox.data.Dataset`; :func:`bundled` gives a bundled dataset by its exact
name (``twinhouse_exp1:N2``, ``twinhouse_exp1:O5``, ``twinhouse_exp1:N2@10min``…, see
:data:`NAMES`), as the command line addresses them. :func:`make_fleet` and :func:`make_zoo`
generate synthetic buildings with known truth (the zoo: random structures of the component
grammar, realistic heating, sensor noise, offsets and gaps).
"""

from ._detailed import HEATERS as HEATERS
from ._detailed import DetailedBuilding as DetailedBuilding
from ._detailed import make_detailed_zoo as make_detailed_zoo
from ._fleet import FLEET_MODELS as FLEET_MODELS
from ._fleet import TRUTH_FILE as TRUTH_FILE
from ._fleet import make_fleet as make_fleet
from ._names import NAMES as NAMES
from ._names import bundled as bundled
from ._names import is_bundled as is_bundled
from ._twinhouse import CITATION as CITATION
from ._twinhouse import TWINHOUSE_EXP1_PHASES as TWINHOUSE_EXP1_PHASES
from ._twinhouse import twinhouse_exp1 as twinhouse_exp1
from ._zoo import HEATING_KINDS as HEATING_KINDS
from ._zoo import ZOO_TRUTH_CSV as ZOO_TRUTH_CSV
from ._zoo import ZOO_TRUTH_JSON as ZOO_TRUTH_JSON
from ._zoo import ZooBuilding as ZooBuilding
from ._zoo import make_zoo as make_zoo
from ._zoo import truth_table as truth_table
from ._zoo import write_zoo as write_zoo
