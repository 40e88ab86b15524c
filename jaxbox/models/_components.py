"""Components: the building blocks of grey-box RC models, each a function ``network -> network``.

Every component adds nodes (states), resistances, heat inputs and their parameters to an
:class:`~jaxbox.models.RCNetwork` with the naming convention, so that related models share
parameter names (a parent's ``R_wal`` is the child's guess for ``R_wal``). Chain them as
functions or fluently with :meth:`RCNetwork.add`::

    from jaxbox.models import RCNetwork, components as c

    net = RCNetwork("ZonWalInt", "zone air, envelope capacity and internal mass")
    net = c.zone(net)                      # C_zon, T_zon0, output T_zon
    net = c.wall(net)                      # R_wal split in halves around C_wal, T_wal0
    net = c.internal_mass(net)             # C_int, R_int, T_int0
    net = c.heating(net, fra_rad=True)     # Q_hea, share fra_rad to the internal mass
    net = c.window(net, "I_s", name="s")   # gA_s on the south facade irradiance
    model = net.build()

====================== ====================================== ======================================
component              parameters [unit]                      physical meaning
====================== ====================================== ======================================
:func:`zone`           ``C_zon`` [J/K], ``T_zon0`` [°C]       zone air (and light content), measured
:func:`wall`           ``R_wal`` [K/W], ``C_wal`` [J/K]       envelope between zone and ambient
:func:`internal_mass`  ``C_int`` [J/K], ``R_int`` [K/W]       floors, inner walls linked to the air
:func:`infiltration`   ``R_inf`` [K/W]                        air exchange, parallel to the envelope
:func:`boundary`       ``R_bou`` [K/W] (+ ``C_bou`` [J/K])    exchange with a measured temperature
:func:`ground`         ``R_gro`` [K/W] (+ ``T_gro0`` [°C])    exchange with the ground
:func:`embedded`       ``C_emb`` [J/K], ``R_emb`` [K/W]       floor heating or concrete core
:func:`window`         ``gA_<name>`` [m²] (+ ``fra_sol`` [-]) solar gains through glazing
:func:`heating`        (+ ``fra_rad`` [-])                    heating power ``Q_hea`` [W]
:func:`electric_gains` ``fra_ele`` [-]                        internal gains ``fra_ele · P_ele`` [W]
:func:`sensor`         ``C_sen`` [J/K], ``R_sen`` [K/W]       a sensor with its own time constant
:func:`sensor_offset`  ``Q_off`` [W]                          constant sensor offset (or base load)
:func:`zone_coupling`  ``R_bou`` [K/W] (+ ``C_bou`` [J/K])    two zones sharing a wall or floor
====================== ====================================== ======================================

Multi-zone: name zones ``zon1``, ``zon2``… The digits of a zone's name are appended to every
name a component derives from it: ``wall(net, zone="zon1")`` adds ``R_wal1`` and ``C_wal1``,
``heating(net, zone="zon1")`` injects ``Q_hea1``, ``window(net, zone="zon1")`` estimates ``gA1``;
the zone is measured as ``T_zon1``. Numbered parameters take the defaults and bounds of their
base name (``C_zon1`` those of ``C_zon``). Pass ``suffix=`` to choose another suffix.
"""

from __future__ import annotations

import dataclasses
import re

from ..data._signals import CONSTANT
from ._network import RCNetwork
from ._parameters import ModelError, Parameter, parameter_for

__all__ = [
    "zone",
    "wall",
    "internal_mass",
    "infiltration",
    "boundary",
    "ground",
    "embedded",
    "window",
    "heating",
    "electric_gains",
    "sensor",
    "sensor_offset",
    "zone_coupling",
]

_DIGITS = re.compile(r"(.*?)(\d+)")


# ---- helpers ----------------------------------------------------------------------------------


def _suffix(zone: str, suffix: str | None) -> str:
    """The numeric suffix of a zone name (``zon2`` -> ``2``), unless given."""
    if suffix is not None:
        return str(suffix)
    m = _DIGITS.fullmatch(zone)
    return m.group(2) if m else ""


def spec_for(name: str, description: str | None = None) -> Parameter:
    """The naming-convention spec of ``name``; a numbered name (``C_zon1``, ``gA2``) takes the
    default and bounds of its base name (``C_zon``, ``gA``)."""
    m = _DIGITS.fullmatch(name)
    if m and not name.startswith("T_"):
        try:
            return parameter_for(m.group(1), description).replace(name=name)
        except ModelError:
            pass
    return parameter_for(name, description)


