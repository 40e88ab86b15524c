"""A zoo of synthetic test buildings with known truth: random grammar structures, real weather.

Each building of :func:`make_zoo` is a structure of the component grammar
(:mod:`jaxbox.models._grammar`) drawn at random from what its data columns can drive (or chosen),
with physically plausible parameters derived from a heat-loss coefficient, simulated exactly
(first-order hold, as :func:`jaxbox.simulate_model`) over a window of the bundled twin-house
weather (Holzkirchen, 2013; each building its own house and start), with realistic heating
(a thermostat with night setback, a PRBS or a ROLBS; in two-zone buildings one zone held at its
setpoint) and sensor imperfections (white noise, a constant offset, gaps). The true structure,
parameters and KPIs are the answer key.

Units: SI inside (s, J/K, K/W, W, m²); temperatures in °C at the data boundary.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..data._args import check_count, check_real

__all__ = [
    "ZooBuilding",
    "make_zoo",
    "truth_table",
    "write_zoo",
    "ZOO_TRUTH_CSV",
    "ZOO_TRUTH_JSON",
    "HEATING_KINDS",
]

#: answer keys written beside the buildings
ZOO_TRUTH_CSV = "truth.csv"
ZOO_TRUTH_JSON = "truth.json"
"""The answer key as JSON, beside :data:`ZOO_TRUTH_CSV`."""
#: heating kinds of the (first) zone
HEATING_KINDS = ("thermostat", "prbs", "rolbs")
#: sampling steps the zoo knows [s]
_STEPS = {300.0: "5min", 600.0: "10min", 3600.0: "60min"}
#: thermostat: day setpoint, night setpoint [°C], day from/to [h]
DAY_SETPOINT, NIGHT_SETPOINT, DAY_HOURS = 21.0, 17.0, (6, 22)
#: plausible time constants [s]
TAU_RANGE = (600.0, 30 * 86400.0)
_FACADE_COLUMNS = ("I_s", "I_e", "I_w")
_WEATHER = ("T_amb", "T_bou", "I_glo_hor", "I_s", "I_e", "I_w")
#: horizon of the thermostat's mean-level control [s]
_HORIZON = 3600.0


@dataclasses.dataclass(frozen=True)
class ZooBuilding:
    """One synthetic building and its truth.

    Attributes:
        name: building name (``z000``…), also its CSV file's stem.
        data: the measured data (°C, W, W/m²): zone temperature(s) with noise, offset and gaps;
            rows of an outage are rows of NaN (missing from the CSV file).
        structure: canonical grammar name of the true structure (``Zon+Wal+Int``).
        params: true parameters [SI] of ``structure`` built on the data's columns.
        noise: standard deviation of the white noise on the measured zone temperatures [K].
        offset: constant sensor offset on the measured zone temperatures [K].
        step: sampling step (``"5min"``, ``"10min"``, ``"60min"``).
        heating: heating kind of the modelled zone (zone 1 of two): one of
            :data:`HEATING_KINDS`.
        gaps: ``(first, last)`` time stamps of every run of missing zone temperatures (output
            gaps and outages).
        outages: ``(first, last)`` time stamps of every outage (all columns missing).
        kpis: ``hlc`` [W/K], ``apertures`` and ``solar_aperture`` [m²], ``time_constants``
            [h], as :func:`jaxbox.validate.kpi_values`.
        clean: the data without noise, offset or gaps (the exact simulation of the truth).
        house: twin house whose weather drives it (``N2``, ``O5``).
        held_zone: the zone held at a constant setpoint by its own heater (two zones), else
            ``None``.
        setpoint: that zone's setpoint [°C] (``None`` without one).
    """

    name: str
    data: object
    structure: str
    params: dict
    noise: float
    offset: float
    step: str
    heating: str
    gaps: tuple
    outages: tuple
    kpis: dict
    clean: object = dataclasses.field(repr=False, default=None)
    house: str = "N2"
    held_zone: int | None = None
    setpoint: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready truth (no data): structure, parameters [SI], KPIs, imperfections."""
        return {
            "name": self.name,
            "structure": self.structure,
            "params": {k: float(v) for k, v in self.params.items()},
            "kpis": self.kpis,
            "noise": self.noise,
            "offset": self.offset,
            "step": self.step,
            "heating": self.heating,
            "held_zone": self.held_zone,
            "setpoint": self.setpoint,
            "house": self.house,
            "start": str(self.data.index[0]),
            "end": str(self.data.index[-1]),
            "samples": len(self.data),
            "columns": list(self.data.columns),
            "gaps": [[str(a), str(b)] for a, b in self.gaps],
            "outages": [[str(a), str(b)] for a, b in self.outages],
        }


