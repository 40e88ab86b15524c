"""Declarative linear RC networks, compiled into pure state-space functions θ ↦ (A, B, C, D).

A network has *nodes* (thermal capacities, one state each, temperature in °C), *resistances*
between two nodes or between a node and a measured boundary temperature (an input such as
``T_amb``), and *heat sources* that inject ``gain · input`` watts into a node (``Q_hea`` with gain
1, ``I_glo_hor`` with gain ``gA`` m², …). A node may also be held at a constant, unknown
temperature (:meth:`RCNetwork.constant`, e.g. deep ground): its "state" keeps its initial value.
A resistance may carry a parametric share (``scale="fra_wal"``, ``scale="1-fra_wal"``), so that
the position of a capacity inside a resistance can be estimated. Declaring holds no parameter
values (only, optionally, parameter specs: :meth:`RCNetwork.parameter`): the built
:class:`RCModel` maps a parameter dict θ (SI values) to matrices with ``jax.numpy`` only, so it can
be jitted, differentiated and ``vmap``-ped over parameter sets.

Example::

    net = (
        RCNetwork("TiTe")
        .node("zon", output="T_zon")
        .node("wal")
        .resistance("zon", "wal", "R_wal", scale=0.5)
        .resistance("wal", "T_amb", "R_wal", scale=0.5)
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA")
    )
    model = net.build()
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ._parameters import ModelError, Parameter, parameter_for

__all__ = ["RCNetwork", "RCModel"]

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*")
_PARAM = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def _parse_gain(gain) -> tuple[tuple[str, object], ...]:
    """Parse a gain expression into factors: ('const', float) | ('param', name) | ('compl', name).

    Accepted: a number, a parameter name, ``1-name`` and products of those joined by ``*``.
    """
    if isinstance(gain, int | float):
        return (("const", float(gain)),)
    if not isinstance(gain, str) or not gain.strip():
        raise ModelError(f"gain {gain!r} must be a number or an expression like 'gA_e*fra_sol'")
    factors = []
    for term in gain.replace(" ", "").split("*"):
        if m := re.fullmatch(r"1-(" + _PARAM.pattern + ")", term):
            factors.append(("compl", m.group(1)))
        elif _PARAM.fullmatch(term):
            factors.append(("param", term))
        else:
            try:
                factors.append(("const", float(term)))
            except ValueError:
                raise ModelError(
                    f"cannot read gain term {term!r} in {gain!r}: use numbers, parameter names, "
                    "'1-name' and '*'"
                ) from None
    return tuple(factors)


#: the prefixes of the parameters a heat input's gain may name: apertures [m²], fractions [-]
#: and constant heat inputs [W]
_GAIN_PREFIXES = ("gA", "fra_", "Q_")


def _check_gain(network: str, input: str, gain) -> tuple[tuple[str, object], ...]:
    """The factors of the gain of heat input ``input``: finite numbers, and parameters that are
    apertures ``gA*``, fractions ``fra_*`` (also as ``1-fra_*``) or heat inputs ``Q_*``."""
    if isinstance(gain, bool):
        raise ModelError(f"{network}: gain of {input!r} is {gain!r}; give a number or a name")
    factors = _parse_gain(gain)
    for kind, value in factors:
        if kind == "const" and not abs(value) < float("inf"):
            raise ModelError(f"{network}: gain of {input!r} is {gain!r}; give a finite number")
        if kind == "param" and not value.startswith(_GAIN_PREFIXES):
            raise ModelError(
                f"{network}: gain {gain!r} of {input!r} names {value!r}; a gain names apertures "
                "gA* [m²], fractions fra_* [-] or heat inputs Q_* [W]"
            )
        if kind == "compl" and not value.startswith("fra_"):
            raise ModelError(
                f"{network}: gain {gain!r} of {input!r} takes 1-{value}; only a fraction fra_* "
                "has a complement"
            )
    return factors


def _gain_text(factors) -> str:
    out = []
    for kind, value in factors:
        out.append(f"{value:g}" if kind == "const" else value if kind == "param" else f"1-{value}")
    return "*".join(out)


@dataclasses.dataclass(frozen=True)
class _Node:
    name: str
    C: str  # "" for a constant node
    T0: str
    output: str | None
    constant: bool = False


@dataclasses.dataclass(frozen=True)
class _Edge:
    a: str
    b: str  # node name or boundary input name
    R: str
    scale: float
    factors: tuple[tuple[str, object], ...] = ()  # parametric share of R: ('param'|'compl', name)

    def text(self) -> str:
        parts = [] if self.scale == 1 else [f"{self.scale:g}"]
        parts += [v if k == "param" else f"(1-{v})" for k, v in self.factors]
        return self.R if not parts else "(" + "*".join(parts + [self.R]) + ")"


@dataclasses.dataclass(frozen=True)
class _Source:
    node: str
    input: str
    gain: tuple[tuple[str, object], ...]


@dataclasses.dataclass(frozen=True)
class RCNetwork:
    """Immutable declaration of a thermal RC network; each method returns a new network.

    Args:
        name: model name, shown in tables and reports.
        description: one line on what the structure represents.

    Networks are usually assembled from components (:mod:`jaxbox.models.components`), each a
    function ``network -> network``; :meth:`add` chains them fluently.
    """

    name: str
    description: str = ""
    nodes: tuple[_Node, ...] = ()
    edges: tuple[_Edge, ...] = ()
    sources: tuple[_Source, ...] = ()
    specs: tuple[Parameter, ...] = ()

    # ---- declaration -------------------------------------------------------------------------
    def _node_names(self) -> tuple[str, ...]:
        return tuple(n.name for n in self.nodes)

    def _require_node(self, name: str, where: str) -> None:
        if name not in self._node_names():
            raise ModelError(
                f"{self.name}: {where} refers to unknown node {name!r}; declare it first with "
                f".node({name!r}) (nodes so far: {', '.join(self._node_names()) or 'none'})"
            )

    def node(
        self,
        name: str,
        C: str | None = None,
        T0: str | None = None,
        output: str | bool | None = None,
    ) -> RCNetwork:
        """Add a thermal node (one state, temperature ``T_<name>`` in °C).

        Args:
            name: node name, letters and digits (``zon``, ``wal``, ``int``, ``zon1``…).
            C: its heat-capacity parameter [J/K]; default ``C_<name>``.
            T0: its initial-temperature parameter [°C]; default ``T_<name>0``.
            output: ``True`` to measure the node as output ``T_<name>``, or the output name.
        """
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise ModelError(f"{self.name}: node name {name!r} must be letters and digits only")
        if name in self._node_names():
            raise ModelError(f"{self.name}: duplicate node {name!r}; node names must be unique")
        C = f"C_{name}" if C is None else C
        T0 = f"T_{name}0" if T0 is None else T0
        for what, value in (("capacity", C), ("initial state", T0)):
            if not isinstance(value, str) or (value and not _PARAM.fullmatch(value)):
                raise ModelError(
                    f"{self.name}: {what} parameter of node {name!r} is {value!r}; give a "
                    "parameter name of letters, digits and '_'"
                )
        if not C:
            raise ModelError(f"{self.name}: node {name!r} has no capacity; give C='C_{name}'")
        if not C.startswith("C_"):
            raise ModelError(
                f"{self.name}: capacity of node {name!r} is {C!r}; capacities are named C_*"
            )
        if not re.fullmatch(r"T_\w+0", T0):
            raise ModelError(f"{self.name}: initial state of node {name!r} must be named T_*0")
        if output is True:
            output = f"T_{name}"
        elif output is False:
            output = None
        if output is not None and (not isinstance(output, str) or not _PARAM.fullmatch(output)):
            raise ModelError(
                f"{self.name}: output of node {name!r} is {output!r}; give True or a column name "
                "of letters, digits and '_' (e.g. 'T_zon')"
            )
        if output is not None and output in [n.output for n in self.nodes]:
            raise ModelError(f"{self.name}: duplicate output {output!r}")
        return dataclasses.replace(self, nodes=self.nodes + (_Node(name, C, T0, output),))

    def constant(self, name: str, T0: str | None = None) -> RCNetwork:
        """Add a node held at a constant temperature ``T0`` [°C] (a parameter, ``T_<name>0``).

        A boundary whose temperature is not measured but constant over the data, e.g. deep
        ground: it is a state with ``dT/dt = 0``, so its value is estimated like an initial state
        (or fixed). It takes no heat input and cannot be measured.
        """
        net = self.node(name, T0=T0)
        node = dataclasses.replace(net.nodes[-1], C="", constant=True)
        return dataclasses.replace(net, nodes=self.nodes + (node,))

    def _constant_nodes(self) -> tuple[str, ...]:
        return tuple(n.name for n in self.nodes if n.constant)

    def resistance(self, a: str, b: str, R: str, scale: float | str = 1.0) -> RCNetwork:
        """Add a resistance ``scale · R`` [K/W] between node ``a`` and node or boundary input ``b``.

        ``b`` is a node name, or a measured temperature input (a name starting with ``T_``,
        e.g. ``T_amb``, ``T_bou``), in °C. ``scale`` is a positive number, or an expression of
        fractions such as ``"fra_wal"`` or ``"1-fra_wal"`` (``"0.5*fra_wal"``…): a share of ``R``
        that is itself estimated. Such a fraction stays strictly inside (0, 1), where neither
        part of ``R`` vanishes: without a declared spec its bounds are [0.01, 0.99] (not the
        [0, 1] of other fractions), and :meth:`build` refuses declared bounds that reach 0 or 1.
        """
        self._require_node(a, f"resistance {R!r}")
        if not isinstance(b, str) or not _PARAM.fullmatch(b):
            raise ModelError(
                f"{self.name}: resistance {R!r} links {a!r} to {b!r}; give a node name or a "
                "temperature input such as 'T_amb'"
            )
        if b not in self._node_names():
            if not b.startswith("T_"):
                raise ModelError(
                    f"{self.name}: resistance {R!r} links {a!r} to {b!r}, which is neither a "
                    "declared node nor a temperature input (inputs are named T_*, e.g. T_amb)"
                )
        if a == b:
            raise ModelError(f"{self.name}: resistance {R!r} links node {a!r} to itself")
        if not isinstance(R, str) or not R.startswith("R_") or not _PARAM.fullmatch(R):
            raise ModelError(f"{self.name}: resistance parameter {R!r} must be named R_*")
        const = self._constant_nodes()
        if a in const and (b in const or b not in self._node_names()):
            raise ModelError(
                f"{self.name}: resistance {R!r} links the constant node {a!r} to another boundary "
                f"{b!r}; a constant node can only be linked to a node with a capacity"
            )
        factors: tuple = ()
        if isinstance(scale, str):
            value = 1.0
            for kind, v in _parse_gain(scale):
                if kind == "const":
                    value *= v
                elif not v.startswith("fra_"):
                    raise ModelError(
                        f"{self.name}: scale {scale!r} of resistance {R!r} names {v!r}; a share "
                        "of a resistance is a fraction fra_* (e.g. 'fra_wal', '1-fra_wal')"
                    )
                else:
                    factors += ((kind, v),)
            scale = value
        try:
            scale = float(scale)
        except (TypeError, ValueError):
            raise ModelError(
                f"{self.name}: scale of resistance {R!r} must be a number or an expression like "
                f"'fra_wal', got {scale!r}"
            ) from None
        if not 0 < scale < float("inf"):
            raise ModelError(
                f"{self.name}: resistance {R!r} needs a finite scale > 0, got {scale!r}"
            )
        edge = _Edge(a, b, R, scale, factors)
        if any(
            {e.a, e.b} == {a, b} and (e.R, e.scale, e.factors) == (R, scale, factors)
            for e in self.edges
        ):
            raise ModelError(
                f"{self.name}: resistance {R!r} between {a!r} and {b!r} is declared twice (two "
                "in parallel would halve it); give the second its own parameter name"
            )
        return dataclasses.replace(self, edges=self.edges + (edge,))

    def heat(self, node: str, input: str, gain: str | float = 1.0) -> RCNetwork:
        """Inject ``gain · input`` [W] into ``node``.

        ``input`` is a power [W] (``Q_hea``, ``P_ele``) or an irradiance [W/m²] (``I_glo_hor``,
        ``I_e``…), ``gain`` a number or an expression of parameters: ``"gA"``,
        ``"gA_e*fra_sol"``, ``"1-fra_rad"``.
        """
        self._require_node(node, f"heat input {input!r}")
        if not isinstance(input, str) or not _PARAM.fullmatch(input):
            raise ModelError(
                f"{self.name}: heat input {input!r} of node {node!r} must be a column name of "
                "letters, digits and '_' (e.g. 'Q_hea', 'I_glo_hor')"
            )
        if node in self._constant_nodes():
            raise ModelError(
                f"{self.name}: node {node!r} is held at a constant temperature and takes no heat "
                f"input {input!r}"
            )
        if input.startswith("T_"):
            raise ModelError(
                f"{self.name}: {input!r} is a temperature; link it with .resistance(), not .heat()"
            )
        source = _Source(node, input, _check_gain(self.name, input, gain))
        if source in self.sources:
            raise ModelError(
                f"{self.name}: heat input {input!r} into {node!r} with gain {gain!r} is declared "
                "twice (it would count twice); declare it once"
            )
        return dataclasses.replace(self, sources=self.sources + (source,))

    def parameter(self, name: str, spec: Parameter | None = None, **fields) -> RCNetwork:
        """Declare the spec of a parameter: its default guess, bounds or description.

        Starts from ``spec``, else from a spec declared before, else from the naming convention
        (:func:`~jaxbox.models.parameter_for`), and changes ``fields`` (``default``, ``lower``,
        ``upper``, ``description``, ``unit``). The parameter must be used by the network when it
        is built; :meth:`build`'s ``params`` still override it.

        Example: ``net.parameter("fra_wal", lower=0.05, upper=0.95)``.
        """
        if spec is not None:
            if not isinstance(spec, Parameter):
                raise ModelError(f"{self.name}: spec of {name!r} must be a Parameter")
            base = spec.replace(name=name)
        else:
            known = [p for p in self.specs if p.name == name]
            base = known[0] if known else parameter_for(name)
        if fields:
            allowed = {"unit", "default", "lower", "upper", "description"}
            bad = [f for f in fields if f not in allowed]
            if bad:
                raise ModelError(
                    f"{self.name}: parameter {name!r} has no field(s) {', '.join(bad)}; give "
                    "default, lower, upper, unit or description"
                )
            base = base.replace(**fields)
        specs = tuple(p for p in self.specs if p.name != name) + (base,)
        return dataclasses.replace(self, specs=specs)

    def add(self, component, *args, **kwargs) -> RCNetwork:
        """Apply a component ``component(network, *args, **kwargs) -> network`` (fluent style).

        Example: ``RCNetwork("M").add(zone).add(wall).add(heating).add(window, "I_glo_hor")``.
        """
        net = component(self, *args, **kwargs)
        if not isinstance(net, RCNetwork):
            name = getattr(component, "__name__", repr(component))
            raise ModelError(f"component {name} must return an RCNetwork, got {type(net).__name__}")
        return net

    # ---- build ---------------------------------------------------------------------------------
    def build(self, params: Mapping[str, Parameter | Mapping] | None = None) -> RCModel:
        """Check the network and compile it into an :class:`RCModel`.

        Args:
            params: optional overrides per parameter name: a :class:`Parameter`, or a dict of the
                fields to change (``{"R_wal": {"default": 0.02, "upper": 1.0}}``).

        Raises:
            ModelError: no node, no output, a node with no path to a boundary temperature
                (its temperature would drift without bound), an override for an unknown
                parameter, a fraction setting a share of a resistance (``scale="fra_wal"``)
                whose bounds reach 0 or 1 (that part of the resistance would vanish).
        """
        if not self.nodes:
            raise ModelError(f"{self.name}: the network has no node; add one with .node()")
        if not any(n.output for n in self.nodes):
            raise ModelError(f"{self.name}: no node is measured; mark one with output=True")
        names = self._node_names()
        const = set(self._constant_nodes())
        # connectivity: every node must reach a boundary temperature through resistances
        linked = {n: set() for n in names if n not in const}
        grounded = set()
        used = set()
        for e in self.edges:
            used.update((e.a, e.b))
            if e.a in linked and e.b in linked:
                linked[e.a].add(e.b)
                linked[e.b].add(e.a)
            else:  # to a boundary input or a constant node
                grounded.add(e.b if e.a in const else e.a)
        idle = [n for n in names if n in const and n not in used]
        if idle:
            raise ModelError(
                f"{self.name}: constant node(s) {', '.join(idle)} are linked to nothing; link "
                "them with .resistance() or remove them"
            )
        reach = set(grounded)
        frontier = list(grounded)
        while frontier:
            for m in linked[frontier.pop()]:
                if m not in reach:
                    reach.add(m)
                    frontier.append(m)
        lost = [n for n in names if n not in reach and n not in const]
        if lost:
            raise ModelError(
                f"{self.name}: node(s) {', '.join(lost)} have no resistance path to a boundary "
                "temperature (e.g. T_amb); connect them, or the network has no steady state"
            )
        # inputs in order of first use
        inputs: list[str] = []
        for e in self.edges:
            if e.b not in names and e.b not in inputs:
                inputs.append(e.b)
        for s in self.sources:
            if s.input not in inputs:
                inputs.append(s.input)
        clash = [n.output for n in self.nodes if n.output in inputs]
        if clash:
            raise ModelError(
                f"{self.name}: output {clash[0]!r} is also an input of the network; a measured "
                "node cannot be driven by its own measurement: rename the output or the input"
            )
        # parameters in a canonical order: capacities, resistances, gains, initial states
        order: list[str] = []
        for n in self.nodes:
            if not n.constant:
                order.append(n.C)
        for e in self.edges:
            order.append(e.R)
            order.extend(v for _, v in e.factors)
        for s in self.sources:
            order.extend(v for k, v in s.gain if k != "const")
        for n in self.nodes:
            order.append(n.T0)
        seen: dict[str, None] = {}
        for p in order:
            seen.setdefault(p, None)
        declared = {p.name: p for p in self.specs}
        unused = [p for p in declared if p not in seen]
        if unused:
            raise ModelError(
                f"{self.name}: spec declared for parameter(s) {', '.join(unused)}, which no "
                f"element of the network uses (parameters: {', '.join(seen)})"
            )
        specs = {p: declared[p] if p in declared else parameter_for(p) for p in seen}
        for f in {f for e in self.edges for _, f in e.factors} - set(declared):
            default = min(max(specs[f].default, 0.01), 0.99)  # (a share of a resistance)
            specs[f] = specs[f].replace(default=default, lower=0.01, upper=0.99)
        for p, over in (params or {}).items():
            if p not in specs:
                raise ModelError(
                    f"{self.name}: override for unknown parameter {p!r}; the model's parameters "
                    f"are {', '.join(specs)}"
                )
            if isinstance(over, Parameter):
                specs[p] = over.replace(name=p)
            else:
                specs[p] = specs[p].replace(**dict(over))
        for e in self.edges:  # a share of a resistance at 0 or 1 removes a part of it
            for _, f in e.factors:
                if not 0.0 < specs[f].lower <= specs[f].upper < 1.0:
                    raise ModelError(
                        f"{self.name}: {f} sets a share of the resistance {e.R} between {e.a!r} "
                        f"and {e.b!r} ({e.text()}); its bounds [{specs[f].lower:g}, "
                        f"{specs[f].upper:g}] must lie strictly inside (0, 1), or that part of "
                        f"{e.R} vanishes: give bounds such as [0.01, 0.99]"
                    )
        return RCModel(
            name=self.name,
            description=self.description,
            network=self,
            states=tuple(f"T_{n.name}" for n in self.nodes),
            inputs=tuple(inputs),
            outputs=tuple(n.output for n in self.nodes if n.output),
            parameters=tuple(specs.values()),
        )


@dataclasses.dataclass(frozen=True)
class RCModel:
    """A compiled linear RC model: ``dx/dt = A x + B u``, ``y = C x + D u``.

    States are node temperatures [°C], inputs are in the data's units (°C, W, W/m²), time is in
    seconds. Holds no parameter values: pass θ, a mapping ``name -> value`` (SI units), to
    :meth:`state_space` and :meth:`initial_state`. Hashable and comparable by value, so it can key
    compiled-function caches.
    """

    name: str
    description: str
    network: RCNetwork
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[Parameter, ...]
    segments: int = 1

    # ---- introspection -----------------------------------------------------------------------
    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def n_states(self) -> int:
        return len(self.states)

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise ModelError(
            f"model {self.name} has no parameter {name!r}; its parameters are "
            f"{', '.join(self.param_names)}"
        )

    def defaults(self) -> dict[str, float]:
        """Default guess for every parameter (SI), by the naming convention or overrides."""
        return {p.name: p.default for p in self.parameters}

    @property
    def structure(self) -> tuple:
        """Everything that shapes the compiled computation, but no default values or bounds."""
        n = self.network
        return (self.states, self.inputs, self.outputs, n.nodes, n.edges, n.sources, self.segments)

    def with_parameters(self, params: Mapping[str, Parameter | Mapping]) -> RCModel:
        """A copy with some parameter specs (defaults, bounds) changed."""
        own = {p.name: p for p in self.parameters}
        new = {**own, **dict(params)}
        base = self.network.build({k: v for k, v in new.items() if k in self.base_names})
        out = base.segmented(self.segments)
        extra = {k: v for k, v in new.items() if k not in self.base_names}
        if not extra:
            return out
        specs = tuple(
            (v.replace(name=p.name) if isinstance(v, Parameter) else p.replace(**dict(v)))
            if (v := extra.get(p.name)) is not None
            else p
            for p in out.parameters
        )
        return dataclasses.replace(out, parameters=specs)

    def scaled(self, s: float) -> RCModel:
        """A copy for a building ``s`` times as large: every parameter's default and bounds as
        :func:`~jaxbox.models.scaled_parameter` scales them (resistances divided by ``s``,
        capacities, constant heat inputs and apertures multiplied); ``self`` where ``s`` is 1.

        Raises:
            ModelError: ``s`` not a finite number > 0.
        """
        from ._parameters import scaled_parameter

        specs = {p.name: scaled_parameter(p, s) for p in self.parameters}
        return self if s == 1.0 else self.with_parameters(specs)

    # ---- segments ------------------------------------------------------------------------------
    @property
    def base_names(self) -> tuple[str, ...]:
        """The parameters of the network (without the initial states of later segments)."""
        extra = {
            f"{m.T0}_s{k}"
            for k in range(2, self.segments + 1)
            for m in self.network.nodes
            if not m.constant
        }
        return tuple(n for n in self.param_names if n not in extra)

    def segment_names(self, k: int) -> tuple[str, ...]:
        """The initial-state parameters of segment ``k`` (1-based), in node order: ``T_*0`` for
        the first, ``T_*0_s<k>`` for the others. A constant node keeps one value (its
        ``T_*0``) for every segment."""
        return tuple(m.T0 if k == 1 or m.constant else f"{m.T0}_s{k}" for m in self.network.nodes)

    def segmented(self, segments: int) -> RCModel:
        """This model for data in ``segments`` separate segments (gaps cut out, or separate
        periods): the same network and parameters, plus the initial states ``T_*0_s2``,
        ``T_*0_s3``… of each later segment (same unit, default and bounds as ``T_*0``). The
        segments share every other parameter; the simulation restarts each segment from its
        own initial states. ``segmented(1)`` is the plain model."""
        segments = int(segments)
        if segments < 1:
            raise ModelError(f"segments must be at least 1, got {segments}")
        if segments == self.segments:
            return self
        base = [p for p in self.parameters if p.name in self.base_names]
        specs = {p.name: p for p in base}
        extra = []
        for k in range(2, segments + 1):
            for m, name in zip(self.network.nodes, self.segment_names(k), strict=True):
                if not m.constant:
                    first = specs[m.T0]
                    extra.append(
                        first.replace(name=name, description=f"{first.description} (segment {k})")
                    )
        return dataclasses.replace(self, parameters=tuple(base + extra), segments=segments)

    def initial_states(self, theta: Mapping):
        """Initial node temperatures of every segment [°C], shape [segments, n] (a numpy array
        where every value is a host number, so that no device program is compiled for it)."""
        rows = [[theta[n] for n in self.segment_names(k)] for k in range(1, self.segments + 1)]
        if all(isinstance(v, (int, float, np.ndarray, np.generic)) for r in rows for v in r):
            return np.asarray(rows, dtype=float)
        return jnp.stack([jnp.stack([jnp.asarray(v, dtype=float) for v in r]) for r in rows])

    def renamed(self, name: str, description: str | None = None) -> RCModel:
        return dataclasses.replace(
            self,
            name=name,
            description=self.description if description is None else description,
            network=dataclasses.replace(self.network, name=name),
        )

    def describe(self) -> dict:
        """A JSON-ready description: name, states, inputs, outputs, parameters with units/bounds."""
        return {
            "name": self.name,
            "description": self.description,
            "states": list(self.states),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "constant_states": [f"T_{n.name}" for n in self.network.nodes if n.constant],
            "equations": self.equations(),
            "parameters": [
                {
                    "name": p.name,
                    "unit": p.unit,
                    "default": p.default,
                    "lower": p.lower,
                    "upper": p.upper,
                    "description": p.description,
                }
                for p in self.parameters
            ],
        }

    def check_data(self, data, outputs: bool = True) -> None:
        """Raise the dataset's ``DataError`` unless ``data`` holds every input of the model (and,
        with ``outputs``, every output), naming the missing columns."""
        names = list(self.inputs) + (list(self.outputs) if outputs else [])
        data.require(names, what=f"model {self.name}")

    def equations(self) -> list[str]:
        """Human-readable energy balance per node."""
        n = self.network
        lines = []
        for node in n.nodes:
            if node.constant:
                lines.append(f"T_{node.name} = {node.T0} (constant)")
                continue
            terms = []
            for e in n.edges:
                R = e.text()
                if e.a == node.name:
                    other = f"T_{e.b}" if e.b in [m.name for m in n.nodes] else e.b
                    terms.append(f"({other} - T_{node.name})/{R}")
                elif e.b == node.name:
                    terms.append(f"(T_{e.a} - T_{node.name})/{R}")
            for s in n.sources:
                if s.node == node.name:
                    g = _gain_text(s.gain)
                    terms.append(s.input if g == "1" else f"{g}*{s.input}")
            lines.append(f"{node.C} dT_{node.name}/dt = " + " + ".join(terms))
        return lines

    def __repr__(self) -> str:
        return (
            f"RCModel({self.name!r}, states={list(self.states)}, inputs={list(self.inputs)}, "
            f"outputs={list(self.outputs)}, parameters={list(self.param_names)})"
        )

    # ---- numerics (pure jnp; jit/vmap/grad friendly) -------------------------------------------
    def rc_form(self, theta: Mapping) -> tuple:
        """``(A [1/s], B, caps [J/K], held)``: the state matrices with the heat capacities.

        Assembled as ``G = Σ_e g_e K_e`` over the edges, with constant incidence matrices
        ``K_e`` and the conductances ``g_e`` [W/K] stacked in one vector (likewise ``H`` over
        edges to inputs and heat sources), instead of a chain of indexed updates: a small
        program for XLA to compile once differentiated and batched (the arrays of
        :meth:`rc_arrays`, through :func:`rc_from_arrays`). ``caps`` holds 1 for a constant
        node and ``held`` (static) marks them; their rows of A and B are zero.
        """
        names = [n for n in self.param_names if n in theta]
        v = jnp.stack([jnp.asarray(theta[n], dtype=float) for n in names] + [1.0, 0.0])
        arrays = self.rc_arrays(names + ["1", "0"], inputs=self.inputs, **self.array_sizes())
        A, B, caps, _ = rc_from_arrays(v, arrays)
        return A, B, caps, tuple(bool(node.constant) for node in self.network.nodes)

    def array_sizes(self) -> dict[str, int]:
        """Sizes of this network in array form (:meth:`rc_arrays`): ``states``, ``edges``,
        ``sources`` (at least 1) and ``factors`` (parameters in the longest product, at least
        1)."""
        net = self.network
        products = [e.factors for e in net.edges] + [s.gain for s in net.sources]
        return dict(
            states=len(net.nodes),
            edges=len(net.edges),
            sources=max(len(net.sources), 1),
            factors=max([1] + [sum(k != "const" for k, _ in f) for f in products]),
        )

    def rc_arrays(
        self,
        slots: Sequence[str],
        *,
        states: int,
        inputs: Sequence[str],
        edges: int,
        sources: int,
        factors: int,
    ) -> dict[str, np.ndarray]:
        """The network as arrays for :func:`rc_from_arrays`: one compiled program for every
        structure of the same (padded) size.

        Args:
            slots: parameter name of each entry of the value vector ``v`` that
                :func:`rc_from_arrays` receives; it must end with two entries named ``"1"``
                and ``"0"`` holding the constants 1 and 0.
            states: states after padding (≥ this model's); the extra ones are inert.
            inputs: the input columns after padding (a superset of this model's inputs).
            edges, sources, factors: edges, heat sources and factors per product after padding.

        Returns:
            ``R`` [E], ``scale`` [E], ``fk``/``fa``/``fb`` [E, F] (a factor is ``fa + fb·v[fk]``),
            ``KG`` [E, n, n], ``KH`` [E, n, m], ``sk``/``sa``/``sb`` [S, F], ``KS`` [S, n, m],
            ``C`` [n], ``T0`` [n] (``[segments, n]`` with segments) and ``pad`` [n] (1 for a
            padding state). A constant node's rows are zero and its capacity slot is ``"1"``.

        Raises:
            ModelError: sizes too small for the network.
        """
        net = self.network
        where = {name: i for i, name in enumerate(slots)}
        one, zero = where["1"], where["0"]
        names = [m.name for m in net.nodes]
        idx = {name: i for i, name in enumerate(names)}
        uidx = {u: j for j, u in enumerate(inputs)}
        n, m = states, len(inputs)
        E, S, F = edges, sources, factors
        if len(names) > n or len(net.edges) > E or len(net.sources) > S:
            raise ModelError(f"model {self.name} does not fit the padded sizes")
        out = dict(
            R=np.full(E, one),
            scale=np.ones(E),
            fk=np.full((E, F), one),
            fa=np.ones((E, F)),
            fb=np.zeros((E, F)),
            KG=np.zeros((E, n, n)),
            KH=np.zeros((E, n, m)),
            sk=np.full((S, F), one),
            sa=np.ones((S, F)),
            sb=np.zeros((S, F)),
            KS=np.zeros((S, n, m)),
            C=np.full(n, one),
            pad=np.zeros(n),
        )

        def product(terms, row, k, a, b, scale=1.0):
            """Write the factors of a product into row ``row``; returns the constant part."""
            f = 0
            for kind, value in terms:
                if kind == "const":
                    scale *= float(value)
                    continue
                if f >= F:
                    raise ModelError(f"model {self.name}: more than {F} factors in a product")
                k[row, f] = where[value]
                a[row, f], b[row, f] = (0.0, 1.0) if kind == "param" else (1.0, -1.0)
                f += 1
            return scale

        for e_i, e in enumerate(net.edges):
            out["R"][e_i] = where[e.R]
            out["scale"][e_i] = product(e.factors, e_i, out["fk"], out["fa"], out["fb"], e.scale)
            i = idx[e.a]
            out["KG"][e_i, i, i] -= 1.0
            if e.b in idx:
                j = idx[e.b]
                out["KG"][e_i, j, j] -= 1.0
                out["KG"][e_i, i, j] += 1.0
                out["KG"][e_i, j, i] += 1.0
            else:
                out["KH"][e_i, i, uidx[e.b]] += 1.0
        for s_i, src in enumerate(net.sources):
            c = product(src.gain, s_i, out["sk"], out["sa"], out["sb"])
            out["KS"][s_i, idx[src.node], uidx[src.input]] = c
        for i, node in enumerate(net.nodes):
            if node.constant:  # held: dT/dt = 0
                for k in ("KG", "KH", "KS"):
                    out[k][:, i] = 0.0
            else:
                out["C"][i] = where[node.C]
        out["pad"][len(names) :] = 1.0
        if self.segments > 1:
            t0 = np.full((self.segments, n), zero)
            for k in range(1, self.segments + 1):
                for i, node in enumerate(net.nodes):
                    t0[k - 1, i] = where.get(node.T0 if k == 1 else f"{node.T0}_s{k}", zero)
        else:
            t0 = np.full(n, zero)
            for i, node in enumerate(net.nodes):
                t0[i] = where.get(node.T0, zero)
        out["T0"] = t0
        return out

    def rc_numpy(self, theta: Mapping) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A [1/s], B, caps [J/K])`` of :meth:`rc_form` evaluated in numpy (float values): no
        JAX dispatch, so nothing is compiled for a new structure."""
        names = [n for n in self.param_names if n in theta]
        v = np.asarray([float(theta[n]) for n in names] + [1.0, 0.0])
        arrays = self.rc_arrays(names + ["1", "0"], inputs=self.inputs, **self.array_sizes())
        A, B, caps, _ = rc_from_arrays(v, arrays, xp=np)
        return A, B, caps

    def state_space_numpy(self, theta: Mapping) -> tuple[np.ndarray, ...]:
        """:meth:`state_space` evaluated in numpy (float values): no JAX dispatch, so nothing is
        compiled for a new structure (post-simulation, time constants, reports)."""
        A, B, _ = self.rc_numpy(theta)
        net = self.network
        out_nodes = [i for i, m in enumerate(net.nodes) if m.output]
        C = np.zeros((len(out_nodes), len(net.nodes)))
        C[np.arange(len(out_nodes)), out_nodes] = 1.0
        return A, B, C, np.zeros((len(out_nodes), len(self.inputs)))

    def steady_state_gains(self, theta: Mapping) -> np.ndarray | None:
        """``G = C (−A)⁻¹ B + D`` [outputs, inputs] over the nodes that are not held at a constant
        temperature: how far each output moves per unit of each input at steady state (K/K,
        K/W, K per W/m²), evaluated in numpy; ``None`` when the state matrix is singular."""
        A, B, C, D = self.state_space_numpy({k: float(np.asarray(v)) for k, v in theta.items()})
        dyn = [i for i, n in enumerate(self.network.nodes) if not n.constant]
        try:
            return C[:, dyn] @ np.linalg.solve(-A[np.ix_(dyn, dyn)], B[dyn]) + D
        except np.linalg.LinAlgError:
            return None

    def sensor_offsets(self, theta: Mapping) -> dict[str, float]:
        """The constant offset [K] of each output that the constant heat input (the input
        ``"one"``, :func:`~jaxbox.models.components.sensor_offset`) stands for: its column of
        :meth:`steady_state_gains`; empty without such an input or with a singular state
        matrix. Also :func:`jaxbox.validate.sensor_offsets`."""
        from ..data._signals import CONSTANT

        if CONSTANT not in self.inputs:
            return {}
        G = self.steady_state_gains(theta)
        if G is None:
            return {}
        g = G[:, self.inputs.index(CONSTANT)]
        return {o: float(v) for o, v in zip(self.outputs, g, strict=True) if np.isfinite(v)}

    def state_space(self, theta: Mapping) -> tuple:
        """Continuous-time matrices (A [1/s], B, C, D) for parameters θ (SI values).

        B maps inputs to dT/dt: ``1/(R C)`` [1/s] for boundary temperatures, ``gain/C`` [K/J] for
        heat inputs. Every parameter of the model must be in θ. Constant nodes keep their
        value (dT/dt = 0). See :meth:`rc_form`, which assembles A and B.
        """
        A, B, _, _ = self.rc_form(theta)
        out_nodes = [i for i, m in enumerate(self.network.nodes) if m.output]
        C = np.zeros((len(out_nodes), len(self.network.nodes)))
        C[np.arange(len(out_nodes)), out_nodes] = 1.0
        D = jnp.zeros((len(out_nodes), len(self.inputs)))
        return A, B, jnp.asarray(C), D

    def initial_state(self, theta: Mapping):
        """Initial node temperatures x0 [°C] from the ``T_*0`` parameters in θ."""
        return jnp.stack([jnp.asarray(theta[m.T0], dtype=float) for m in self.network.nodes])


def rc_from_arrays(v, arrays, xp=jnp) -> tuple:
    """``(A [1/s], B, caps [J/K], x0 [°C])`` of a network in array form (:meth:`RCModel.rc_arrays`)
    for the parameter values ``v`` (one entry per slot); ``xp`` is ``jax.numpy`` (traceable) or
    ``numpy`` (no dispatch or compilation: for evaluations outside compiled code).

    The same program for every structure of the same padded size. A padding state gets a
    decoupled decay faster than every mode of the network (three or more times its largest
    diagonal rate, none the same: the spectrum stays simple, so the eigendecomposition of the
    discretisation and its derivatives stay exact), no input and the initial value 0.
    """
    take = lambda k: v[k]  # noqa: E731
    f_edge = xp.prod(arrays["fa"] + arrays["fb"] * take(arrays["fk"]), axis=-1)
    cond = 1.0 / (arrays["scale"] * take(arrays["R"]) * f_edge)
    gain = xp.prod(arrays["sa"] + arrays["sb"] * take(arrays["sk"]), axis=-1)
    G = xp.tensordot(cond, arrays["KG"], 1)
    H = xp.tensordot(cond, arrays["KH"], 1) + xp.tensordot(gain, arrays["KS"], 1)
    caps = take(arrays["C"])
    A, B = G / caps[:, None], H / caps[:, None]
    pad = arrays["pad"]
    if not (isinstance(pad, np.ndarray) and not pad.any()):  # padding states (traced: always)
        fastest = xp.max(xp.abs(xp.diagonal(A)) * (1.0 - pad))
        if xp is jnp:
            fastest = jax.lax.stop_gradient(fastest)
        rank = xp.cumsum(pad)  # 1, 2, … along the padding states
        A = A - xp.diag(pad * (2.0 + rank) * xp.maximum(fastest, 1e-12))
    return A, B, caps, take(arrays["T0"])