def _declare(net: RCNetwork, name: str, description: str, **fields) -> RCNetwork:
    """Declare the spec of ``name`` unless the network (or its user) declared it already."""
    if any(p.name == name for p in net.specs):
        return net
    return net.parameter(name, spec_for(name, description), **fields)


def _nodes(net: RCNetwork) -> tuple[str, ...]:
    return tuple(n.name for n in net.nodes)


def _require_zone(net: RCNetwork, zone: str, what: str) -> None:
    if zone not in _nodes(net):
        raise ModelError(
            f"{net.name}: {what} refers to unknown node {zone!r}; add the zone first with "
            f"zone(net, {zone!r}) (nodes so far: {', '.join(_nodes(net)) or 'none'})"
        )


def _split(net, a, b, R, C, T0, node, position, what) -> RCNetwork:
    """``R`` from ``a`` to ``b`` split around a capacity ``C``: ``position·R`` on ``a``'s side."""
    if isinstance(position, str):
        inner, outer = position, f"1-{position}"
    else:
        p = float(position)
        if not 0.0 < p < 1.0:
            raise ModelError(
                f"{net.name}: {what}: position {position!r} must lie strictly between 0 and 1 "
                "(the share of the resistance on the zone side), or name a fraction to estimate"
            )
        inner, outer = p, 1.0 - p
    net = net.node(node, C=C, T0=T0)
    net = net.resistance(a, node, R, scale=inner).resistance(node, b, R, scale=outer)
    if isinstance(position, str):
        net = _declare(
            net,
            position,
            f"share of {R} between {a} and the capacity {C} (the rest lies towards {b})",
            default=0.5,
            lower=0.01,
            upper=0.99,
        )
    return net


# ---- components -------------------------------------------------------------------------------


def zone(net: RCNetwork, name: str = "zon", *, output: bool | str = True) -> RCNetwork:
    """Zone air: a node ``name`` with heat capacity ``C_<name>`` [J/K] and initial temperature
    ``T_<name>0`` [°C], measured as output ``T_<name>`` [°C].

    Physical meaning: the air of the zone and everything in fast thermal contact with it
    (furniture, light partitions). Multi-zone: ``zone(net, "zon1")``, ``zone(net, "zon2")``.
    """
    net = net.node(name, output=output)
    return _declare(net, f"C_{name}", f"heat capacity of the air (and light content) of {name}")


def wall(
    net: RCNetwork,
    zone: str = "zon",
    to: str = "T_amb",
    *,
    name: str = "wal",
    capacity: bool = True,
    position: float | str = 0.5,
    suffix: str | None = None,
) -> RCNetwork:
    """Envelope: thermal resistance ``R_wal`` [K/W] from the zone to ``to`` (ambient ``T_amb``
    by default, or another temperature input or node); with ``capacity``, ``R_wal`` is split
    around a heat capacity ``C_wal`` [J/K] (state ``T_wal``, initial ``T_wal0`` [°C]).

    Physical meaning: the opaque envelope (walls, roof) conducting heat between the zone air and
    outside, with its thermal mass.

    Args:
        position: share of ``R_wal`` between the zone and ``C_wal`` (0.5: two halves); a
            fraction name such as ``"fra_wal"`` estimates it (bounds [0.01, 0.99]).
        capacity: ``False`` for a resistance without thermal mass.
        name: subscript of the parameters and of the node (``wal``).
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "wall")
    R, node = f"R_{name}{s}", f"{name}{s}"
    if capacity:
        net = _split(net, zone, to, R, f"C_{node}", f"T_{node}0", node, position, "wall")
        net = _declare(net, f"C_{node}", f"heat capacity of the envelope of {zone}")
        text = f"thermal resistance of the envelope, {zone} to {to}, split around C_{node}"
    else:
        net = net.resistance(zone, to, R)
        text = f"thermal resistance of the envelope, {zone} to {to}"
    return _declare(net, R, text)


def internal_mass(
    net: RCNetwork, zone: str = "zon", *, name: str = "int", suffix: str | None = None
) -> RCNetwork:
    """Internal mass: heat capacity ``C_int`` [J/K] (state ``T_int``, initial ``T_int0`` [°C])
    linked to the zone air by ``R_int`` [K/W].

    Physical meaning: floors, inner walls and heavy furniture, exchanging heat only with the
    zone air (by convection and radiation).
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "internal mass")
    node = f"{name}{s}"
    net = net.node(node).resistance(zone, node, f"R_{node}")
    net = _declare(net, f"C_{node}", f"heat capacity of the internal mass of {zone}")
    return _declare(net, f"R_{node}", f"resistance between the air of {zone} and its internal mass")


