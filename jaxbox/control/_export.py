"""A fitted model exported for a controller or another tool.

:func:`to_state_space` gives the discrete-time model at a chosen step, exact for the fit's hold
of the inputs. jaxbox's own recursion is ``x_{k+1} = Φ x_k + Γ0 u_k + Γ1 (u_{k+1} − u_k)``
(Γ1 = 0 for a zero-order hold); with a first-order hold it looks one input ahead, which a
standard discrete state space cannot. The state ``ξ_k = x_k − Γ1 u_k`` removes that::

    ξ_{k+1} = Φ ξ_k + (Γ0 + (Φ − I) Γ1) u_k,     y_k = C ξ_k + (D + C Γ1) u_k,

the standard form ``(A, B, C, D)`` exported (``A = Φ``), exact at the samples for inputs linear
between them; ``x = ξ + Γ1 u`` gives the node temperatures back. Also exported: ``Φ``, ``Γ0``,
``Γ1`` themselves, the continuous ``A_c``, ``B_c`` [SI], names and units, the process- and
measurement-noise covariances ``Q`` and ``R`` [K²] of the stochastic form at that step, and the
last state estimate of the Kalman filter over the fit's data (the node temperatures ``x`` [°C]
with covariance ``P`` [K²]).

:func:`modelica_model` writes the RC network as a Modelica model: parameters with units, inputs
as ``RealInput`` connectors, one energy balance per node, the outputs as ``RealOutput``.
"""

from __future__ import annotations

import dataclasses
import io
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..data._signals import signal_unit
from ..models import RCModel

__all__ = [
    "StateSpaceModel",
    "to_state_space",
    "read_state_space",
    "modelica_model",
    "python_control_script",
    "FORMATS",
]

#: export formats
FORMATS = ("json", "npz", "modelica", "python-control")
_ARRAYS = ("A", "B", "C", "D", "Phi", "Gamma0", "Gamma1", "A_c", "B_c", "Q", "R", "x", "P")


