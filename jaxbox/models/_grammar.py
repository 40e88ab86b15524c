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
``BouC``   the same, split around ``C_bou``              replaces ``Bou`` (never both)
``Hea``    heater with its own capacity ``C_hea``        a heating column
``Rad``    radiative heating share ``fra_rad`` to C_int  ``Int``, a heating column, not ``Hea``
``WinSEW`` one aperture per facade (``gA_s``…)           facade irradiances ``I_s``, ``I_e``…
``Sol``    solar share ``fra_sol`` to the mass           ``Int`` or ``Wal``, solar gains
``Ae``     solar gains on the envelope ``gA_wal``        ``Wal``, ``I_glo_hor``
``Ele``    internal gains ``fra_ele · P_ele``            a column ``P_ele``
``Cpl``    two zones coupled by ``R_bou``                two zones as states
``CplC``   the coupling split around ``C_bou``           replaces ``Cpl`` (never both)
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

A name is checked as it is read, and so is a :class:`Structure` built by hand; each refusal is a
:class:`~jaxbox.models.ModelError` naming the word and the fix:

- each word once, in canonical order: the zones, each zone's tokens in the order of the table
  (boundaries in column order after ``Inf``), then ``Cpl``/``CplC``, then ``Bz``;
- a capacity variant replaces its plain token: ``BouC`` replaces ``Bou`` (``CelC`` ``Cel``) and
  ``CplC`` replaces ``Cpl``; a name with both is refused (it would declare the boundary twice);
- ``Cpl`` and ``CplC`` couple two zones as states (``Zon1+Zon2+Cpl``); ``Bz1``/``Bz2`` hold a
  numbered zone that is not a state; one zone ``Zon`` or numbered zones, two at most;
- the needs in the table among a zone's own tokens hold (``Zon+Inf``: infiltration needs
  ``Wal``); the needs on data columns are checked when a grammar builds the structure
  (:meth:`Structure.network`: ``Hea`` without a heating column is refused, not dropped);