def infiltration(
    net: RCNetwork,
    zone: str = "zon",
    to: str = "T_amb",
    *,
    name: str = "inf",
    suffix: str | None = None,
) -> RCNetwork:
    """Infiltration and ventilation: resistance ``R_inf`` [K/W] between the zone air and the
    ambient temperature, in parallel with the envelope.

    Physical meaning: heat carried by air exchange, ``1/R_inf = ρ c_p V̇`` [W/K].
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "infiltration")
    R = f"R_{name}{s}"
    net = net.resistance(zone, to, R)
    return _declare(net, R, f"resistance of infiltration and ventilation, {zone} to {to}")


def boundary(
    net: RCNetwork,
    zone: str = "zon",
    to: str = "T_bou",
    *,
    name: str = "bou",
    capacity: bool = False,
    position: float | str = 0.5,
    suffix: str | None = None,
) -> RCNetwork:
    """Boundary to a measured temperature ``to`` (attic, cellar, neighbour; ``T_bou`` by
    default) or to another node: resistance ``R_bou`` [K/W] alone, or, with ``capacity``,
    ``R_bou`` split around a heat capacity ``C_bou`` [J/K] with initial temperature ``T_bou0``
    [°C] (node ``bouwal``, state ``T_bouwal``, so that it is not confused with the input).

    Physical meaning: the floor, ceiling or party wall towards a space whose temperature is
    known, with its thermal mass.

    Args:
        position: share of ``R_bou`` on the zone side of ``C_bou`` (or a fraction name).
        name: subscript (``bou``; e.g. ``cel`` for the cellar: ``R_cel``, ``C_cel``).
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "boundary")
    R = f"R_{name}{s}"
    if capacity:
        C, T0, node = f"C_{name}{s}", f"T_{name}{s}0", f"{name}wal{s}"
        net = _split(net, zone, to, R, C, T0, node, position, "boundary")
        net = _declare(net, C, f"heat capacity of the construction between {zone} and {to}")
        return _declare(net, R, f"resistance from {zone} to {to}, split around {C}")
    net = net.resistance(zone, to, R)
    return _declare(net, R, f"resistance from {zone} to the boundary temperature {to}")


def zone_coupling(
    net: RCNetwork,
    a: str = "zon1",
    b: str = "zon2",
    *,
    name: str = "bou",
    capacity: bool = False,
    position: float | str = 0.5,
) -> RCNetwork:
    """Two zones coupled by a boundary: ``R_bou`` [K/W] alone, or split around a wall or floor
    with heat capacity ``C_bou`` [J/K] (initial ``T_bou0`` [°C]).

    Physical meaning: the party wall or floor between two zones. Use ``name`` to tell several
    couplings apart (``name="bou23"``: ``R_bou23``).
    """
    _require_zone(net, b, "zone coupling")
    return boundary(net, a, b, name=name, capacity=capacity, position=position, suffix="")


def ground(
    net: RCNetwork,
    zone: str = "zon",
    to: str | None = "T_gro",
    *,
    name: str = "gro",
    temperature: float | None = None,
    suffix: str | None = None,
) -> RCNetwork:
    """Ground: resistance ``R_gro`` [K/W] from the zone to a ground temperature input ``to``
    [°C], or, with ``to=None``, to a constant ground temperature ``T_gro0`` [°C] (a parameter:
    estimated, or fixed in the fit; ``temperature`` sets its default).

    Physical meaning: the slab on grade and the soil below it.
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "ground")
    R = f"R_{name}{s}"
    if to is None:
        node = f"{name}{s}"
        net = net.constant(node).resistance(zone, node, R)
        fields = {} if temperature is None else {"default": float(temperature)}
        net = _declare(net, f"T_{node}0", "constant ground temperature", **fields)
        to = f"the constant T_{node}0"
    else:
        if temperature is not None:
            raise ModelError(
                f"{net.name}: ground: temperature={temperature!r} is the default of a constant "
                "ground temperature; pass to=None to use one, or drop it"
            )
        net = net.resistance(zone, to, R)
    return _declare(net, R, f"resistance from {zone} to the ground temperature {to}")


def embedded(
    net: RCNetwork,
    zone: str = "zon",
    input: str | None = None,
    *,
    name: str = "emb",
    suffix: str | None = None,
) -> RCNetwork:
    """Embedded emission system: heat capacity ``C_emb`` [J/K] (initial ``T_emb0`` [°C]) that
    receives the heating power ``input`` [W] (``Q_hea`` by default) and releases it to the zone
    air through ``R_emb`` [K/W].

    Physical meaning: floor heating or thermally activated concrete core; also a heater with its
    own thermal mass (``name="hea"``: ``C_hea``, ``R_hea``).
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "embedded system")
    node = f"{name}{s}"
    input = f"Q_hea{s}" if input is None else input
    net = net.node(node).resistance(node, zone, f"R_{node}").heat(node, input)
    net = _declare(net, f"C_{node}", f"heat capacity of the emission system {node} of {zone}")
    return _declare(net, f"R_{node}", f"resistance from the emission system {node} to {zone}")