# ---- parameters ---------------------------------------------------------------------------------


def _logu(rng, lo, hi) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _zone_params(structure, z: int, hlc: float, rng, extra_share: float) -> dict[str, float]:
    """Parameters of zone ``z`` with a loss of ``hlc`` [W/K] to the ambient and boundaries
    (``extra_share`` of it to a zone held as a boundary)."""
    from ..models._grammar import is_boundary_token

    s = "" if z == 0 else str(z)
    tok = set(structure.zone_tokens(z))
    bounds = [t for t in tok if is_boundary_token(t)]
    inf = float(rng.uniform(0.1, 0.3)) if "Inf" in tok else 0.0
    bou = {t: float(rng.uniform(0.1, 0.25)) for t in sorted(bounds)}
    wall = 1.0 - inf - sum(bou.values()) - extra_share
    t0 = float(rng.uniform(18.0, 24.0))
    p = {
        f"C_zon{s}": hlc * float(rng.uniform(1.0e4, 3.0e4)),
        f"T_zon{s}0": t0,
        f"R_wal{s}": 1.0 / (hlc * wall),
    }
    if "Wal" in tok:
        p[f"C_wal{s}"] = hlc * float(rng.uniform(1.5e5, 4.0e5))
        p[f"T_wal{s}0"] = t0 - float(rng.uniform(0.0, 4.0))
    if "Inf" in tok:
        p[f"R_inf{s}"] = 1.0 / (hlc * inf)
    if "Int" in tok:
        p[f"C_int{s}"] = hlc * float(rng.uniform(1.0e5, 5.0e5))
        p[f"R_int{s}"] = 1.0 / (hlc * float(rng.uniform(2.0, 8.0)))
        p[f"T_int{s}0"] = t0 - float(rng.uniform(0.0, 2.0))
    for t, share in bou.items():
        base = (t[:-1] if t.endswith("C") else t).lower()
        p[f"R_{base}{s}"] = 1.0 / (hlc * share)
        if t.endswith("C"):
            p[f"C_{base}{s}"] = hlc * float(rng.uniform(5.0e4, 2.0e5))
            p[f"T_{base}{s}0"] = t0 - float(rng.uniform(0.0, 3.0))
    if "Hea" in tok:
        p[f"C_hea{s}"] = _logu(rng, 1.0e5, 1.0e6)
        p[f"R_hea{s}"] = float(rng.uniform(15 * 60.0, 60 * 60.0)) / p[f"C_hea{s}"]
        p[f"T_hea{s}0"] = t0 + float(rng.uniform(0.0, 3.0))
    if "Rad" in tok:
        p[f"fra_rad{s}"] = float(rng.uniform(0.1, 0.9))
    ga = hlc * float(rng.uniform(0.003, 0.012))  # full sun warms the zone by 2–10 K
    win = structure.window(z)
    if win is not None:
        w = rng.dirichlet(np.full(len(win) - 3, 3.0))
        for letter, share in zip(win[3:], w, strict=True):
            p[f"gA_{letter.lower()}{s}"] = ga * float(share)
    else:
        p[f"gA{s}"] = ga
    if "Sol" in tok:
        p[f"fra_sol{s}"] = float(rng.uniform(0.1, 0.9))
    if "Ae" in tok:
        p[f"gA_wal{s}"] = hlc * float(rng.uniform(0.002, 0.008))
    return p


def _draw_params(structure, hlc: float, rng) -> dict[str, float]:
    """Every parameter of ``structure`` for a building losing ``hlc`` [W/K]."""
    p: dict[str, float] = {}
    states = structure.states
    if len(states) == 2:
        share = float(rng.uniform(0.4, 0.7))
        for z, h in zip(states, (hlc * share, hlc * (1.0 - share)), strict=True):
            p.update(_zone_params(structure, z, h, rng, 0.0))
        cpl = [t for z, t in structure.tokens if z == -1]
        if cpl:
            p["R_bou"] = 1.0 / (hlc * float(rng.uniform(0.1, 0.5)))
            if cpl[0] == "CplC":
                p["C_bou"] = hlc * float(rng.uniform(5.0e4, 2.0e5))
                p["T_bou0"] = float(rng.uniform(18.0, 24.0))
    else:
        extra = float(rng.uniform(0.1, 0.25)) if structure.bound_zones else 0.0
        p.update(_zone_params(structure, states[0], hlc, rng, extra))
        if structure.bound_zones:
            p["R_bou"] = 1.0 / (hlc * extra)
    return p