- one window token per zone, each facade once, in the order S, E, W, N (``WinSE``);
- any other word is refused with the list of tokens and the nearest one (``Wall``: did you mean
  ``Wal``?). A boundary word reads as its column (``Cel`` is ``T_cel``) unless that column is
  reserved (``T_amb``, ``T_zon``…, or a component's name: ``Amb``, ``WalC`` are refused) or the
  word reads like a typo of a token (``Wall``, ``Zone``, ``Heat``, ``Bouc``);
  :meth:`Grammar.from_columns` refuses such a boundary column likewise.
"""

from __future__ import annotations

import dataclasses
import difflib
import operator
import re
from collections.abc import Iterable

import numpy as np

from ..data._errors import list_names
from ..data._suggest import suggestion_text
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
#: temperature columns that are never boundaries: the ambient, the zones, the tokens' own names
_NOT_BOUNDARY = re.compile(r"T_(amb\w*|zon\d*|wal|int|inf|hea|rad|sol|ae|ele|off|cpl|win\w*|bz)$")
#: a boundary column and its boundary word (``T_cel`` -> ``Cel``)
_BOUNDARY_COLUMN = re.compile(r"T_[a-z]{2,}")
#: per-zone tokens in canonical order (boundaries come after Inf, in column order)
_ORDER = ("Wal", "Int", "Inf", "<bou>", "Hea", "Rad", "Win", "Sol", "Ae", "Ele", "Off")
#: the per-zone component tokens (besides the windows ``Win…`` and the boundaries)
_COMPONENTS = ("Wal", "Int", "Inf", "Hea", "Rad", "Sol", "Ae", "Ele", "Off")
#: a word of a name: letters, then the zone number (``Wal1``)
_WORD = re.compile(r"([A-Za-z]+)(\d?)")
#: what a mistyped word may have meant (lower case -> as written); ``Bou`` is a boundary word
#: like any other, listed for its own typos (``Bouc``)
_SPELLING = {w.lower(): w for w in ("Zon", *_COMPONENTS, "Win", "Bou", "BouC", "Cpl", "CplC", "Bz")}
#: words that carry no zone number
_NOT_PER_ZONE = ("Zon", "Cpl", "CplC", "Bz", "Bz1")
#: a boundary word at least this close to a token (difflib ratio) reads as a typo of it: a
#: letter more (``Wall``, ``Zone``) is 0.86, two more (``Solar``) 0.75, one letter off in three
#: (``Cel`` and ``Ele``) 0.67
_TYPO = 0.75
_TOKENS = (
    "the words are the zones Zon (one zone, column T_zon) or Zon1, Zon2 (columns T_zon1, "
    "T_zon2); per zone Wal, Int, Inf, Hea, Rad, Sol, Ae, Ele, Off and Win with its facades "
    "(WinSE), numbered with two zones (Wal1); Cpl or CplC (two zone states coupled); Bz1, Bz2 "
    "(a zone held as a measured boundary); and a boundary named after its temperature column "
    "(Bou for T_bou, Cel for T_cel; BouC, CelC with a capacity)"
)


def _boundary_token(column: str) -> str:
    return column[2:].capitalize()


def _nearest(word: str, cutoff: float = 0.6) -> str | None:
    """The token ``word`` most likely stands for (case aside), if any is close."""
    hit = difflib.get_close_matches(word.lower(), _SPELLING, n=1, cutoff=cutoff)
    return _SPELLING[hit[0]] if hit else None


def _token_problem(token: str) -> tuple[str, str | None] | None:
    """Why ``token`` (a per-zone word without its zone number) is no token, and the word meant
    (``None``: a component, a window or a boundary name)."""
    if token in _COMPONENTS:
        return None
    if m := re.fullmatch(r"Win([SEWN]+)", token):
        canon = "".join(x for x in "SEWN" if x in m[1])
        if m[1] == canon:
            return None
        return "a window names each facade once, in the order S, E, W, N", f"Win{canon}"
    parts = re.findall(r"[A-Z][a-z]*", token)
    if len(parts) > 1 and "".join(parts) == token and all(_token_problem(p) is None for p in parts):
        return "words are joined by '+'", "+".join(parts)
    m = re.fullmatch(r"([A-Z][a-z]+)(C?)", token)
    if m is None:
        return "", _nearest(token)
    base = m[1]
    if _NOT_BOUNDARY.match(f"T_{base.lower()}"):
        low = base.lower()
        if low.startswith("amb"):
            why = "the ambient T_amb is in every structure, the envelope runs to it"
            return why + "; drop the word", None
        if low.startswith("win"):
            return "a window is Win and its facades S, E, W, N: WinSE", _nearest(token)
        if low == "cpl":
            return "the coupling of two zone states is Cpl or CplC, with no zone number", "Cpl"
        if low.startswith("zon"):
            return "a zone is a word of its own: Zon, Zon1, Zon2", None
        if low == "bz":
            return "a zone held as a measured boundary is Bz and its number: Bz1, Bz2", "Bz1"
        if m[2]:
            return "only a boundary or the coupling has a capacity variant: BouC, CplC", base
        return "", _nearest(token)
    meant = _nearest(base, _TYPO)
    if meant and base != "Bou":
        why = f"a boundary to a column T_{base.lower()} would read like a typo of {meant}"
        return why, meant
    return None


def _typo_column(column: str) -> str | None:
    """Why the boundary column ``column`` is refused (its word reads as a typo), if it is."""
    word = _boundary_token(column)
    problem = _token_problem(word)
    if problem is None:
        return None
    return (
        f"column {column} would be a boundary {word!r}, which reads like a typo of the token "
        f"{problem[1]!r}; rename the column (boundary columns are T_ and a name of two or more "
        "letters unlike the tokens: T_bou, T_cel, T_gro) or drop it"
    )


def _require_search_columns(cols: list[str], zone: bool) -> None:
    """Raise :class:`ModelError` naming every signal a structure search cannot go without
    (``T_amb``; a zone temperature ``T_zon``, or ``T_zon1``/``T_zon2``) that ``cols`` lack,
    with the columns there are and how to map them."""
    missing = [name for name, ok in (("T_amb", "T_amb" in cols), ("T_zon", zone)) if not ok]
    if not missing:
        return
    what = {"T_amb": "the ambient temperature T_amb", "T_zon": "a zone temperature T_zon"}
    needs = " and ".join(what[m] for m in missing)
    if "T_zon" in missing:
        needs += " (or T_zon1, T_zon2 for two zones)"
    close = [
        match
        for name in missing
        for match in difflib.get_close_matches(name, cols, n=1, cutoff=0.7)
    ]
    hint = f" (did you mean {list_names(close)}?)" if close else ""
    mapping = ", ".join(f"{name!r}: 'your_col'" for name in missing)
    # the heating and the sun too: a search that finds only the temperatures fits no heat
    guess = suggestion_text(missing, cols, also=("Q_hea", "I_glo_hor"))
    raise ModelError(
        f"a structure search needs {needs}{hint}; the data have {list_names(cols)}; map yours with "
        f"columns={{{mapping}}} in jaxbox.data.load{guess}"
    )


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
        scale: the building's size against the naming defaults': every structure's
            resistances, capacities, constant heat inputs and solar apertures (their defaults
            and bounds) are those of a building ``scale`` times as large
            (:func:`~jaxbox.models.scaled_parameter`). ``None`` (the default) builds them
            unscaled; the structure search sets it from its data (the data's heat input per
            kelvin of zone-ambient difference over :data:`~jaxbox.models.REFERENCE_HLC`, at
            least 1), so that a school or an office block is searched as a house is.
    """

    zones: tuple[int, ...]
    boundaries: tuple[str, ...] = ()
    facades: tuple[str, ...] = ()
    horizontal: bool = True
    heating: tuple[tuple[int, str], ...] = ()
    electric: bool = False
    offsets: bool = True
    scale: float | None = None

    @classmethod
    def from_columns(cls, columns: Iterable[str]) -> Grammar:
        """The grammar of data with these canonical column names.

        Every column ``T_`` and a lower-case name of two or more letters that the grammar does
        not reserve (``T_amb``, ``T_zon``…, the tokens' own names ``T_wal``…) is a boundary.

        Raises:
            ModelError: no zone temperature, no ``T_amb``, more than two zones, or a boundary
                column whose word reads like a typo of a token (``T_wall``: ``Wall``).
        """
        cols = list(columns)
        numbered = sorted(int(m[1]) for x in cols if (m := re.fullmatch(r"T_zon(\d+)", x)))
        _require_search_columns(cols, zone="T_zon" in cols or bool(numbered))
        zones: tuple[int, ...] = (0,) if "T_zon" in cols else tuple(numbered)
        if len(zones) > 2:
            raise ModelError(
                f"the structure search models one or two zones; the data have {len(zones)} "
                "(T_zon1…); choose the models with --models / candidates="
            )
        heating = tuple(
            (z, col) for z in zones if (col := "Q_hea" if z == 0 else f"Q_hea{z}") in cols
        )
        boundaries = tuple(
            x for x in cols if _BOUNDARY_COLUMN.fullmatch(x) and not _NOT_BOUNDARY.match(x)
        )
        for x in boundaries:
            if (why := _typo_column(x)) is not None:
                raise ModelError(f"a structure search reads boundary columns: {why}")
        return cls(
            zones=zones,
            boundaries=boundaries,
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
        states: zone numbers modelled as states (``(0,)`` for the single zone), in order.
        tokens: per-zone component tokens as ``(zone, token)`` pairs, and structure tokens
            (``Cpl``, ``CplC``) with zone ``-1``.
        bound_zones: zone numbers whose measured temperature is a boundary input, in order.

    Raises:
        ModelError: the fields do not spell a structure of the grammar (the rules of
            :mod:`~jaxbox.models.grammar`: ``Cpl`` with one zone state, ``Bou`` with ``BouC``,
            ``Inf`` without ``Wal``, a word that is no token…).
    """

    states: tuple[int, ...] = (0,)
    tokens: frozenset = frozenset()
    bound_zones: tuple[int, ...] = ()

    def __post_init__(self):
        for field in ("states", "bound_zones"):
            value = getattr(self, field)
            try:
                if isinstance(value, str | bytes) or any(isinstance(z, bool) for z in value):
                    raise TypeError
                zones = tuple(sorted(operator.index(z) for z in value))
            except TypeError:
                raise ModelError(
                    f"Structure {field} are zone numbers (0: the one zone T_zon; 1, 2: T_zon1, "
                    f"T_zon2), got {value!r}"
                ) from None
            object.__setattr__(self, field, zones)
        pairs = self.tokens
        try:
            ok = not isinstance(pairs, str | bytes) and all(
                isinstance(p, tuple)
                and len(p) == 2
                and isinstance(p[0], int)
                and not isinstance(p[0], bool)
                and isinstance(p[1], str)
                for p in pairs
            )
        except TypeError:  # (not iterable)
            ok = False
        if not ok:
            raise ModelError(
                "Structure tokens are (zone, token) pairs such as (0, 'Wal'), (1, 'Int') or "
                f"(-1, 'Cpl'), got {pairs!r}"
            )
        object.__setattr__(self, "tokens", frozenset(pairs))
        if (why := _problem(self.states, self.tokens, self.bound_zones)) is not None:
            raise ModelError(f"structure {self.name!r}: {why}")

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
        return _spell(self.states, self.tokens, self.bound_zones)

    def __str__(self) -> str:
        return self.name

    # ---- building -------------------------------------------------------------------------------
    def network(self, grammar: Grammar | None = None) -> RCNetwork:
        """The RC network of this structure (``grammar`` gives the heating columns; by default
        ``Q_hea`` / ``Q_hea1``… for every zone).

        Raises:
            ModelError: with ``grammar``, a zone that is not one of its zones, or a component
                whose column the grammar lacks and that the network would otherwise drop
                (``Hea``, ``Rad`` without the zone's heating column, ``Sol`` without any solar
                input).
        """
        if grammar is not None and (why := _grammar_problem(self, grammar)) is not None:
            raise ModelError(f"structure {self.name!r}: {why}")
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
        cpl = [t for z, t in self.tokens if z == -1]  # (one at most, two zone states)
        if cpl:
            a, b = (zone_names[z] for z in self.states)
            net = c.zone_coupling(net, a, b, capacity=cpl == ["CplC"])
        for zb in self.bound_zones:
            for z in self.states:
                net = c.boundary(net, zone_names[z], to=f"T_zon{zb}", name="bou", suffix="")
        return net

    def build(self, grammar: Grammar | None = None) -> RCModel:
        """The :class:`RCModel` of this structure (scaled by ``grammar.scale``, see
        :class:`Grammar`)."""
        model = self.network(grammar).build()
        s = None if grammar is None else grammar.scale
        return model if s is None else model.scaled(s)

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


# ---- the rules of a structure -------------------------------------------------------------------


def _spell(states, tokens, bound) -> str:
    """The canonical name of these fields (checked or not)."""
    words = [_zone_word(z) for z in states]
    for z in states:
        suffix = "" if z == 0 else str(z)
        words += [t + suffix for t in sorted((t for zz, t in tokens if zz == z), key=_rank)]
    words += sorted(t for z, t in tokens if z == -1)
    words += [f"Bz{z}" for z in bound]
    return "+".join(words)


def _zone_word(z: int) -> str:
    return "Zon" if z == 0 else f"Zon{z}"


def _problem(states, tokens, bound) -> str | None:
    """Why these fields spell no structure of the grammar (``None``: they do)."""
    zones = ", ".join(_zone_word(z) for z in states)
    if not states:
        return "a structure has a zone state: Zon (or Zon1, Zon2)"
    if len(set(states)) != len(states) or len(set(bound)) != len(bound):
        return "each zone once, as a state or as a measured boundary"
    if 0 in states and len(states) > 1:
        return (
            "one zone is Zon (column T_zon), two zones are Zon1 and Zon2 (T_zon1, T_zon2); "
            "do not mix them"
        )
    if bound and (0 in bound or 0 in states):
        return (
            "a zone held as a measured boundary (Bz1, Bz2) goes with numbered zones: write "
            "e.g. Zon1+Bz2 (columns T_zon1, T_zon2)"
        )
    if both := sorted(set(states) & set(bound)):
        z = both[0]
        return f"zone {z} is both a state (Zon{z}) and a measured boundary (Bz{z}); keep one"
    if len(set(states) | set(bound)) > 2:
        return "the grammar models one or two zones; choose two, or declare the model yourself"
    for z, t in sorted(tokens):
        if z == -1:
            if t not in ("Cpl", "CplC"):
                return f"{t!r} is no structure token (those are Cpl and CplC)"
        elif z not in states:
            return (
                f"{t}{z or ''} belongs to zone {_zone_word(z)}, which is not a state (states: "
                f"{zones})"
            )
        elif (why := _token_problem(t)) is not None:
            meant = f"; did you mean {why[1]!r}?" if why[1] else ""
            return f"{t!r} is not a grammar token ({why[0] or 'unknown'}){meant}"
    cpl = sorted(t for z, t in tokens if z == -1)
    if len(cpl) == 2:
        fixed = _spell(states, tokens - {(-1, "Cpl")}, bound)
        return (
            f"CplC (the coupling split around a capacity C_bou) replaces Cpl, which it grows "
            f"from; write {fixed!r}"
        )
    if cpl and len(states) != 2:
        other = " (the other zone held as a measured boundary needs no coupling)" if bound else ""
        return (
            f"{cpl[0]} couples two zones modelled as states (Zon1+Zon2+{cpl[0]}, columns "
            f"T_zon1 and T_zon2), and this structure has one, {zones}{other}: add the other "
            f"zone or drop {cpl[0]}"
        )
    for z in states:
        suffix = "" if z == 0 else str(z)
        tok = {t for zz, t in tokens if zz == z}
        for t in sorted(tok, key=_rank):
            if is_boundary_token(t) and t.endswith("C") and t[:-1] in tok:
                fixed = _spell(states, tokens - {(z, t[:-1])}, bound)
                return (
                    f"{t}{suffix} (the boundary to T_{t[:-1].lower()} split around a capacity) "
                    f"replaces {t[:-1]}{suffix}, which it grows from; write {fixed!r}"
                )
        wins = sorted(t for t in tok if t.startswith("Win"))
        if len(wins) > 1:
            letters = "".join(x for x in "SEWN" if any(x in w[3:] for w in wins))
            return (
                f"one window token per zone, with all its facades: Win{letters}{suffix} "
                f"instead of {', '.join(w + suffix for w in wins)}"
            )
        for t in sorted(tok, key=_rank):
            if t in _NEEDS and not _NEEDS[t](tok):
                return _needs_text(t, z, states, tokens, bound)
    return None


def _needs_text(token: str, z: int, states, tokens, bound) -> str:
    """Why ``token`` of zone ``z`` lacks what it needs (``_NEEDS``), and names that do not."""
    s = "" if z == 0 else str(z)

    def spelled(add=(), drop=()) -> str:
        t = (set(tokens) - {(z, x) for x in drop}) | {(z, x) for x in add}
        return repr(_spell(states, t, bound))

    tok = {t for zz, t in tokens if zz == z}
    if token in ("Inf", "Ae"):
        what = {
            "Inf": "infiltration, parallel to the envelope: without the envelope capacity "
            "R_inf and R_wal join the same two temperatures and the data cannot tell them apart",
            "Ae": "solar gains on the envelope, received by the envelope capacity",
        }[token]
        return f"{token}{s} ({what}) needs Wal{s}; write {spelled(add=['Wal'])}"
    if token == "Rad" and "Hea" in tok:
        return (
            f"Rad{s} (radiative heating share) and Hea{s} (heater capacity) are two accounts of "
            f"the heating's lag; keep one: {spelled(drop=['Hea'])} or {spelled(drop=['Rad'])}"
        )
    if token == "Rad":
        return (
            f"Rad{s} (radiative heating share) needs Int{s}, the internal mass that receives "
            f"it; write {spelled(add=['Int'])}"
        )
    return (
        f"{token}{s} (solar share to the mass) needs a mass to receive it, Int{s} or Wal{s}; "
        f"write {spelled(add=['Int'])} or {spelled(add=['Wal'])}"
    )


def _grammar_problem(s: Structure, g: Grammar) -> str | None:
    """Why grammar ``g`` cannot build structure ``s`` (``None``: it can)."""
    lost = [z for z in (*s.states, *s.bound_zones) if z not in g.zones]
    if lost:
        have = ", ".join(f"T_zon{z or ''}" for z in g.zones)
        return (
            f"zone T_zon{lost[0] or ''} is not a zone of the grammar's data ({have}); name the "
            f"zones after the data: {', '.join(_zone_word(z) for z in g.zones)}"
        )
    for z in s.states:
        suffix = "" if z == 0 else str(z)
        tok = set(s.zone_tokens(z))
        if g.heat_column(z) is None and (need := sorted(tok & {"Hea", "Rad"})):
            what = {"Hea": "heater capacity", "Rad": "radiative heating share"}[need[0]]
            return (
                f"{need[0]}{suffix} ({what}) needs the heating column Q_hea{suffix}, which the "
                f"data lack; drop {need[0]}{suffix}"
            )
        if "Sol" in tok and s.window(z) is None and not g.horizontal:
            return (
                f"Sol{suffix} (solar share to the mass) needs solar gains: the column "
                f"I_glo_hor or facade windows (WinSE{suffix}); drop Sol{suffix}"
            )
    return None


# ---- parsing ------------------------------------------------------------------------------------


def is_structure_name(name: str) -> bool:
    """Whether ``name`` is written in the grammar (``Zon+…``, or ``Zon1+…``)."""
    return isinstance(name, str) and re.fullmatch(r"Zon\d?(\+[A-Za-z]+\d?)*", name) is not None


def parse_structure(name: str) -> Structure:
    """The structure a canonical name spells (``"Zon+Wal+Int"``, ``"Zon1+Zon2+Wal1+Cpl"``).

    Raises:
        ModelError: a word is not a grammar token (the message lists the tokens and the nearest
            one), or the words break a rule of the grammar (:mod:`~jaxbox.models.grammar`), or
            they are not in canonical order; each message says what to write instead.
    """
    if not isinstance(name, str):
        raise ModelError(
            f"a structure name is text such as 'Zon+Wal+Int', got {type(name).__name__}"
        )
    if not is_structure_name(name):
        raise ModelError(_not_a_name(name))
    states: list[int] = []
    bound: list[int] = []
    tokens = set()
    seen = set()
    for word in name.split("+"):
        if word in seen:
            raise ModelError(f"{name!r}: {word!r} appears twice; write each word once")
        seen.add(word)
        if m := re.fullmatch(r"Zon(\d?)", word):
            states.append(int(m[1] or 0))
        elif m := re.fullmatch(r"Bz([1-9])", word):
            bound.append(int(m[1]))
        elif word in ("Cpl", "CplC"):
            tokens.add((-1, word))
        elif word == "Bz0":
            why = "zones held as measured boundaries are numbered from 1: Bz1 for T_zon1"
            raise ModelError(_unknown(name, word, why, "Bz1"))
        else:
            m = _WORD.fullmatch(word)
            if (why := _token_problem(m[1])) is not None:
                meant = why[1]
                if meant and m[2]:  # (the zone number goes with each per-zone word)
                    per_zone = (w + m[2] if w not in _NOT_PER_ZONE else w for w in meant.split("+"))
                    meant = "+".join(per_zone)
                raise ModelError(_unknown(name, word, why[0], meant))
            tokens.add((int(m[2] or 0), m[1]))
    why = _problem(tuple(sorted(states)), frozenset(tokens), tuple(sorted(bound)))
    if why is not None:
        raise ModelError(f"{name!r}: {why}")
    s = Structure(tuple(states), frozenset(tokens), tuple(bound))
    if s.name != name:
        raise ModelError(f"{name!r} is not in canonical order; write it {s.name!r}")
    return s


def _unknown(name: str, word: str, why: str, meant: str | None) -> str:
    """The message refusing ``word`` of ``name``: why, the word meant, the words there are."""
    text = f"{name!r}: {word!r} is not a grammar token"
    if why:
        text += f" ({why})"
    if meant:
        return f"{text}; did you mean {meant!r}? {_TOKENS[0].upper()}{_TOKENS[1:]}"
    return f"{text}. {_TOKENS[0].upper()}{_TOKENS[1:]}"


def _not_a_name(name: str) -> str:
    """The message refusing a ``name`` that is not written in the grammar, with the nearest
    name that is."""
    text = f"{name!r} is not a structure name (words joined by '+', from 'Zon': 'Zon+Wal+Int')"
    guess = re.sub(r"\s+", "", name)
    if not is_structure_name(guess):
        guess = "+".join(w for w in re.findall(r"[A-Z][a-z]*\d?", guess))
    if guess != name and is_structure_name(guess):
        text += f"; did you mean {guess!r}?"
    return text


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

    def add(label, *new, drop=None):
        t = set(s.tokens)
        if drop is not None:
            t.discard((z, drop))
        t.update((z, n) for n in new)
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
    if swaps and heat and "Hea" in tok:  # two accounts of a heating's lag
        if "Int" in tok:
            add("radiative heating share instead of the heater capacity", "Rad", drop="Hea")
        else:  # the share needs a mass to go to: the mass comes with it
            label = "internal mass with a radiative heating share instead of the heater capacity"
            add(label, "Int", "Rad", drop="Hea")
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
    heater capacity: two accounts of the heating's lag; where the share has no internal mass to
    go to, the mass comes with it)."""
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