def _share(net, zone, to, what, s, default_to):
    """Node receiving the non-convective share: ``to``, else the first existing default."""
    if to is not None:
        _require_zone(net, to, what)
        return to
    for cand in default_to:
        if f"{cand}{s}" in _nodes(net):
            return f"{cand}{s}"
    raise ModelError(
        f"{net.name}: {what} is split but no node receives the share; add internal_mass() "
        f"(or a wall) first, or give to='node'"
    )


def _fraction(fra, default: str, s: str):
    if fra is True:
        return f"{default}{s}"
    if isinstance(fra, int | float) and not isinstance(fra, bool):
        if not 0.0 <= float(fra) <= 1.0:
            raise ModelError(f"fraction {fra!r} must lie in [0, 1]")
        return float(fra)
    if not isinstance(fra, str) or not fra.startswith("fra_"):
        raise ModelError(f"fraction {fra!r} must be True, a number in [0, 1] or a name fra_*")
    return fra


def _split_gain(gain: str | None, fra) -> tuple:
    """Gains (rest, share) of a split source; ``gain=None`` for a plain power input."""
    if isinstance(fra, float):
        if gain is None:
            return 1.0 - fra, fra
        return f"{1.0 - fra!r}*{gain}", f"{fra!r}*{gain}"
    if gain is None:
        return f"1-{fra}", fra
    return f"{gain}*1-{fra}", f"{gain}*{fra}"


def window(
    net: RCNetwork,
    input: str = "I_glo_hor",
    zone: str = "zon",
    *,
    name: str | None = None,
    fra: bool | float | str | None = None,
    to: str | None = None,
    suffix: str | None = None,
) -> RCNetwork:
    """Window: solar gains ``gA · input`` [W] from an irradiance ``input`` [W/m²] through a solar
    aperture ``gA_<name>`` [m²] (``gA`` without a name), into the zone air.

    Physical meaning: glazed area times solar transmittance, for one orientation. Declare any
    number of windows: ``window(net, "I_e", name="e")``, ``window(net, "I_w", name="w")``.

    Args:
        fra: split the gains between the zone air and ``to`` (the internal mass by default):
            ``True`` estimates a share ``fra_sol`` [-], a name ``"fra_*"`` estimates that one,
            a number fixes it. The share ``fra`` goes to ``to``, ``1 − fra`` to the zone air.
        to: node receiving the share (default: internal mass ``int``, else the wall).
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, f"window on {input!r}")
    gA = ("gA" if not name else f"gA_{name}") + s
    if any(src.input == input and any(v == gA for _, v in src.gain) for src in net.sources):
        raise ModelError(
            f"{net.name}: duplicate window {gA!r} on {input!r}; give each window its own name"
        )
    text = f"solar aperture of the window{f' {name}' if name else ''} on {input} into {zone}"
    if fra is None:
        net = net.heat(zone, input, gain=gA)
    else:
        fra = _fraction(fra, "fra_sol", s)
        target = _share(net, zone, to, f"window {gA}", s, ("int", "wal"))
        g_zone, g_to = _split_gain(gA, fra)
        net = net.heat(zone, input, gain=g_zone).heat(target, input, gain=g_to)
        if isinstance(fra, str):
            net = _declare(net, fra, f"share of the solar gains absorbed by {target}")
    return _declare(net, gA, text)


def heating(
    net: RCNetwork,
    input: str | None = None,
    zone: str = "zon",
    *,
    fra_rad: bool | float | str | None = None,
    to: str | None = None,
    suffix: str | None = None,
) -> RCNetwork:
    """Heating: the power ``input`` [W] (``Q_hea``, ``Q_hea1``… by default) into the zone air;
    with ``fra_rad``, its radiative share goes to ``to`` (the internal mass, else the wall) and
    the rest to the zone air.

    Physical meaning: radiators, convectors, electric heaters: the convective part warms the air
    at once, the radiative part the surfaces around.

    Args:
        fra_rad: ``True`` estimates ``fra_rad`` [-], a name ``"fra_*"`` estimates that one, a
            number fixes it.
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "heating")
    input = f"Q_hea{s}" if input is None else input
    if fra_rad is None:
        return net.heat(zone, input)
    fra = _fraction(fra_rad, "fra_rad", s)
    target = _share(net, zone, to, "heating", s, ("int", "wal"))
    g_zone, g_to = _split_gain(None, fra)
    net = net.heat(zone, input, gain=g_zone).heat(target, input, gain=g_to)
    if isinstance(fra, str):
        net = _declare(net, fra, f"radiative share of {input}, released to {target}")
    return net