# ---- numerics -----------------------------------------------------------------------------------


def _matrices(model, theta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of ``model`` at ``theta`` (numpy: nothing to compile)."""
    return model.state_space_numpy(theta)[:3]


def _time_constants(A: np.ndarray) -> np.ndarray:
    """τ [s] of every mode, ascending."""
    lam = np.linalg.eigvals(A).real
    return np.sort(-1.0 / lam)


def _kpis(model, theta, A, B, C) -> dict:
    """The KPIs of :func:`jaxbox.validate.kpi_values` in numpy (no compilation)."""
    from ..validate._kpi import kpi_inputs

    heat, solar = kpi_inputs(model)
    jh = [model.inputs.index(u) for u in heat]
    js = [model.inputs.index(u) for u in solar]
    gain = C @ np.linalg.solve(-A, B)
    n_out = C.shape[0]
    out: dict = {"hlc": None, "apertures": {}, "solar_aperture": None}
    if jh:
        Gh = gain[:, jh]
        if len(jh) == 1 and n_out > 1:
            k = int(np.argmax(Gh[:, 0]))

            def solve(rhs):
                return rhs[k] / Gh[k, 0]
        elif len(jh) == n_out:

            def solve(rhs):
                return np.sum(np.linalg.solve(Gh, rhs))
        else:
            pinv = np.linalg.pinv(Gh)

            def solve(rhs):
                return np.sum(pinv @ rhs)

        out["hlc"] = float(solve(np.ones(n_out)))
        out["apertures"] = {u: float(solve(gain[:, j])) for u, j in zip(solar, js, strict=True)}
        if js:
            out["solar_aperture"] = float(sum(out["apertures"].values()))
    out["time_constants"] = [float(t) / 3600.0 for t in _time_constants(A)]
    return out


def _modes(model, theta):
    """``(λ [1/s], T, T⁻¹)`` with ``A = T diag(λ) T⁻¹``, from the symmetric form
    ``K^{1/2} A K^{-1/2} = Q diag(λ) Qᵀ`` (K the heat capacities): ``T = K^{-1/2} Q``."""
    A, _, caps = model.rc_numpy(theta)
    k = np.sqrt(caps)
    S = A * k[:, None] / k
    lam, Q = np.linalg.eigh(0.5 * (S + S.T))
    return lam, Q / k[:, None], Q.T * k


def _phi2(x: np.ndarray) -> np.ndarray:
    """``(eˣ − 1 − x) / x²``, by its series near 0."""
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)
    return np.where(small, 0.5 + x / 6 + x**2 / 24 + x**3 / 120, (np.expm1(xs) - xs) / xs**2)


def _discretize(modes, B, dt):
    """First-order hold (Φ, Γ0, Γ1) as :func:`jaxbox.simulate.discretize_foh`, mode by mode."""
    lam, T, Ti = modes
    x = lam * dt
    TiB = Ti @ B
    Phi = (T * np.exp(x)) @ Ti
    G0 = (T * (np.expm1(x) / lam)) @ TiB
    G1 = (T * (_phi2(x) * dt)) @ TiB
    return Phi, G0, G1


@dataclasses.dataclass
class _Loop:
    """A closed-loop heater: input ``col`` of the model holds output ``out`` at ``setpoint``."""

    col: int
    out: int
    setpoint: np.ndarray  # [°C] per sample
    qmax: float  # [W]


def _simulate(model, theta, u, dt, loops=(), noise=None):
    """Exact FOH simulation, step by step; closed-loop inputs of ``loops`` are written into
    ``u`` (a copy is returned). The controller sees the measured output (``y + noise``) at
    ``t_k`` and sets the power at ``t_{k+1}`` by mean-level control: the power that, held
    constant, brings the zone to the setpoint within :data:`_HORIZON` (clipped to
    [0, ``qmax``], rounded to 0.1 W).

    Returns:
        (y [samples, outputs] without noise, x [samples, states], u).
    """
    A, B, C = _matrices(model, theta)
    modes = _modes(model, theta)
    lam, T, Ti = modes
    Phi, G0, G1 = _discretize(modes, B, dt)
    x0 = np.array([float(theta[m.T0]) for m in model.network.nodes])
    u = np.array(u, dtype=float)
    n = len(u)
    G01 = G0 - G1
    if not loops:  # x_{k+1} = Φ x_k + d_k, mode by mode
        import scipy.signal  # here: its import costs a command that never simulates ~1 s

        drive = u[:-1] @ G01.T + u[1:] @ G1.T
        w = np.vstack([x0, drive]) @ Ti.T  # modal coordinates
        z = np.empty_like(w)
        for i, mu in enumerate(np.exp(lam * dt)):
            z[:, i] = scipy.signal.lfilter([1.0], [1.0, -mu], w[:, i])
        X = z @ T.T
        return X @ C.T, X, u
    # closed loop: the controlled columns start at zero and are set step by step
    cols = [lp.col for lp in loops]
    u[:, cols] = 0.0
    drive = u[:-1] @ G01.T + u[1:] @ G1.T
    E = (T * np.exp(lam * _HORIZON)) @ Ti
    M = (T * (np.expm1(lam * _HORIZON) / lam)) @ Ti @ B
    CE, CM = C @ E, C @ M
    free_u = [u[:, :] @ CM[lp.out] for lp in loops]  # controlled columns are zero here
    gain = [CM[lp.out, lp.col] for lp in loops]
    noise = np.zeros((n, C.shape[0])) if noise is None else noise
    X = np.empty((n, len(x0)))
    x = x0
    for k in range(n):
        X[k] = x
        if k == n - 1:
            break
        for i, lp in enumerate(loops):
            # the power at t_{k+1} that, held for the horizon, brings the measured zone
            # temperature to its setpoint
            target = lp.setpoint[k + 1] - noise[k, lp.out]
            q = (target - CE[lp.out] @ x - free_u[i][k]) / gain[i]
            u[k + 1, lp.col] = round(min(max(q, 0.0), lp.qmax), 1)
            if k == 0:
                u[0, lp.col] = u[1, lp.col]
        x = Phi @ x + drive[k] + G01[:, cols] @ u[k, cols] + G1[:, cols] @ u[k + 1, cols]
    return X @ C.T, X, u


# ---- heating ------------------------------------------------------------------------------------


def _prbs(n: int, steps_per_bit: int, rng) -> np.ndarray:
    """A maximum-length pseudo-random binary sequence (0/1) from a 9-bit LFSR, each bit held
    ``steps_per_bit`` samples, from a random state."""
    state = int(rng.integers(1, 2**9))
    bits = []
    for _ in range(-(-n // steps_per_bit) + 1):
        new = ((state >> 8) ^ (state >> 4)) & 1  # x^9 + x^5 + 1
        state = ((state << 1) | new) & 0x1FF
        bits.append(new)
    return np.repeat(np.asarray(bits, float), steps_per_bit)[:n]


def _rolbs(n: int, dt: float, rng) -> np.ndarray:
    """A randomly ordered logarithmically distributed binary sequence (0/1): on and off
    periods of log-spaced durations (1 h to 60 h, as in the twin-house experiments), each
    duration once per state in random order, repeated."""
    durations = np.geomspace(3600.0, 60 * 3600.0, 7)
    samples = np.maximum(1, np.round(durations / dt)).astype(int)
    out = np.empty(0)
    on = bool(rng.random() < 0.5)
    while len(out) < n:
        ons, offs = rng.permutation(samples), rng.permutation(samples)
        for a, b in zip(ons, offs, strict=True):
            first, second = (a, b) if on else (b, a)
            out = np.concatenate([out, np.full(first, float(on)), np.full(second, float(not on))])
    return out[:n]


def _setback(index: pd.DatetimeIndex) -> np.ndarray:
    """Day/night thermostat setpoints [°C] at the time stamps."""
    hour = index.hour + index.minute / 60.0
    day = (hour >= DAY_HOURS[0]) & (hour < DAY_HOURS[1])
    return np.where(day, DAY_SETPOINT, NIGHT_SETPOINT)


# ---- weather ------------------------------------------------------------------------------------


def _weather(house: str, dt: float) -> pd.DataFrame:
    from ._twinhouse import twinhouse_exp1

    if dt == 3600.0:
        return twinhouse_exp1(house, "1h").frame[list(_WEATHER)]
    frame = twinhouse_exp1(house, "10min").frame[list(_WEATHER)]
    if dt == 600.0:
        return frame
    index = pd.date_range(frame.index[0], frame.index[-1], freq="5min", name="time")
    t0 = frame.index.asi8.astype(float)
    t = index.asi8.astype(float)
    return pd.DataFrame(
        {c: np.round(np.interp(t, t0, frame[c].to_numpy()), 4) for c in frame}, index=index
    )


def _step_seconds(step) -> float:
    seconds = float(pd.Timedelta(step) / pd.Timedelta(seconds=1))
    if seconds not in _STEPS:
        raise ValueError(f"make_zoo steps are 5min, 10min or 60min; got {step!r}")
    return seconds


def _pick(rng, value):
    """A draw from a list/tuple, or the value itself."""
    if isinstance(value, list | tuple):
        return value[int(rng.integers(len(value)))]
    return value


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


# ---- one building -------------------------------------------------------------------------------


def _columns(zones: int, rng, p_bou: float, p_facades: float) -> list[str]:
    if zones == 1:
        cols = ["T_zon", "T_amb", "I_glo_hor", "Q_hea"]
        if rng.random() < p_bou:
            cols.append("T_bou")
    else:
        cols = ["T_zon1", "T_zon2", "T_amb", "I_glo_hor", "Q_hea1", "Q_hea2"]
    if rng.random() < p_facades:
        cols += list(_FACADE_COLUMNS)
    return cols


def _columns_of(structure) -> list[str]:
    """The columns a chosen structure needs (and the held zone's heating)."""
    model = structure.build()
    cols = list(dict.fromkeys([*model.outputs, "T_amb", "I_glo_hor", *model.inputs]))
    for z in structure.bound_zones:
        cols.append(f"Q_hea{z}")
    return cols


def _building(k, name, rng, opts) -> ZooBuilding:
    from ..data import Dataset
    from ..models._grammar import Grammar, parse_structure, random_structure

    dt = _step_seconds(_pick(rng, opts["step"]))
    house = str(_pick(rng, ("N2", "O5")))
    kind = str(_pick(rng, opts["heating"]))
    if kind not in HEATING_KINDS:
        raise ValueError(f"unknown heating kind {kind!r}; choose from {HEATING_KINDS}")
    sigma = opts["noise"]
    sigma = float(rng.uniform(*sigma)) if isinstance(sigma, tuple | list) else float(sigma)
    offset = 0.0
    if rng.random() < opts["offset"]:
        offset = float(rng.uniform(0.1, 0.3) * rng.choice([-1.0, 1.0]))
    if opts["structure"] is not None:
        structure = parse_structure(str(_pick(rng, opts["structure"])))
        columns = _columns_of(structure)
        grammar = Grammar.from_columns(columns)
    else:
        two = 2 in opts["zones"] and (1 not in opts["zones"] or rng.random() < opts["p_two"])
        columns = _columns(2 if two else 1, rng, opts["p_bou"], opts["p_facades"])
        grammar = Grammar.from_columns(columns)
        for _ in range(100):  # one to three components on a single zone, up to two on two
            size = int(rng.integers(0, 3)) if two else int(rng.integers(1, 4))
            structure = random_structure(grammar, rng, size)
            if len(structure.build(grammar).states) <= opts["max_states"]:
                break
    model = structure.build(grammar)
    # parameters: redraw until every time constant is plausible
    for _ in range(100):
        hlc = _logu(rng, 40.0, 400.0)
        theta = _draw_params(structure, hlc, rng)
        A, B, C = _matrices(model, theta)
        tau = _time_constants(A)
        if tau[0] >= TAU_RANGE[0] and tau[-1] <= TAU_RANGE[1]:
            break
    else:  # pragma: no cover - the ranges above make this practically impossible
        raise RuntimeError(f"no plausible parameters for {structure.name}")
    if set(theta) != set(model.param_names):  # pragma: no cover - a grammar change
        raise RuntimeError(
            f"{structure.name}: drew {sorted(theta)} for parameters {sorted(model.param_names)}"
        )
    theta = {n: theta[n] for n in model.param_names}
    # weather window
    weather = _weather(house, dt)
    n = int(round(opts["days"] * 86400.0 / dt)) + 1
    if n > len(weather) or n < 48:
        raise ValueError(f"days={opts['days']} gives {n} samples; the weather holds {len(weather)}")
    first = int(rng.integers(0, len(weather) - n + 1))
    w = weather.iloc[first : first + n]
    index = w.index
    values: dict[str, np.ndarray] = {c: w[c].to_numpy() for c in columns if c in w}
    outputs = list(model.outputs)
    noise = rng.normal(0.0, sigma, (n, len(outputs))) + offset
    # heating of the modelled zone(s)
    held_zone, setpoint, loops = None, None, []
    zones = [z for z in (0, 1, 2) if f"T_zon{z or ''}" in columns]
    main_zone = structure.states[0]
    zhlc = {z: hlc for z in zones}
    if len(structure.states) == 2:
        zhlc = {z: 1.0 / theta[f"R_wal{z}"] for z in structure.states}
    for z in zones:
        col = f"Q_hea{z or ''}"
        if z == main_zone:
            if kind == "thermostat":
                qmax = zhlc[z] * float(rng.uniform(25.0, 35.0))
                loops.append((z, col, _setback(index), qmax))
                values[col] = np.zeros(n)
            else:
                level = zhlc[z] * float(rng.uniform(5.0, 10.0))
                if kind == "prbs":
                    bit = max(1, int(round(float(rng.uniform(1.0, 4.0)) * 3600.0 / dt)))
                    values[col] = np.round(level * _prbs(n, bit, rng), 1)
                else:
                    values[col] = np.round(level * _rolbs(n, dt, rng), 1)
        else:
            held_zone = z
            setpoint = round(float(rng.uniform(19.0, 23.0)), 1)
            qmax = zhlc[z] * float(rng.uniform(25.0, 35.0))
            if z in structure.states:
                loops.append((z, col, np.full(n, setpoint), qmax))
                values[col] = np.zeros(n)
    if held_zone is not None and held_zone in structure.bound_zones:
        values.update(_held_zone(held_zone, setpoint, hlc, values, index, dt, sigma, rng))
    u = np.column_stack([values[c] for c in model.inputs])
    loop_objs = [
        _Loop(model.inputs.index(col), outputs.index(f"T_zon{z or ''}"), sp, qmax)
        for z, col, sp, qmax in loops
    ]
    y, _, u = _simulate(model, theta, u, dt, loop_objs, noise)
    for j, c in enumerate(model.inputs):
        values[c] = u[:, j]
    clean_cols = {c: values[c] for c in columns if c not in outputs}
    clean_cols.update({c: y[:, j] for j, c in enumerate(outputs)})
    clean_cols = {c: clean_cols[c] for c in columns}
    frame = pd.DataFrame(clean_cols, index=index)
    clean = Dataset(frame)
    measured = frame.copy()
    for j, c in enumerate(outputs):
        measured[c] = y[:, j] + noise[:, j]
    # gaps: output values missing for a few hours, an outage of every column for 6–48 h
    missing = np.zeros(n, bool)
    outage = np.zeros(n, bool)
    if rng.random() < opts["gaps"]:
        for _ in range(int(rng.integers(1, 4))):
            length = max(1, int(round(float(rng.uniform(1.0, 6.0)) * 3600.0 / dt)))
            a = int(rng.integers(n // 10, n - n // 10 - length))
            missing[a : a + length] = True
    if rng.random() < opts["gaps"]:
        length = max(2, int(round(float(rng.uniform(6.0, 48.0)) * 3600.0 / dt)))
        length = min(length, n // 4)
        a = int(rng.integers(n // 4, 3 * n // 4 - length))
        outage[a : a + length] = True
    measured.loc[missing, outputs] = np.nan
    measured.loc[outage, :] = np.nan
    data = Dataset(measured.loc[~outage]) if outage.any() else Dataset(measured)
    span = lambda a, b: (index[a], index[b - 1])  # noqa: E731
    return ZooBuilding(
        name=name,
        data=data,
        structure=structure.name,
        params=theta,
        noise=sigma,
        offset=offset,
        step=_STEPS[dt],
        heating=kind,
        gaps=tuple(span(a, b) for a, b in _runs(missing | outage)),
        outages=tuple(span(a, b) for a, b in _runs(outage)),
        kpis=_kpis(model, theta, A, B, C),
        clean=clean,
        house=house,
        held_zone=held_zone,
        setpoint=setpoint,
    )


def _held_zone(z, setpoint, hlc, values, index, dt, sigma, rng) -> dict[str, np.ndarray]:
    """The measured temperature [°C] and heating [W] of zone ``z`` held at ``setpoint`` by its
    thermostat (simulated on its own as a ``Zon+Wal`` zone; the other zone sees it as a measured
    boundary)."""
    from ..models._grammar import parse_structure

    aux = parse_structure("Zon+Wal").build()
    h = hlc * float(rng.uniform(0.5, 1.0))
    theta = _draw_params(parse_structure("Zon+Wal"), h, rng)
    theta["T_zon0"] = setpoint
    theta["T_wal0"] = setpoint - 2.0
    n = len(index)
    cols = {"T_amb": values["T_amb"], "Q_hea": np.zeros(n), "I_glo_hor": values["I_glo_hor"]}
    u = np.column_stack([cols[c] for c in aux.inputs])
    loop = _Loop(aux.inputs.index("Q_hea"), 0, np.full(n, setpoint), h * 30.0)
    noise = rng.normal(0.0, sigma, (n, 1))
    y, _, u = _simulate(aux, theta, u, dt, [loop], noise)
    return {f"T_zon{z}": np.round(y[:, 0] + noise[:, 0], 4), f"Q_hea{z}": u[:, 1]}


# ---- the zoo ------------------------------------------------------------------------------------


def make_zoo(
    n: int,
    directory: str | os.PathLike | None = None,
    *,
    seed: int = 0,
    step: str | Sequence[str] = ("5min", "10min", "60min"),
    days: float = 14.0,
    noise: float | tuple[float, float] = (0.02, 0.2),
    offset: float = 0.3,
    gaps: float = 0.3,
    heating: str | Sequence[str] = HEATING_KINDS,
    zones: Sequence[int] = (1, 2),
    structure: str | Sequence[str] | None = None,
    max_states: int = 4,
    two_zone: float = 0.2,
    boundary: float = 0.4,
    facades: float = 0.4,
    prefix: str = "z",
) -> list[ZooBuilding]:
    """``n`` synthetic buildings of random grammar structures with known truth.

    Every building draws (from its own random stream, so building ``k`` does not depend on
    ``n``): its step, twin house and start day in the weather, heating kind, noise, offset and
    gaps; its columns (always ``T_amb``, ``I_glo_hor`` and the heating; ``T_bou`` and the
    facade irradiances ``I_s``, ``I_e``, ``I_w`` at times; one zone ``T_zon`` or two
    ``T_zon1``, ``T_zon2``); a structure the columns can drive
    (:func:`~jaxbox.models._grammar.random_structure`: one to three components on a single
    zone, up to two on a two-zone root; at most ``max_states`` states); a
    heat-loss coefficient of 40–400 W/K (log-uniform) and every other parameter in plausible
    proportion to it (air 10–30 kJ/K, envelope 150–400 kJ/K, internal mass 100–500 kJ/K per
    W/K of loss; infiltration and boundaries 10–30 % of the loss; heater 0.1–1 MJ/K with a
    time constant of 15–60 min; solar aperture 0.003–0.012 m² per W/K; fractions 0.1–0.9;
    initial zone temperatures 18–24 °C), redrawn until every time constant lies between
    10 min and 30 days.

    Heating: ``"thermostat"`` holds the measured zone temperature at 21 °C from 6 to 22 h and
    17 °C at night (mean-level control over one hour, heater 25–35 K worth of loss, saturating);
    ``"prbs"`` a pseudo-random binary sequence (bits of 1–4 h); ``"rolbs"`` a randomly ordered
    logarithmically distributed binary sequence (1 h to 60 h); both 5–10 K worth of loss. In a
    two-zone building zone 2 is held at a constant setpoint (19–23 °C) by its own heater: a
    state of the model, or (``Bz`` structures) a measured boundary of zone 1.

    Args:
        n: number of buildings.
        directory: if given, write ``<name>.csv`` per building (column ``time`` first; the rows
            of an outage left out) and the answer keys :data:`ZOO_TRUTH_CSV` and
            :data:`ZOO_TRUTH_JSON` there (created if needed).
        seed: seed of every random draw.
        step: ``"5min"``, ``"10min"``, ``"60min"``, or a list to draw from. 5-minute weather
            is interpolated linearly in time from the 10-minute data.
        days: length of each building's data [days] (at most ~40).
        noise: standard deviation of the white noise on the zone temperatures [K], or a
            ``(lo, hi)`` range to draw it from (uniform).
        offset: probability of a constant sensor offset (±0.1–0.3 K) on the zone temperatures.
        gaps: probability of output gaps (1–3 runs of 1–6 h of missing zone temperatures) and,
            independently, of an outage (every column missing for 6–48 h).
        heating: heating kind, or a list to draw from (see :data:`HEATING_KINDS`).
        zones: allowed zone counts, ``(1,)``, ``(2,)`` or ``(1, 2)``.
        structure: a grammar name (``"Zon+Wal"``) or a list to draw from, instead of random
            structures; the columns are those it needs.
        max_states: the most states of a random structure.
        two_zone: probability of a two-zone building when both counts are allowed.
        boundary: probability of a ``T_bou`` column (attic air) in a one-zone building.
        facades: probability of the facade irradiance columns.
        prefix: names are ``prefix`` + a zero-padded number.

    Returns:
        One :class:`ZooBuilding` per building.

    Raises:
        ValueError: ``n < 1``, an unknown step or heating kind, or more days than the weather.
    """
    n = check_count(n, "n (buildings)")
    seed = check_count(seed, "seed", 0)
    days = check_real(days, "days", "days")
    if not days > 0:
        raise ValueError(f"days must be > 0, got {days}")
    zones = tuple(int(z) for z in zones)
    if not zones or not set(zones) <= {1, 2}:
        raise ValueError(f"zones must be a subset of (1, 2), got {zones}")
    opts = {
        "step": tuple(step) if isinstance(step, list | tuple) else step,
        "days": float(days),
        "noise": tuple(noise) if isinstance(noise, list | tuple) else float(noise),
        "offset": float(offset),
        "gaps": float(gaps),
        "heating": tuple(heating) if isinstance(heating, list | tuple) else heating,
        "zones": zones,
        "structure": tuple(structure) if isinstance(structure, list | tuple) else structure,
        "max_states": int(max_states),
        "p_two": float(two_zone),
        "p_bou": float(boundary),
        "p_facades": float(facades),
    }
    width = max(3, len(str(int(n) - 1)))
    zoo = []
    for k in range(int(n)):
        rng = np.random.default_rng([int(seed), k])
        zoo.append(_building(k, f"{prefix}{k:0{width}d}", rng, opts))
    if directory is not None:
        write_zoo(zoo, directory)
    return zoo


def truth_table(zoo: Sequence[ZooBuilding]) -> pd.DataFrame:
    """One row per building (index ``building``): structure, step, heating, noise, offset,
    gaps, ``hlc`` [W/K], ``solar_aperture`` [m²], ``tau1``… [h] and every parameter [SI]."""
    rows = []
    for b in zoo:
        row = {
            "building": b.name,
            "structure": b.structure,
            "step": b.step,
            "heating": b.heating,
            "held_zone": b.held_zone,
            "house": b.house,
            "start": str(b.data.index[0]),
            "noise": b.noise,
            "offset": b.offset,
            "gaps": len(b.gaps),
            "outages": len(b.outages),
            "hlc": b.kpis["hlc"],
            "solar_aperture": b.kpis["solar_aperture"],
        }
        row.update({f"tau{i + 1}": v for i, v in enumerate(b.kpis["time_constants"])})
        row.update(b.params)
        rows.append(row)
    return pd.DataFrame(rows).set_index("building")


def write_zoo(zoo: Sequence[ZooBuilding], directory: str | os.PathLike) -> Path:
    """Write every building as ``<name>.csv`` (``time`` first, outage rows left out) and the
    answer keys :data:`ZOO_TRUTH_CSV` and :data:`ZOO_TRUTH_JSON` into ``directory``."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    for b in zoo:
        frame = b.data.frame
        frame = frame.loc[~frame.isna().all(axis=1)]
        frame.index.name = "time"
        frame.to_csv(out / f"{b.name}.csv")
    truth_table(zoo).to_csv(out / ZOO_TRUTH_CSV)
    text = json.dumps([b.to_dict() for b in zoo], indent=1, default=_json_default)
    (out / ZOO_TRUTH_JSON).write_text(text + "\n", encoding="utf-8")
    return out


def _json_default(x):
    if isinstance(x, np.floating | np.integer):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
