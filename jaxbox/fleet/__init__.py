"""Fleets: thousands of buildings identified on Dask, with physical KPIs and their intervals.

:func:`run_fleet` takes a folder of building files (or one long-format table), fits each
building (a given model or the forward selection), validates it, computes its KPIs
(:func:`jaxbox.validate.kpis`) and writes one row per building to ``results.parquet``
(:func:`read_results`), partition by partition, on a local or remote Dask cluster.
"""

from ._config import FleetConfig as FleetConfig
from ._config import FleetError as FleetError
from ._config import load_config as load_config
from ._results import SCHEMA as SCHEMA
from ._results import read_results as read_results
from ._run import FleetRun as FleetRun
from ._run import run_fleet as run_fleet
from ._sources import Building as Building
from ._sources import discover as discover
from ._work import STATUSES as STATUSES
from ._work import process_partition as process_partition