def electric_gains(
    net: RCNetwork,
    input: str = "P_ele",
    zone: str = "zon",
    *,
    fra: float | str = "fra_ele",
    suffix: str | None = None,
) -> RCNetwork:
    """Internal gains from electricity use: ``fra_ele · P_ele`` [W] into the zone air.

    Physical meaning: appliances and lighting release their electricity as heat; ``fra_ele``
    [-] may exceed 1 (bounds [0, 3]) because occupants' body heat follows their electricity use.
    A number fixes the fraction.
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "electric gains")
    if isinstance(fra, str):
        fra = fra if _DIGITS.fullmatch(fra) or not s else f"{fra}{s}"
        net = net.heat(zone, input, gain=fra)
        return _declare(net, fra, f"share of {input} released as internal gains in {zone}")
    return net.heat(zone, input, gain=float(fra))


def sensor(
    net: RCNetwork, zone: str = "zon", *, name: str = "sen", suffix: str | None = None
) -> RCNetwork:
    """Temperature sensor with its own dynamics: heat capacity ``C_sen`` [J/K] (initial
    ``T_sen0`` [°C]) linked to the zone air by ``R_sen`` [K/W]; the zone's output (``T_zon``)
    is measured on the sensor node instead of the zone air.

    Physical meaning: a sensor with thermal mass, or mounted on a surface, lagging the air.
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "sensor")
    node = f"{name}{s}"
    zone_node = next(n for n in net.nodes if n.name == zone)
    if not zone_node.output:
        raise ModelError(f"{net.name}: sensor: zone {zone!r} is not measured; nothing to move")
    output = zone_node.output
    nodes = tuple(dataclasses.replace(n, output=None) if n.name == zone else n for n in net.nodes)
    net = dataclasses.replace(net, nodes=nodes)
    net = net.node(node, output=output).resistance(zone, node, f"R_{node}")
    net = _declare(net, f"C_{node}", f"heat capacity of the sensor measuring {output}")
    return _declare(net, f"R_{node}", f"resistance between the air of {zone} and its sensor")


def sensor_offset(net: RCNetwork, zone: str = "zon", *, suffix: str | None = None) -> RCNetwork:
    """A constant offset of the zone's temperature sensor, as a constant heat input ``Q_off``
    [W] (signed, bounds ±1e4 W) into the zone air, through the virtual input ``"one"``
    (:data:`jaxbox.data.CONSTANT`, 1 at every sample).

    Physical meaning: a sensor that reads ``d`` kelvin too high or too low at every sample. A
    constant heat input ``Q`` into the zone shifts every state of the network by its steady-state
    response, and the zone's temperature by ``d = G·Q`` with ``G`` [K/W] the zone's temperature
    rise per watt; with the initial states free, the model with ``Q_off`` gives exactly the
    outputs of the model without it plus the offset ``d``. The same input also stands for a
    constant internal gain: the data cannot tell a base load from an offset.
    """
    s = _suffix(zone, suffix)
    _require_zone(net, zone, "sensor offset")
    name = f"Q_off{s}"
    net = net.heat(zone, CONSTANT, gain=name)
    return _declare(
        net, name, f"constant heat input into {zone}: a sensor offset, or a constant base load"
    )
