"""The model library: named, documented RC structures ready to fit.

Models are registered by name; :func:`get_model` returns a fresh :class:`RCModel`, and
:func:`list_models` lists the names. Names spell the structure with the naming-convention
subscripts: ``Zon`` (zone air), ``Wal`` (envelope), ``Int`` (internal mass), ``Inf``
(infiltration), ``Bou`` (boundary), ``Win`` (windows per orientation).
"""

from __future__ import annotations

from collections.abc import Callable

from ._network import RCModel, RCNetwork
from ._parameters import ModelError

__all__ = ["register", "get_model", "list_models", "library_models"]

_REGISTRY: dict[str, Callable[[], RCModel]] = {}


def register(name: str, factory: Callable[[], RCModel | RCNetwork], *, replace: bool = False):
    """Register a model factory under ``name`` (a network is built on each call)."""
    if name in _REGISTRY and not replace:
        raise ModelError(f"a library model named {name!r} exists already; pass replace=True")

    def make() -> RCModel:
        m = factory()
        return m.build() if isinstance(m, RCNetwork) else m

    _REGISTRY[name] = make
    return factory


def get_model(name: str | RCModel) -> RCModel:
    """The library model ``name`` (an :class:`RCModel` is passed through)."""
    if isinstance(name, RCModel):
        return name
    try:
        return _REGISTRY[name]()
    except KeyError:
        raise ModelError(
            f"no library model named {name!r}; available: {', '.join(_REGISTRY)} "
            "(`jaxbox models` lists them)"
        ) from None


def list_models() -> list[str]:
    """Names of every library model, in registration order (simple to complex)."""
    return list(_REGISTRY)


def library_models() -> list[RCModel]:
    return [make() for make in _REGISTRY.values()]


# ---- experiment-1 single-zone models (De Coninck et al. 2016) ------------------------------------


def _zon() -> RCNetwork:
    return (
        RCNetwork(
            "Zon",
            "one state: zone air and everything coupled to it; envelope R_wal to ambient; solar "
            "aperture gA on global horizontal irradiance",
        )
        .node("zon", output=True)
        .resistance("zon", "T_amb", "R_wal")
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA")
    )


def _zon_wal() -> RCNetwork:
    return (
        RCNetwork(
            "ZonWal",
            "zone air + envelope state: R_wal split in two equal halves around C_wal",
        )
        .node("zon", output=True)
        .node("wal")
        .resistance("zon", "wal", "R_wal", scale=0.5)
        .resistance("wal", "T_amb", "R_wal", scale=0.5)
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA")
    )


register("Zon", _zon)
register("ZonWal", _zon_wal)
