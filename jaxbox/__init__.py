"""jaxbox: grey-box RC thermal models of buildings, identified and validated with JAX.

Data → models → simulate → fit → validate → select → report. Call :func:`enable_x64` once after
import (the command line does it for you): every computation runs in float64.

The subpackages and the public names below load on first use, so that ``import jaxbox`` is light
(the command line installs its Ctrl-C handling before anything heavy is imported). The verbs are
``fit_model`` and ``simulate_model``; ``jaxbox.fit`` and ``jaxbox.simulate`` are the packages.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: subpackages, loaded on first use
_SUBPACKAGES = (
    "control",
    "data",
    "datasets",
    "design",
    "fit",
    "fleet",
    "forecast",
    "models",
    "reference",
    "report",
    "select",
    "simulate",
    "stochastic",
    "validate",
)
#: public name -> the module that defines it
_NAMES = {
    "enable_compilation_cache": "_cache",
    "PrecisionError": "_x64",
    "enable_x64": "_x64",
    "DataError": "data",
    "Dataset": "data",
    "load": "data",
    "design_experiment": "design",
    "FitError": "fit",
    "FitResult": "fit",
    "LevenbergMarquardt": "fit",
    "fit_model": "fit",
    "fit_batch": "fit",
    "fit_many": "fit",
    "run_fleet": "fleet",
    "plot_forecast": "forecast",
    "ModelError": "models",
    "Parameter": "models",
    "RCModel": "models",
    "RCNetwork": "models",
    "get_model": "models",
    "list_models": "models",
    "GreyBox": "select",
    "forward_selection": "select",
    "forward_selection_many": "select",
    "structure_search": "select",
    "Simulation": "simulate",
    "simulate_model": "simulate",
    "MLResult": "stochastic",
    "fit_ml": "stochastic",
}

__all__ = sorted([*_SUBPACKAGES, *_NAMES, "__version__"])


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    if name in _NAMES:
        value = getattr(importlib.import_module(f".{_NAMES[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'jaxbox' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
