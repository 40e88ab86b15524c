"""The model library: named, documented RC structures ready to fit.

Models are registered by name, with family tags; :func:`get_model` returns a fresh
:class:`RCModel`, :func:`list_models` lists the names (of one family with ``family=``), and
:func:`describe_models` describes them all (what ``jaxbox models --json`` prints). Names spell the
structure with the naming-convention subscripts: ``Zon`` (zone air, with its envelope resistance
``R_wal``, heating ``Q_hea`` and solar aperture ``gA``), ``Wal`` (envelope capacity), ``Int``
(internal mass), ``Inf`` (infiltration), ``Win`` (windows east and west instead of one horizontal
aperture), ``Bou`` (boundary resistance to ``T_bou``), ``BouC`` (boundary with a capacity),
``Zon2`` (two zones). Models are declared from :mod:`~jaxbox.models.components`; so can yours::

    from jaxbox.models import RCNetwork, components as c, register

    @register("ZonWalGro", family="mine")
    def _():
        net = c.wall(c.zone(RCNetwork("ZonWalGro", "...")))
        return c.window(c.heating(c.ground(net, to=None)))

Families
--------
``exp1``: the single-zone hierarchy of De Coninck et al. (2016), experiment 1 (free parameters,
initial states included):

1. ``Zon``: C_zon, R_wal, gA, T_zon0 (inputs T_amb, I_glo_hor, Q_hea);
2. ``ZonWal``: + envelope state: C_zon, C_wal, R_wal, gA, T_zon0, T_wal0;
3. ``ZonWalIntInf``: + internal mass and infiltration: C_zon, C_wal, C_int, R_wal, R_int, R_inf,
   gA, T_zon0, T_wal0, T_int0;
4. ``ZonWalIntInfWin``: windows east and west (gA_e, gA_w on I_e, I_w) in place of gA;
5. ``ZonWalIntInfWinBou``: + R_bou to the attic temperature T_bou;
6. ``ZonWalIntInfWinBouC``: R_bou split around a capacity C_bou (+ T_bou0).

``exp2``: zones with internal mass and a boundary. ``ZonIntBou``: C_zon, C_int, R_int, R_wal,
R_bou, gA, T_zon0, T_int0, the neighbouring zone as boundary temperature T_bou. ``Zon2IntBou``:
two such zones (parameters numbered 1 and 2: C_zon1, …, T_int20; inputs Q_hea1, Q_hea2; outputs
T_zon1, T_zon2) whose boundary is each other, one resistance R_bou; ``Zon2IntBouC``: a wall
R_bou–C_bou–R_bou between them (+ T_bou0).

``bacher-madsen``: the ladder of Bacher & Madsen (2011), *Identifying suitable models for the heat
dynamics of buildings*, Energy and Buildings 43:1511–1522, as used with CTSM-R, named ``BM_`` +
their name. Their states and parameters in our names:

============================= ================================ ==================================
Bacher & Madsen               jaxbox                           component
============================= ================================ ==================================
Ti, Ci (interior)             T_zon, C_zon                     :func:`~components.zone`
Te, Ce (envelope)             T_wal, C_wal                     :func:`~components.wall`
Rie, Rea                      fra_wal·R_wal, (1−fra_wal)·R_wal ``wall(position="fra_wal")``
Ria (models without Te)       R_wal                            ``wall(capacity=False)``
Ria (with Te: the Ria models) R_inf                            :func:`~components.infiltration`
Th, Ch, Rih (heater)          T_hea, C_hea, R_hea              ``embedded(name="hea")``
Ts, Cs, Ris (sensor)          T_sen, C_sen, R_sen (measured)   :func:`~components.sensor`
Tm, Cm, Rim (interior medium) T_int, C_int, R_int              :func:`~components.internal_mass`
Aw (solar on the interior)    gA                               :func:`~components.window`
Ae (solar on the envelope)    gA_wal                           ``window(zone="wal", name="wal")``
Φh, Φs, Ta                    Q_hea, I_glo_hor, T_amb          inputs
============================= ================================ ==================================

Models: ``BM_Ti`` (the structure of ``Zon``), ``BM_TiTe``, ``BM_TiTh``, ``BM_TiTeTh``,
``BM_TiTmTe``, ``BM_TiTeThRia``, ``BM_TiTmTeTh``, ``BM_TiTeThTs``, ``BM_TiTmTeThTs``, and with solar
gains on the envelope ``BM_TiTeAe``, ``BM_TiTeThAe``, ``BM_TiTmTeAe``, ``BM_TiTeThRiaAe``,
``BM_TiTmTeThAe``, ``BM_TiTeThTsAe``, ``BM_TiTmTeThTsAe``. Where the heater Th exists, Q_hea enters
it; otherwise Q_hea enters the interior. With the sensor Ts, ``T_zon`` is measured on it.

Identifiability: in output-error estimation the models with both Th and Ts (``BM_TiTeThTs``,
``BM_TiTmTeThTs`` and their ``Ae`` variants) have one combination of ``C_zon``, ``C_hea``,
``C_sen``, ``R_hea`` and ``R_sen`` that the measured ``T_zon`` does not determine: the interior
node is hidden between two dead-end branches. Fix one of them (e.g. ``fixed={"C_sen": 1e5}``)
to identify the others.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
from collections.abc import Callable, Sequence

from . import _components as c
from ._grammar import Grammar, is_structure_name, parse_structure
from ._network import RCModel, RCNetwork
from ._parameters import ModelError

__all__ = [
    "register",
    "get_model",
    "list_models",
    "library_models",
    "families",
    "model_families",
    "describe_models",
]


@dataclasses.dataclass(frozen=True)
class _Entry:
    make: Callable[[], RCModel]
    families: tuple[str, ...]


_REGISTRY: dict[str, _Entry] = {}
_FAMILY = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


def _families(family) -> tuple[str, ...]:
    if family is None:
        return ()
    out = (family,) if isinstance(family, str) else tuple(family)
    for f in out:
        if not isinstance(f, str) or not _FAMILY.fullmatch(f):
            raise ModelError(f"family tag {f!r} must be letters, digits, '-', '_' or '.'")
    return out


def register(
    name: str,
    factory: Callable[[], RCModel | RCNetwork] | None = None,
    *,
    family: str | Sequence[str] | None = None,
    replace: bool = False,
):
    """Register a model factory under ``name``, tagged with one or more ``family`` names.

    ``factory`` returns an :class:`RCNetwork` (built on each call) or an :class:`RCModel`; the
    model is built once here, so a faulty declaration fails at registration. The model takes the
    registered name. Without ``factory``, returns a decorator::

        @register("ZonGro", family="mine")
        def zon_gro():
            return ...

    Raises:
        ModelError: the name exists (pass ``replace=True``), or the declaration is invalid.
    """
    if factory is None:
        return lambda f: register(name, f, family=family, replace=replace)
    if not isinstance(name, str) or not name:
        raise ModelError(f"a library model needs a non-empty name, got {name!r}")
    if name in _REGISTRY and not replace:
        raise ModelError(f"a library model named {name!r} exists already; pass replace=True")
    tags = _families(family)

    def make() -> RCModel:
        m = factory()
        if isinstance(m, RCNetwork):
            m = m.build()
        if not isinstance(m, RCModel):
            raise ModelError(
                f"the factory of library model {name!r} returned {type(m).__name__}; it must "
                "return an RCNetwork or an RCModel"
            )
        return m if m.name == name else m.renamed(name)

    make()
    _REGISTRY[name] = _Entry(make, tags)
    return factory


def get_model(name: str | RCModel, columns: Sequence[str] | None = None) -> RCModel:
    """The library model ``name`` (an :class:`RCModel` is passed through); a structure name of
    the component grammar (``"Zon+Wal+Int"``, :mod:`~jaxbox.models.grammar`) builds that
    structure.

    ``columns``: the data's canonical columns. A structure is then built for those data as the
    structure search builds it (:meth:`~jaxbox.models.Grammar.from_columns`): without a solar
    aperture where they have no ``I_glo_hor``, without heating where they have no ``Q_hea``.
    Without them (or where they hold no zone and ``T_amb``) it has both. Library models do not
    depend on the data.
    """
    if isinstance(name, RCModel):
        return name
    if name not in _REGISTRY and is_structure_name(name):
        structure = parse_structure(name)
        if columns is not None:
            try:
                grammar = Grammar.from_columns([str(x) for x in columns])
            except ModelError:
                grammar = None  # no zone or no T_amb: the fit names the missing column
            if grammar is not None:
                return structure.build(grammar)
        return structure.build()
    try:
        return _REGISTRY[name].make()
    except (KeyError, TypeError):
        near = difflib.get_close_matches(name, _REGISTRY, n=1) if isinstance(name, str) else []
        meant = f"did you mean {near[0]!r}? " if near else ""
        raise ModelError(
            f"no library model named {name!r}; {meant}available: {', '.join(_REGISTRY)} "
            "(`jaxbox models` lists them), or a structure of the component grammar such as "
            "'Zon+Wal+Int' (jaxbox.models.grammar)"
        ) from None


def _check_family(family: str | None) -> None:
    if family is not None and family not in families():
        raise ModelError(f"no model family {family!r}; families: {', '.join(families())}")


def list_models(family: str | None = None) -> list[str]:
    """Names of the library models, in registration order (simple to complex within a family);
    only those tagged ``family`` (``"exp1"``, ``"exp2"``, ``"bacher-madsen"``…) when given."""
    _check_family(family)
    return [n for n, e in _REGISTRY.items() if family is None or family in e.families]


def library_models(family: str | None = None) -> list[RCModel]:
    """The library models (of ``family``), in registration order."""
    return [_REGISTRY[n].make() for n in list_models(family)]


def families() -> dict[str, list[str]]:
    """Family tag -> model names, in registration order."""
    out: dict[str, list[str]] = {}
    for n, e in _REGISTRY.items():
        for f in e.families:
            out.setdefault(f, []).append(n)
    return out


def model_families(name: str) -> tuple[str, ...]:
    """The family tags of library model ``name``."""
    get_model(name)
    return _REGISTRY[name].families


def describe_models(family: str | None = None) -> list[dict]:
    """JSON-ready descriptions of the library models (of ``family``): :meth:`RCModel.describe`
    plus ``families`` and the number of free parameters."""
    out = []
    for n in list_models(family):
        d = _REGISTRY[n].make().describe()
        d["families"] = list(_REGISTRY[n].families)
        d["n_parameters"] = len(d["parameters"])
        out.append(d)
    return out


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


# ---- experiment 1, continued: built from components ----------------------------------------------


def _exp1(name: str, description: str, *, windows: bool, bou: int) -> RCNetwork:
    """Zone + envelope state + internal mass + infiltration, with one horizontal aperture or
    windows east and west, and optionally a boundary to T_bou (``bou``: 0 none, 1 resistance,
    2 resistance–capacity)."""
    net = RCNetwork(name, description)
    net = c.wall(c.zone(net))
    net = c.infiltration(c.internal_mass(net))
    if bou:
        net = c.boundary(net, to="T_bou", capacity=bou == 2)
    net = c.heating(net)
    if windows:
        return c.window(c.window(net, "I_e", name="e"), "I_w", name="w")
    return c.window(net, "I_glo_hor")


register("Zon", _zon, family="exp1")
register("ZonWal", _zon_wal, family="exp1")
register(
    "ZonWalIntInf",
    lambda: _exp1(
        "ZonWalIntInf",
        "zone air, envelope state (R_wal in halves around C_wal), internal mass C_int behind "
        "R_int, infiltration R_inf to ambient; gA on global horizontal irradiance",
        windows=False,
        bou=0,
    ),
    family="exp1",
)
register(
    "ZonWalIntInfWin",
    lambda: _exp1(
        "ZonWalIntInfWin",
        "as ZonWalIntInf with windows east and west (gA_e on I_e, gA_w on I_w) instead of gA",
        windows=True,
        bou=0,
    ),
    family="exp1",
)
register(
    "ZonWalIntInfWinBou",
    lambda: _exp1(
        "ZonWalIntInfWinBou",
        "as ZonWalIntInfWin with a resistance R_bou to the boundary (attic) temperature T_bou",
        windows=True,
        bou=1,
    ),
    family="exp1",
)
register(
    "ZonWalIntInfWinBouC",
    lambda: _exp1(
        "ZonWalIntInfWinBouC",
        "as ZonWalIntInfWinBou with R_bou split in halves around a boundary capacity C_bou",
        windows=True,
        bou=2,
    ),
    family="exp1",
)


# ---- experiment 2: zones with internal mass and a boundary ---------------------------------------


def _zone_int(net: RCNetwork, zone: str) -> RCNetwork:
    """One exp-2 zone: air, envelope resistance, internal mass, heating, horizontal aperture."""
    net = c.wall(c.zone(net, zone), zone, capacity=False)
    net = c.internal_mass(net, zone)
    return c.window(c.heating(net, zone=zone), "I_glo_hor", zone)


def _zon_int_bou() -> RCNetwork:
    net = RCNetwork(
        "ZonIntBou",
        "zone air with envelope resistance R_wal, internal mass C_int behind R_int, gA on "
        "global horizontal irradiance, and R_bou to the neighbouring zone's temperature T_bou",
    )
    return c.boundary(_zone_int(net, "zon"), to="T_bou")


def _zon2_int_bou(capacity: bool) -> RCNetwork:
    name = "Zon2IntBouC" if capacity else "Zon2IntBou"
    joint = "a wall R_bou split in halves around C_bou" if capacity else "one resistance R_bou"
    net = RCNetwork(
        name,
        "two ZonIntBou zones (parameters numbered 1, 2; heating Q_hea1, Q_hea2; outputs T_zon1, "
        f"T_zon2) joined by {joint}",
    )
    net = _zone_int(_zone_int(net, "zon1"), "zon2")
    return c.zone_coupling(net, "zon1", "zon2", capacity=capacity)


register("ZonIntBou", _zon_int_bou, family="exp2")
register("Zon2IntBou", lambda: _zon2_int_bou(False), family=("exp2", "multizone"))
register("Zon2IntBouC", lambda: _zon2_int_bou(True), family=("exp2", "multizone"))


# ---- Bacher & Madsen (2011) ---------------------------------------------------------------------

_BM_STATES = {"Ti": "interior", "Te": "envelope", "Th": "heater", "Ts": "sensor", "Tm": "medium"}


def _bacher_madsen(code: str) -> RCNetwork:
    """The Bacher & Madsen model ``code`` (e.g. ``TiTmTeThTsAe``) from components."""
    parts = re.findall(r"T[iehsm]|Ria|Ae", code)
    if "".join(parts) != code or parts[0] != "Ti":
        raise ModelError(f"cannot read Bacher & Madsen model {code!r}")
    has = set(parts)
    words = ", ".join(_BM_STATES[p] for p in parts if p in _BM_STATES)
    extras = {"Ria": "interior-ambient resistance Ria", "Ae": "solar gains on the envelope Ae"}
    more = "".join(f" + {extras[p]}" for p in parts if p in extras)
    net = RCNetwork(f"BM_{code}", f"Bacher & Madsen (2011) {code}: states {words}{more}")
    net = c.zone(net)
    if "Te" in has:
        net = c.wall(net, position="fra_wal")  # Rie = fra_wal R_wal, Rea = (1 - fra_wal) R_wal
    else:
        net = c.wall(net, capacity=False)  # Ria
    if "Tm" in has:
        net = c.internal_mass(net)
    if "Ria" in has:
        net = c.infiltration(net)
    net = c.embedded(net, name="hea") if "Th" in has else c.heating(net)
    if "Ts" in has:
        net = c.sensor(net)
    net = c.window(net, "I_glo_hor")
    if "Ae" in has:
        if "Te" not in has:
            raise ModelError(f"Bacher & Madsen {code!r}: Ae needs the envelope state Te")
        net = c.window(net, "I_glo_hor", "wal", name="wal")
    return net


BACHER_MADSEN = (
    "Ti",
    "TiTe",
    "TiTh",
    "TiTeTh",
    "TiTmTe",
    "TiTeThRia",
    "TiTmTeTh",
    "TiTeThTs",
    "TiTmTeThTs",
    "TiTeAe",
    "TiTeThAe",
    "TiTmTeAe",
    "TiTeThRiaAe",
    "TiTmTeThAe",
    "TiTeThTsAe",
    "TiTmTeThTsAe",
)

for _code in BACHER_MADSEN:
    register(f"BM_{_code}", lambda code=_code: _bacher_madsen(code), family="bacher-madsen")
del _code
