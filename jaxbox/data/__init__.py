"""Monitoring data: load, check, resample, slice and split time series of a building.

pandas is used here (and in :mod:`jaxbox.datasets`) only; everything downstream receives numpy
arrays from :meth:`Dataset.array`. Signals use canonical names with fixed units (°C, W, W/m²),
listed in :data:`SIGNALS`.

:func:`load` refuses what is always wrong (unparseable or duplicate time stamps and columns,
text in number columns, infinities, absurd magnitudes, a temperature column in kelvin);
:func:`check_plausibility` (or :meth:`Dataset.check_plausible`) judges the periods actually used
for identification and validation: physical ranges per kind of signal, kelvin/°F/kW mix-ups in
part of a column, spikes, jumps and stuck sensors. :func:`as_dataset` turns what a user passes
as data (a Dataset, a DataFrame, a path) into a Dataset. Gaps (missing rows and values) are
kept and judged in the windows used: :func:`prepare_window` interpolates short input gaps,
splits the window into segments at long ones and leaves output gaps to be masked;
:func:`concat_periods` joins separate periods as segments of one dataset.
"""

from ._args import check_mapping as check_mapping
from ._checks import check_finite as check_finite
from ._dataset import Dataset as Dataset
from ._errors import DataError as DataError
from ._errors import DataWarning as DataWarning
from ._gaps import DEFAULT_MAX_GAP as DEFAULT_MAX_GAP
from ._gaps import MAX_CUTS as MAX_CUTS
from ._gaps import concat_periods as concat_periods
from ._gaps import prepare_window as prepare_window
from ._load import as_dataset as as_dataset
from ._load import load as load
from ._plausible import ALLOWABLE as ALLOWABLE
from ._plausible import PLAUSIBLE_RANGES as PLAUSIBLE_RANGES
from ._plausible import Finding as Finding
from ._plausible import allowing as allowing
from ._plausible import check_plausibility as check_plausibility
from ._plausible import edge_samples as edge_samples
from ._plausible import find_implausible as find_implausible
from ._plausible import plausible_range as plausible_range
from ._plausible import trim_edges as trim_edges
from ._signals import CONSTANT as CONSTANT
from ._signals import SIGNALS as SIGNALS
from ._signals import signal_unit as signal_unit
from ._units import UNITS as UNITS
