"""Example data sets shipped with jaxbox (small, derived from measured open data).

:func:`twinhouse_exp1` gives one of the two IEA EBC Annex 58 twin houses (Holzkirchen, summer
2013) as a :class:`jaxbox.data.Dataset`.
"""

from ._twinhouse import CITATION as CITATION
from ._twinhouse import TWINHOUSE_EXP1_PHASES as TWINHOUSE_EXP1_PHASES
from ._twinhouse import twinhouse_exp1 as twinhouse_exp1