@dataclasses.dataclass(frozen=True, eq=False)
class StateSpaceModel:
    """A discrete-time state space of a fitted model (see the module docstring).

    Attributes:
        model: model name. step: sampling step [s]. hold: ``"foh"`` or ``"zoh"``.
        states, inputs, outputs: names; units: unit of every state, input and output.
        A, B, C, D: the standard discrete form in the state ``ξ = x − Γ1 u``.
        Phi, Gamma0, Gamma1: jaxbox's recursion in the node temperatures ``x``.
        A_c [1/s], B_c: the continuous model ``dx/dt = A_c x + B_c u``.
        Q, R: process- and measurement-noise covariances at this step [K²] (None: unknown).
        x, P: the last state estimate (node temperatures [°C]) and its covariance [K²], at
            ``time`` (None: not estimated).
        params: the parameters [SI]. noise: where the noise comes from.
    """

    model: str
    step: float
    hold: str
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    units: dict
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Phi: np.ndarray
    Gamma0: np.ndarray
    Gamma1: np.ndarray
    A_c: np.ndarray
    B_c: np.ndarray
    Q: np.ndarray | None
    R: np.ndarray | None
    x: np.ndarray | None
    P: np.ndarray | None
    time: str | None
    params: dict
    noise: str

    @property
    def xi(self) -> np.ndarray | None:
        """The last state estimate in the standard form's state ``ξ = x − Γ1 u``; needs the
        input at that time, so it is returned only for a zero-order hold (``ξ = x``)."""
        return None if self.x is None or self.hold != "zoh" else self.x

    def simulate(self, u, x0) -> tuple[np.ndarray, np.ndarray]:
        """Outputs [N, p] and node temperatures [N, n] of the standard form for inputs
        ``u`` [N, m] from node temperatures ``x0`` [°C] at the first sample."""
        u = np.asarray(u, float)
        xi = np.asarray(x0, float) - self.Gamma1 @ u[0]
        xs, ys = [], []
        for uk in u:
            xs.append(xi + self.Gamma1 @ uk)
            ys.append(self.C @ xi + self.D @ uk)
            xi = self.A @ xi + self.B @ uk
        return np.asarray(ys), np.asarray(xs)

    def to_dict(self) -> dict:
        """JSON-ready: every field, arrays as nested lists (None where unknown)."""
        doc = {
            "format": "jaxbox.state_space/1",
            "model": self.model,
            "step_s": self.step,
            "hold": self.hold,
            "states": list(self.states),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "units": dict(self.units),
            "time": self.time,
            "params": dict(self.params),
            "noise": self.noise,
            "state_note": "A, B, C, D act on xi = x - Gamma1 u; x are the node temperatures",
        }
        for k in _ARRAYS:
            v = getattr(self, k)
            doc[k] = None if v is None else np.asarray(v).tolist()
        return doc

    @classmethod
    def from_dict(cls, doc: Mapping) -> StateSpaceModel:
        """The model of :meth:`to_dict` (or of a saved JSON file)."""
        if doc.get("format") != "jaxbox.state_space/1":
            raise ValueError(
                "not a jaxbox state-space export (no 'format': 'jaxbox.state_space/1')"
            )
        arrays = {k: None if doc[k] is None else np.asarray(doc[k], float) for k in _ARRAYS}
        return cls(
            model=doc["model"],
            step=float(doc["step_s"]),
            hold=doc["hold"],
            states=tuple(doc["states"]),
            inputs=tuple(doc["inputs"]),
            outputs=tuple(doc["outputs"]),
            units=dict(doc["units"]),
            time=doc["time"],
            params=dict(doc["params"]),
            noise=doc["noise"],
            **arrays,
        )

    def save(self, path, format: str | None = None, modelica: str | None = None) -> Path:
        """Write the export to ``path`` in ``format`` (default from the suffix: ``.json``,
        ``.npz``, ``.mo``, ``.py``); ``modelica`` is the text of :func:`modelica_model` (needed
        for that format, which holds the continuous model)."""
        path = Path(path)
        fmt = format or {
            ".json": "json",
            ".npz": "npz",
            ".mo": "modelica",
            ".py": "python-control",
        }.get(path.suffix, "")
        if fmt not in FORMATS:
            raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {format!r}")
        if fmt == "json":
            text = json.dumps(self.to_dict(), indent=1)
        elif fmt == "modelica":
            if modelica is None:
                raise ValueError("the modelica format needs the text of modelica_model()")
            text = modelica
        elif fmt == "python-control":
            text = python_control_script(self)
        else:
            buf = io.BytesIO()
            meta = {k: v for k, v in self.to_dict().items() if k not in _ARRAYS}
            arrays = {
                k: np.asarray(getattr(self, k)) for k in _ARRAYS if getattr(self, k) is not None
            }
            np.savez(buf, meta=np.asarray(json.dumps(meta)), **arrays)
            tmp = path.with_name(path.name + ".part")
            tmp.write_bytes(buf.getvalue())
            tmp.replace(path)
            return path
        tmp = path.with_name(path.name + ".part")
        tmp.write_text(text)
        tmp.replace(path)
        return path

    def to_control(self):
        """A ``control.StateSpace`` (python-control, an optional dependency: ``pip install
        'jaxbox[control]'``) of the standard form, with the step as its ``dt``."""
        try:
            import control
        except ImportError:
            raise ImportError(
                "python-control is not installed: pip install control (or 'jaxbox[control]')"
            ) from None
        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            self.step,
            inputs=list(self.inputs),
            outputs=list(self.outputs),
            states=[f"xi_{s}" for s in self.states],
        )


def read_state_space(path) -> StateSpaceModel:
    """A state space saved as JSON or NPZ by :meth:`StateSpaceModel.save`."""
    path = Path(path)
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            doc = json.loads(str(z["meta"]))
            for k in _ARRAYS:
                doc[k] = z[k] if k in z.files else None
        return StateSpaceModel.from_dict(doc)
    return StateSpaceModel.from_dict(json.loads(path.read_text()))


