"""The noise parameters of the stochastic form of an RC model, by a naming convention.

The stochastic form of a model adds a Wiener process to every state equation and a white
measurement error to every output::

    dx = (A x + B u) dt + σ dω,     y_k = C x_k + D u_k + e_k,   e_k ~ N(0, diag(σ_y²))

========================= ======= ======================================= =================
name                      unit    meaning                                 default, bounds
========================= ======= ======================================= =================
``sigma_<node>``          K/√s    diffusion of state ``T_<node>``         1e-3, [1e-7, 0.1]
``sigma_y_<output>``      K       standard deviation of output errors     0.05, [1e-4, 5]
========================= ======= ======================================= =================

``<output>`` is the output name without its ``T_`` prefix (output ``T_zon`` → ``sigma_y_zon``).
A diffusion of ``s`` K/√s adds a variance ``s² Δt`` [K²] to its state over ``Δt`` seconds when
the state is left to itself (``s = 1e-3`` K/√s: about 0.06 K over an hour). Nodes held at a
constant temperature have no diffusion. A diffusion can be fixed to 0 (``fixed={"sigma_wal":
0}``); a measurement noise must stay positive.
"""

from __future__ import annotations

from ..models import Parameter, RCModel

__all__ = [
    "diffusion_names",
    "measurement_names",
    "noise_names",
    "noise_parameters",
    "SIGMA_DEFAULT",
    "SIGMA_BOUNDS",
    "SIGMA_Y_DEFAULT",
    "SIGMA_Y_BOUNDS",
]

#: default diffusion [K/√s] and its bounds
SIGMA_DEFAULT = 1e-3
SIGMA_BOUNDS = (1e-7, 0.1)
#: default measurement-noise standard deviation [K] and its bounds
SIGMA_Y_DEFAULT = 0.05
SIGMA_Y_BOUNDS = (1e-4, 5.0)


def _strip(name: str) -> str:
    return name[2:] if name.startswith("T_") and len(name) > 2 else name


def diffusion_names(model: RCModel) -> tuple[str | None, ...]:
    """Per state: its diffusion parameter ``sigma_<node>``, or None for a constant node."""
    return tuple(None if node.constant else f"sigma_{node.name}" for node in model.network.nodes)


def measurement_names(model: RCModel) -> tuple[str, ...]:
    """Per output: its measurement-noise parameter ``sigma_y_<output without T_>``."""
    return tuple(f"sigma_y_{_strip(o)}" for o in model.outputs)


def noise_names(model: RCModel) -> tuple[str, ...]:
    """Every noise parameter of the stochastic form: diffusions, then measurement noises."""
    return tuple(n for n in diffusion_names(model) if n) + measurement_names(model)


def noise_parameters(model: RCModel) -> tuple[Parameter, ...]:
    """The :class:`~jaxbox.models.Parameter` spec of each noise parameter (units, bounds)."""
    out = []
    for node, name in zip(model.network.nodes, diffusion_names(model), strict=True):
        if name:
            out.append(
                Parameter(
                    name,
                    "K/√s",
                    SIGMA_DEFAULT,
                    *SIGMA_BOUNDS,
                    f"diffusion of state T_{node.name}",
                )
            )
    for o, name in zip(model.outputs, measurement_names(model), strict=True):
        out.append(
            Parameter(
                name,
                "K",
                SIGMA_Y_DEFAULT,
                *SIGMA_Y_BOUNDS,
                f"standard deviation of the measurement error of {o}",
            )
        )
    return tuple(out)
