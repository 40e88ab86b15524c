"""The component grammar: model structures as words of components, and how they grow.

A :class:`Structure` is a set of component tokens, written as a name that reads back into the
same structure (``"Zon+Wal+Int+Inf+Bou"``). Every structure is a zone (or two) with an envelope
resistance to the ambient ``T_amb``, its heating ``Q_hea`` and, where the data have the global
horizontal irradiance, a solar aperture ``gA``; each token adds one component of
:mod:`~jaxbox.models.components`:

========== ============================================= =========================================
token      component                                     needs
========== ============================================= =========================================
``Wal``    envelope capacity ``C_wal`` (R_wal in halves)
``Int``    internal mass ``C_int``, ``R_int``
``Inf``    infiltration ``R_inf`` parallel to the wall   ``Wal``
``Bou``    boundary ``R_bou`` to the column ``T_bou``    a temperature column ``T_bou``
``BouC``   the same, split around ``C_bou``              ``Bou`` (it replaces it)
``Hea``    heater with its own capacity ``C_hea``        a heating column
``Rad``    radiative heating share ``fra_rad`` to C_int  ``Int``, a heating column, not ``Hea``
``WinSEW`` one aperture per facade (``gA_s``…)           facade irradiances ``I_s``, ``I_e``…
``Sol``    solar share ``fra_sol`` to the mass           ``Int`` or ``Wal``, solar gains
``Ae``     solar gains on the envelope ``gA_wal``        ``Wal``, ``I_glo_hor``
``Ele``    internal gains ``fra_ele · P_ele``            a column ``P_ele``
``Cpl``    two zones coupled by ``R_bou``                two zones as states
``CplC``   the coupling split around ``C_bou``           ``Cpl`` (it replaces it)
``Bz2``    zone 2's measured temperature as a boundary   a column ``T_zon2``
``Off``    a constant sensor offset, as the constant
           heat input ``Q_off`` into the zone
========== ============================================= =========================================

Boundaries are named after their column: ``T_cel`` gives ``Cel``/``CelC`` (``R_cel``,
``C_cel``), ``T_gro`` gives ``Gro``/``GroC``. With two zones (columns ``T_zon1``, ``T_zon2``)
every zone token carries its zone's number (``Wal1``, ``Int2``) and the structure either models
both zones as states (``Zon1+Zon2+Cpl``) or one of them as a measured boundary input of the other
(``Zon1+Bz2``: a zone held by its thermostat behaves as such a boundary).

:func:`extensions` lists the one-component extensions of a structure that the data can drive;
:func:`roots` the simplest structures; :func:`random_structure` draws one (the test-building
generator uses it). Names are canonical: the same structure always has the same name, so
:func:`~jaxbox.models.get_model` reads them too.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable

import numpy as np

from . import _components as c
from ._network import RCModel, RCNetwork
from ._parameters import ModelError

__all__ = [
    "Structure",
    "Grammar",
    "extensions",
    "reductions",
    "roots",
    "random_structure",
    "parse_structure",
    "is_structure_name",
    "is_boundary_token",
]

#: facade irradiance columns and their window letters
FACADES = {"I_s": "S", "I_e": "E", "I_w": "W", "I_n": "N"}
_FACADE_OF = {v: k for k, v in FACADES.items()}
#: temperature columns that are never boundaries
_NOT_BOUNDARY = re.compile(r"T_(amb|zon\d*|wal|int|inf|hea|rad|sol|ae|ele|cpl|win\w*|bz)$")
#: per-zone tokens in canonical order (boundaries come after Inf, in column order)
_ORDER = ("Wal", "Int", "Inf", "<bou>", "Hea", "Rad", "Win", "Sol", "Ae", "Ele", "Off")
_ZONE_TOKEN = re.compile(r"(Zon|Wal|Int|Inf|Hea|Rad|Sol|Ae|Ele|Off|Win[SEWN]+|[A-Z][a-z]+C?)(\d?)")


def _boundary_token(column: str) -> str:
    return column[2:].capitalize()


@dataclasses.dataclass(frozen=True)
class Grammar:
    """What the data can drive.

    Attributes:
        zones: measured zone numbers: ``(0,)`` for one zone ``T_zon``, ``(1, 2)`` for ``T_zon1``
            and ``T_zon2``.
        boundaries: measured boundary temperature columns (``T_bou``, ``T_cel``…), in order.
        facades: facade irradiance columns (``I_s``, ``I_e``…).
        horizontal: the data have ``I_glo_hor``.
        heating: zone number -> its heating column (``Q_hea``, ``Q_hea1``…).
        electric: the data have ``P_ele``.
        offsets: a measured zone may have a constant sensor offset (``Off``).
    """

    zones: tuple[int, ...]
    boundaries: tuple[str, ...] = ()
    facades: tuple[str, ...] = ()
    horizontal: bool = True
    heating: tuple[tuple[int, str], ...] = ()
    electric: bool = False
    offsets: bool = True

    @classmethod
    def from_columns(cls, columns: Iterable[str]) -> Grammar:
        """The grammar of data with these canonical column names.

        Raises:
            ModelError: no zone temperature, no ``T_amb``, or more than two zones.
        """
        cols = list(columns)
        if "T_amb" not in cols:
            raise ModelError("a structure search needs the ambient temperature column T_amb")
        numbered = sorted(int(m[1]) for x in cols if (m := re.fullmatch(r"T_zon(\d+)", x)))
        if "T_zon" in cols:
            zones: tuple[int, ...] = (0,)
        elif numbered:
            zones = tuple(numbered)
        else:
            raise ModelError(
                "a structure search needs a zone temperature column T_zon (or T_zon1, T_zon2)"
            )
        if len(zones) > 2:
            raise ModelError(
                f"the structure search models one or two zones; the data have {len(zones)} "
                "(T_zon1…); choose the models with --models / candidates="
            )
        heating = tuple(
            (z, col) for z in zones if (col := "Q_hea" if z == 0 else f"Q_hea{z}") in cols
        )
        return cls(
            zones=zones,
            boundaries=tuple(
                x for x in cols if re.fullmatch(r"T_[a-z]+", x) and not _NOT_BOUNDARY.match(x)
            ),
            facades=tuple(f for f in FACADES if f in cols and f != "I_n"),
            horizontal="I_glo_hor" in cols,
            heating=heating,
            electric="P_ele" in cols,
        )

    def heat_column(self, zone: int) -> str | None:
        return dict(self.heating).get(zone)


@dataclasses.dataclass(frozen=True)
class Structure:
    """A model structure: zones as states, zones as boundaries, and component tokens.

    Attributes:
        states: zone numbers modelled as states (``(0,)`` for the single zone).
        tokens: per-zone component tokens as ``(zone, token)`` pairs, and structure tokens
            (``Cpl``, ``CplC``) with zone ``-1``.
        bound_zones: zone numbers whose measured temperature is a boundary input.
    """

    states: tuple[int, ...] = (0,)
    tokens: frozenset = frozenset()
    bound_zones: tuple[int, ...] = ()

    # ---- naming ---------------------------------------------------------------------------------
    def zone_tokens(self, zone: int) -> list[str]:
        return [t for z, t in self.tokens if z == zone]

    def has(self, zone: int, token: str) -> bool:
        return (zone, token) in self.tokens

    def window(self, zone: int) -> str | None:
        return next((t for t in self.zone_tokens(zone) if t.startswith("Win")), None)

    @property
    def name(self) -> str:
        """The canonical name (``Zon+Wal+Int``; two zones ``Zon1+Zon2+Wal1+Cpl``)."""
        words = []
        for z in self.states:
            words.append("Zon" if z == 0 else f"Zon{z}")
        for z in self.states:
            suffix = "" if z == 0 else str(z)
            for t in sorted(self.zone_tokens(z), key=_rank):
                words.append(t + suffix)
        words += sorted(t for z, t in self.tokens if z == -1)
        words += [f"Bz{z}" for z in self.bound_zones]
        return "+".join(words)

    def __str__(self) -> str:
        return self.name

    # ---- building -------------------------------------------------------------------------------
    def network(self, grammar: Grammar | None = None) -> RCNetwork:
        """The RC network of this structure (``grammar`` gives the heating columns; by default
        ``Q_hea`` / ``Q_hea1``… for every zone)."""
        net = RCNetwork(self.name, self.describe())
        zone_names = {z: "zon" if z == 0 else f"zon{z}" for z in self.states}
        for z in self.states:
            zn, tok = zone_names[z], set(self.zone_tokens(z))
            net = c.zone(net, zn)
            net = c.wall(net, zn, capacity="Wal" in tok)
            if "Int" in tok:
                net = c.internal_mass(net, zn)
            if "Inf" in tok:
                net = c.infiltration(net, zn)
            for t in sorted(tok, key=_rank):
                if is_boundary_token(t):
                    base = t[:-1] if t.endswith("C") else t
                    net = c.boundary(
                        net, zn, to=f"T_{base.lower()}", name=base.lower(), capacity=t.endswith("C")
                    )
            heat = f"Q_hea{'' if z == 0 else z}"
            if grammar is not None:
                heat = grammar.heat_column(z)
            if heat is not None:
                if "Hea" in tok:
                    net = c.embedded(net, zn, heat, name="hea")
                else:
                    net = c.heating(net, heat, zn, fra_rad=True if "Rad" in tok else None)
            fra = True if "Sol" in tok else None
            win = self.window(z)
            if win is not None:
                for letter in win[3:]:
                    net = c.window(net, _FACADE_OF[letter], zn, name=letter.lower(), fra=fra)
            elif grammar is None or grammar.horizontal:
                net = c.window(net, "I_glo_hor", zn, fra=fra)
            if "Ae" in tok:
                net = c.window(net, "I_glo_hor", f"wal{'' if z == 0 else z}", name="wal")
            if "Ele" in tok:
                net = c.electric_gains(net, zone=zn)
            if "Off" in tok:
                net = c.sensor_offset(net, zn)
        cpl = [t for z, t in self.tokens if z == -1]
        if len(self.states) == 2 and cpl:
            a, b = (zone_names[z] for z in self.states)
            net = c.zone_coupling(net, a, b, capacity=cpl[0] == "CplC")
        for zb in self.bound_zones:
            for z in self.states:
                net = c.boundary(net, zone_names[z], to=f"T_zon{zb}", name="bou", suffix="")
        return net

    def build(self, grammar: Grammar | None = None) -> RCModel:
        """The :class:`RCModel` of this structure."""
        return self.network(grammar).build()

    def describe(self) -> str:
        parts = []
        for z in self.states:
            where = "the zone" if z == 0 else f"zone {z}"
            tok = self.zone_tokens(z)
            words = [
                _WORDS.get(t[:-1] if t.endswith("C") and t not in _WORDS else t, t)
                for t in sorted(tok, key=_rank)
            ]
            parts.append(f"{where}: air, envelope" + "".join(f", {w}" for w in words))
        if any(z == -1 for z, _ in self.tokens):
            parts.append("zones coupled")
        for zb in self.bound_zones:
            parts.append(f"zone {zb} as a measured boundary")
        return "structure from the component grammar; " + "; ".join(parts)


_WORDS = {
    "Wal": "envelope capacity",
    "Int": "internal mass",
    "Inf": "infiltration",
    "Hea": "heater capacity",
    "Rad": "radiative heating share",
    "Sol": "solar share to the mass",
    "Ae": "solar gains on the envelope",
    "Ele": "electric gains",
    "Off": "sensor offset",
}


def _rank(token: str) -> tuple[int, str]:
    base = "Win" if token.startswith("Win") else token
    if base in _ORDER:
        return (_ORDER.index(base), token)
    return (_ORDER.index("<bou>"), token)


def is_boundary_token(token: str) -> bool:
    """Whether a zone token is a boundary to a measured temperature (``Bou``, ``CelC``…)."""
    return _rank(token)[0] == _ORDER.index("<bou>")


# ---- parsing ------------------------------------------------------------------------------------


def is_structure_name(name: str) -> bool:
    """Whether ``name`` is written in the grammar (``Zon+…``, or ``Zon1+…``)."""
    return isinstance(name, str) and re.fullmatch(r"Zon\d?(\+[A-Za-z]+\d?)*", name) is not None


def parse_structure(name: str) -> Structure:
    """The structure a canonical name spells (``"Zon+Wal+Int"``, ``"Zon1+Zon2+Wal1+Cpl"``).

    Raises:
        ModelError: a word is not a grammar token.
    """
    if not is_structure_name(name):
        raise ModelError(f"{name!r} is not a structure name (words joined by '+', from 'Zon')")
    states: list[int] = []
    bound: list[int] = []
    tokens = set()
    for word in name.split("+"):
        if m := re.fullmatch(r"Zon(\d?)", word):
            states.append(int(m[1] or 0))
        elif m := re.fullmatch(r"Bz(\d)", word):
            bound.append(int(m[1]))
        elif word in ("Cpl", "CplC"):
            tokens.add((-1, word))
        elif m := _ZONE_TOKEN.fullmatch(word):
            tokens.add((int(m[2] or 0), m[1]))
        else:
            raise ModelError(f"{name!r}: {word!r} is not a grammar token")
    if not states or len(set(states)) != len(states):
        raise ModelError(f"{name!r}: each zone state 'Zon'/'Zon1'… once, at least one")
    for z, t in tokens:
        if z not in (-1, *states):
            raise ModelError(f"{name!r}: {t}{z} belongs to a zone that is not a state")
    s = Structure(tuple(sorted(states)), frozenset(tokens), tuple(sorted(bound)))
    if s.name != name:
        raise ModelError(f"{name!r} is not in canonical order; write it {s.name!r}")
    return s


# ---- growth -------------------------------------------------------------------------------------


def roots(grammar: Grammar) -> list[Structure]:
    """The simplest structures: one zone; with two zones, both as states coupled (``Cpl``) and
    each one alone with the other as a measured boundary (``Bz``)."""
    if grammar.zones == (0,):
        return [Structure((0,))]
    a, b = grammar.zones
    return [
        Structure((a, b), frozenset({(-1, "Cpl")})),
        Structure((a,), frozenset(), (b,)),
        Structure((b,), frozenset(), (a,)),
    ]


#: what a zone's component needs among the zone's other components (to be added; to stay when
#: another is removed)
_NEEDS = {
    "Inf": lambda tok: "Wal" in tok,
    "Ae": lambda tok: "Wal" in tok,
    "Rad": lambda tok: "Int" in tok and "Hea" not in tok,
    "Sol": lambda tok: "Int" in tok or "Wal" in tok,
}


def _zone_extensions(
    s: Structure, z: int, g: Grammar, swaps: bool = True
) -> list[tuple[str, frozenset]]:
    tok = set(s.zone_tokens(z))
    heat = g.heat_column(z) is not None
    solar = g.horizontal or bool(g.facades)
    out = []

    def add(label, new, drop=None):
        t = set(s.tokens)
        if drop is not None:
            t.discard((z, drop))
        t.add((z, new))
        out.append((label, frozenset(t)))

    if "Wal" not in tok:
        add("envelope capacity", "Wal")
    if "Int" not in tok:
        add("internal mass", "Int")
    if "Inf" not in tok and _NEEDS["Inf"](tok):
        add("infiltration", "Inf")
    for col in g.boundaries:
        b = _boundary_token(col)
        if b not in tok and b + "C" not in tok:
            add(f"boundary to {col}", b)
        elif b in tok:
            add(f"capacity on the boundary to {col}", b + "C", drop=b)
    if heat and "Hea" not in tok and "Rad" not in tok:
        add("heater capacity", "Hea")
    if heat and "Rad" not in tok and _NEEDS["Rad"](tok):
        add("radiative heating share", "Rad")
    if swaps and heat and "Int" in tok and "Hea" in tok:  # two accounts of a heating's lag
        add("radiative heating share instead of the heater capacity", "Rad", drop="Hea")
    if g.facades and s.window(z) is None:
        add("facade windows", "Win" + "".join(FACADES[f] for f in g.facades))
    if solar and "Sol" not in tok and _NEEDS["Sol"](tok):
        add("solar share to the mass", "Sol")
    if g.horizontal and "Ae" not in tok and _NEEDS["Ae"](tok):
        add("solar gains on the envelope", "Ae")
    if g.electric and "Ele" not in tok:
        add("electric gains", "Ele")
    if g.offsets and "Off" not in tok:
        add("sensor offset", "Off")
    return out


def extensions(
    structure: Structure, grammar: Grammar, *, swaps: bool = True
) -> list[tuple[str, Structure]]:
    """The one-component extensions of ``structure`` that the data can drive, as
    ``(what was added, new structure)``, in a fixed order. With ``swaps``, also the moves that
    trade one component for another of the same role (a radiative heating share in place of a
    heater capacity: two accounts of the heating's lag)."""
    out = []
    for z in structure.states:
        where = "" if z == 0 else f" (zone {z})"
        for label, tokens in _zone_extensions(structure, z, grammar, swaps):
            out.append((label + where, dataclasses.replace(structure, tokens=tokens)))
    if structure.has(-1, "Cpl"):
        t = (set(structure.tokens) - {(-1, "Cpl")}) | {(-1, "CplC")}
        grown = dataclasses.replace(structure, tokens=frozenset(t))
        out.append(("capacity on the coupling", grown))
    return out


def reductions(structure: Structure, grammar: Grammar) -> list[tuple[str, Structure]]:
    """The structures one component smaller than ``structure``, as ``(what was removed, new
    structure)``, in a fixed order: a component removed when no other one needs it
    (infiltration and envelope solar gains need the envelope capacity, a radiative heating share
    the internal mass, a solar share to the mass a mass), a capacity on a boundary or on the
    coupling removed from it. The zones, their coupling and the boundaries of measured zones
    stay."""
    del grammar  # (the same for every grammar: a smaller structure drives no new column)
    out = []
    for z, token in sorted(structure.tokens):
        if z == -1:
            if token == "CplC":
                t = (structure.tokens - {(z, token)}) | {(z, "Cpl")}
                out.append(("without the capacity on the coupling", t))
            continue
        where = "" if z == 0 else f" (zone {z})"
        if is_boundary_token(token) and token.endswith("C"):
            t = (structure.tokens - {(z, token)}) | {(z, token[:-1])}
            what = f"without the capacity on the boundary to T_{token[:-1].lower()}{where}"
            out.append((what, t))
            continue
        rest = {t for zz, t in structure.tokens if zz == z} - {token}
        if any(not _NEEDS[t](rest) for t in rest if t in _NEEDS):
            continue
        label = "facade windows" if token.startswith("Win") else _WORDS.get(token)
        label = label or f"boundary to T_{token.lower()}"
        out.append((f"without the {label}{where}", structure.tokens - {(z, token)}))
    return [(what, dataclasses.replace(structure, tokens=frozenset(t))) for what, t in out]


def random_structure(
    grammar: Grammar, rng: np.random.Generator, size: int | None = None
) -> Structure:
    """A random structure of the grammar: a root grown by ``size`` random extensions (drawn
    from 0 to 4 when not given). A sensor offset is not a component of the building: it is
    never drawn (the test-building generator adds offsets to the measurements)."""
    grammar = dataclasses.replace(grammar, offsets=False)
    options = roots(grammar)
    s = options[int(rng.integers(len(options)))] if grammar.zones != (0,) else options[0]
    n = int(rng.integers(0, 5)) if size is None else int(size)
    for _ in range(n):
        ext = extensions(s, grammar, swaps=False)  # (the zoo's structures stay as drawn)
        if not ext:
            break
        s = ext[int(rng.integers(len(ext)))][1]
    return s