def _unit(name: str) -> str:
    if name == "one":
        return "1"
    return signal_unit(name) or ""


def to_state_space(result, step: float | str | None = None, *, data=None) -> StateSpaceModel:
    """The discrete-time state space of a fit at ``step`` (seconds or a duration such as
    ``"15min"``; default the fit's), exact for its hold, with the last state estimate of the
    Kalman filter over ``data`` (default: the fit's data; its last regular segment).

    ``result`` is a fit (output error: its noise estimated from its residuals, said in
    ``noise``; maximum likelihood) or a :class:`~jaxbox.forecast.StochasticForm`.
    """
    import pandas as pd

    from ..forecast import stochastic_form

    form = stochastic_form(result)
    model = form.model
    dt = form.step if step is None else _seconds(step)
    sysm = form.system(dt)
    n = model.n_states
    A = sysm.Phi
    B = sysm.G0 + (sysm.Phi - np.eye(n)) @ sysm.G1
    Dd = sysm.D + sysm.C @ sysm.G1
    A_c, B_c, _, _ = model.state_space_numpy({k: form.params[k] for k in model.param_names})
    x = P = time = None
    source = data if data is not None else getattr(result, "data", None)
    if source is not None:
        from ..stochastic._checks import as_data

        source = as_data(source)
        a, b = source.segments[-1]
        if len(source.segments) > 1:
            source = source.slice(source.index[a], source.index[b - 1])
        run = form.filter(source)
        x, P, time = run.m[-1], run.P[-1], str(pd.Timestamp(source.index[-1]))
    units = {s: "°C" for s in model.states}
    units.update({i: _unit(i) for i in model.inputs})
    units.update({o: _unit(o) or "°C" for o in model.outputs})
    return StateSpaceModel(
        model=model.name,
        step=float(dt),
        hold=form.hold,
        states=tuple(model.states),
        inputs=tuple(model.inputs),
        outputs=tuple(model.outputs),
        units=units,
        A=A,
        B=B,
        C=sysm.C,
        D=Dd,
        Phi=sysm.Phi,
        Gamma0=sysm.G0,
        Gamma1=sysm.G1,
        A_c=np.asarray(A_c),
        B_c=np.asarray(B_c),
        Q=sysm.Q,
        R=sysm.R,
        x=x,
        P=P,
        time=time,
        params=dict(form.params),
        noise=form.note,
    )


def _seconds(step) -> float:
    import pandas as pd

    if isinstance(step, int | float | np.integer | np.floating) and not isinstance(step, bool):
        seconds = float(step)
    else:
        try:
            seconds = pd.Timedelta(step).total_seconds()
        except (TypeError, ValueError):
            raise ValueError(
                f"step must be seconds or a duration such as '15min', got {step!r}"
            ) from None
    if not np.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"step must be a positive duration, got {step!r}")
    return seconds


# ---- Modelica -----------------------------------------------------------------------------------

_MODELICA_UNITS = {"J/K": "J/K", "K/W": "K/W", "W/K": "W/K", "m²": "m2", "°C": "degC", "-": "1"}


def _mo_unit(unit: str) -> str:
    return _MODELICA_UNITS.get(unit, unit.replace("²", "2").replace("°C", "degC"))


def _factor(kind: str, value) -> str:
    if kind == "const":
        return repr(float(value))
    return str(value) if kind == "param" else f"(1 - {value})"


def _identifier(name: str) -> str:
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in name)
    return out if out[:1].isalpha() else f"M_{out}"


def modelica_model(model: RCModel, params: Mapping[str, float], name: str | None = None) -> str:
    """The RC network of ``model`` with parameter values ``params`` [SI] as a Modelica model.

    Parameters carry their units (``J/K``, ``K/W``, ``m2``, ``degC``…), every input is a
    ``Modelica.Blocks.Interfaces.RealInput`` (the constant input ``one`` is the literal 1),
    every output a ``RealOutput``; the node temperatures start at ``T_*0``. One energy balance
    per node: ``C*der(T) = Σ (T_other − T)/R + Σ gain·input``; a node held at a constant
    temperature is ``T = T0``.
    """
    net = model.network
    nodes = {node.name for node in net.nodes}
    starts = {node.T0 for node in net.nodes}
    used = [p for p in model.parameters if not p.name.startswith("T_") or p.name in starts]
    lines = [
        f'model {_identifier(name or model.name)} "RC model {model.name} identified by jaxbox"'
    ]
    for p in used:
        desc = (p.description or p.name).replace('"', "'")
        lines.append(
            f'  parameter Real {p.name}(unit="{_mo_unit(p.unit)}") = {float(params[p.name])!r} '
            f'"{desc}";'
        )
    for i in model.inputs:
        if i == "one":
            continue
        lines.append(f'  Modelica.Blocks.Interfaces.RealInput {i}(unit="{_mo_unit(_unit(i))}");')
    for o in model.outputs:
        lines.append(f'  Modelica.Blocks.Interfaces.RealOutput y_{o}(unit="degC");')
    for node in net.nodes:
        lines.append(f'  Real T_{node.name}(start={node.T0}, fixed=true, unit="degC");')
    lines.append("equation")
    for node in net.nodes:
        if node.constant:
            lines.append(f"  T_{node.name} = {node.T0};")
            continue
        terms = []
        for e in net.edges:
            if node.name not in (e.a, e.b):
                continue
            other = e.b if e.a == node.name else e.a
            other = f"T_{other}" if other in nodes else other
            res = [repr(float(e.scale))] if e.scale != 1 else []
            res += [_factor(k, v) for k, v in e.factors]
            res.append(e.R)
            terms.append(f"({other} - T_{node.name})/({' * '.join(res)})")
        for s in net.sources:
            if s.node != node.name:
                continue
            gain = [_factor(k, v) for k, v in s.gain if not (k == "const" and float(v) == 1.0)]
            inp = "1.0" if s.input == "one" else s.input
            terms.append(" * ".join([*gain, inp]))
        lines.append(f"  {node.C}*der(T_{node.name}) = {' + '.join(terms) or '0'};")
    for o in model.outputs:
        lines.append(f"  y_{o} = {o};")
    lines.append(f"end {_identifier(name or model.name)};")
    return "\n".join(lines) + "\n"


def python_control_script(ssm: StateSpaceModel) -> str:
    """A Python file defining the standard form's arrays (``A``, ``B``, ``C``, ``D``, ``dt``,
    names) and ``state_space()``, which returns a ``control.StateSpace`` (python-control)."""

    def arr(a) -> str:
        return "np.array(" + repr(np.asarray(a).tolist()) + ")"

    return "\n".join(
        [
            f'"""Discrete state space of {ssm.model} exported by jaxbox (step {ssm.step:g} s, '
            f"{ssm.hold} hold).",
            "",
            "The state is xi = x - Gamma1 u (x: the node temperatures [°C]); see jaxbox.control.",
            '"""',
            "",
            "import numpy as np",
            "",
            f"dt = {ssm.step!r}",
            f"states = {[f'xi_{s}' for s in ssm.states]!r}",
            f"inputs = {list(ssm.inputs)!r}",
            f"outputs = {list(ssm.outputs)!r}",
            f"units = {dict(ssm.units)!r}",
            f"A = {arr(ssm.A)}",
            f"B = {arr(ssm.B)}",
            f"C = {arr(ssm.C)}",
            f"D = {arr(ssm.D)}",
            f"Gamma1 = {arr(ssm.Gamma1)}",
            f"x = {None if ssm.x is None else arr(ssm.x)}",
            f"P = {None if ssm.P is None else arr(ssm.P)}",
            f"Q = {None if ssm.Q is None else arr(ssm.Q)}",
            f"R = {None if ssm.R is None else arr(ssm.R)}",
            "",
            "",
            "def state_space():",
            '    """A control.StateSpace (python-control) of this model."""',
            "    import control",
            "",
            "    return control.ss(A, B, C, D, dt, inputs=inputs, outputs=outputs, states=states)",
            "",
        ]
    )
