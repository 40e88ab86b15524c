"""Detailed synthetic buildings whose truth lies outside the component grammar.

Each building of :func:`make_detailed_zoo` is a fine resistance–capacitance network of 15–20
states (multi-layer walls and roof, a floor slab to the ground or a measured cellar, an internal
mass, the air and a radiator or a floor heating), driven by real weather (the bundled twin-house
data, Holzkirchen 2013), with the sun on every facade from the solar position and a
direct/diffuse split of the measured global horizontal irradiance, unmeasured occupancy gains on
daily and weekly schedules, ventilation following a schedule, and heating under a PI thermostat
with night setback or an open-loop PRBS/ROLBS. Its measured data are what a monitoring system
records: the zone temperature with white and coloured (AR(1)) noise, quantised to 0.1 K; the
ambient temperature, global horizontal irradiance, at times three vertical facade irradiances;
the heating power; at times a cellar temperature ``T_bou``. No structure of the grammar is the
truth, so these buildings measure how far the search's answers (the heat-loss coefficient
first) can be trusted when the model is necessarily an approximation.

Units: SI inside (s, J/K, W/K, W, m²); temperatures in °C at the data boundary.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence

import numpy as np
import pandas as pd
import scipy.linalg

from ..data._args import check_count, check_real
from ._zoo import HEATING_KINDS, ZooBuilding, _prbs, _rolbs, _weather, write_zoo

__all__ = ["DetailedBuilding", "make_detailed_zoo", "DETAILED_STEPS", "HEATERS"]

#: sampling steps of the detailed buildings [s] and their names
DETAILED_STEPS = {600.0: "10min", 1800.0: "30min", 3600.0: "60min"}
#: heater kinds: a radiator with its own water and steel, or a floor heating in the screed
HEATERS = ("radiator", "floor")
#: site of the bundled weather (Holzkirchen): latitude, longitude [°], time zone [h from UTC]
LATITUDE, LONGITUDE, UTC_OFFSET = 47.85, 11.72, 1.0
#: facades: name → azimuth from north, clockwise [°]
FACADES = {"n": 0.0, "e": 90.0, "s": 180.0, "w": 270.0}
#: volumetric heat capacity of air [J/(m³·K)]
RHO_C_AIR = 1200.0
#: interior and exterior surface resistances [m²·K/W]
R_SI, R_SE = 0.13, 0.04
#: the most states of a building
MAX_STATES = 20
#: ground reflectance
ALBEDO = 0.2
_INPUTS = ("T_amb", "T_gnd", "Q_hea", "I_n", "I_e", "I_s", "I_w", "I_hor", "q_occ")


@dataclasses.dataclass(frozen=True)
class DetailedBuilding(ZooBuilding):
    """One detailed synthetic building and its truth (a :class:`ZooBuilding` with more).

    ``structure`` describes the network (``"detailed: wall 3+2+2, roof 3+2, floor 2+2,
    radiator"``: nodes per layer); ``params`` holds its physical description [SI] (areas,
    U-values, conductances of every element, capacities, heater, schedules); ``kpis["hlc"]``
    is the true heat-loss coefficient [W/K] from the network's matrices (see
    :func:`make_detailed_zoo`), ``kpis["time_constants"]`` every mode's time constant [h].

    Attributes:
        states: number of states of the network.
        heater: ``"radiator"`` or ``"floor"`` (see :data:`HEATERS`).
        use: occupancy schedule, ``"home"`` or ``"office"``.
        setpoints: thermostat (day, night) setpoints [°C], ``None`` in open loop.
        hlc_parts: the true loss [W/K] of each element (walls, roof, floor, windows,
            ventilation), summing to ``kpis["hlc"]``.
        coloured: standard deviation of the AR(1) part of the zone sensor's noise [K] (0 for
            white noise alone); ``noise`` is that of the white part.
    """

    states: int = 0
    heater: str = "radiator"
    use: str = "home"
    setpoints: tuple | None = None
    hlc_parts: dict = dataclasses.field(default_factory=dict)
    coloured: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready truth (no data), with the network's description."""
        out = super().to_dict()
        out.update(
            states=self.states,
            heater=self.heater,
            use=self.use,
            setpoints=None if self.setpoints is None else list(self.setpoints),
            hlc_parts={k: float(v) for k, v in self.hlc_parts.items()},
            coloured=self.coloured,
        )
        return out


# ---- sun ----------------------------------------------------------------------------------------


def solar_position(times: pd.DatetimeIndex, latitude: float = LATITUDE) -> tuple:
    """Cosine of the zenith angle and the azimuth [rad, from north, clockwise] of the sun at
    local standard times (UTC + :data:`UTC_OFFSET`), by Spencer's declination and equation of
    time."""
    doy = np.asarray(times.day_of_year, float)
    hours = np.asarray(times.hour + times.minute / 60.0 + times.second / 3600.0, float)
    g = 2.0 * np.pi * (doy - 1.0 + (hours - 12.0) / 24.0) / 365.0
    decl = (
        0.006918
        - 0.399912 * np.cos(g)
        + 0.070257 * np.sin(g)
        - 0.006758 * np.cos(2 * g)
        + 0.000907 * np.sin(2 * g)
        - 0.002697 * np.cos(3 * g)
        + 0.00148 * np.sin(3 * g)
    )
    eot = 229.18 * (
        0.000075
        + 0.001868 * np.cos(g)
        - 0.032077 * np.sin(g)
        - 0.014615 * np.cos(2 * g)
        - 0.040849 * np.sin(2 * g)
    )  # [min]
    solar = hours - UTC_OFFSET + LONGITUDE / 15.0 + eot / 60.0
    omega = np.radians(15.0 * (solar - 12.0))
    phi = math.radians(latitude)
    cosz = math.sin(phi) * np.sin(decl) + math.cos(phi) * np.cos(decl) * np.cos(omega)
    az = np.arctan2(np.sin(omega), np.cos(omega) * math.sin(phi) - np.tan(decl) * math.cos(phi))
    return cosz, az + np.pi


def split_irradiance(ghi: np.ndarray, cosz: np.ndarray, doy: np.ndarray) -> tuple:
    """Direct normal and diffuse horizontal irradiance [W/m²] of the global horizontal ``ghi``
    by the Erbs correlation (all diffuse with the sun below 5°)."""
    ghi = np.maximum(np.asarray(ghi, float), 0.0)
    i0 = 1367.0 * (1.0 + 0.033 * np.cos(2.0 * np.pi * doy / 365.0))
    up = cosz > math.sin(math.radians(5.0))
    kt = np.where(up, ghi / (i0 * np.maximum(cosz, 0.087)), 0.0)
    kt = np.clip(kt, 0.0, 1.0)
    kd = np.where(
        kt <= 0.22,
        1.0 - 0.09 * kt,
        np.where(
            kt <= 0.8,
            0.9511 - 0.1604 * kt + 4.388 * kt**2 - 16.638 * kt**3 + 12.336 * kt**4,
            0.165,
        ),
    )
    kd = np.where(up, kd, 1.0)
    dhi = kd * ghi
    dni = np.where(up, np.minimum((ghi - dhi) / np.maximum(cosz, 0.087), 1100.0), 0.0)
    return dni, dhi


def facade_irradiance(index: pd.DatetimeIndex, ghi: np.ndarray, dt: float) -> dict:
    """Irradiance [W/m²] on the vertical facades ``n``, ``e``, ``s``, ``w`` (isotropic sky,
    ground reflectance :data:`ALBEDO`) at time stamps that end intervals of ``dt`` [s] (the sun
    at each interval's middle)."""
    mid = index - pd.Timedelta(seconds=dt / 2.0)
    cosz, az = solar_position(mid)
    dni, dhi = split_irradiance(ghi, cosz, np.asarray(mid.day_of_year, float))
    sinz = np.sqrt(np.maximum(1.0 - cosz**2, 0.0))
    out = {}
    for f, azimuth in FACADES.items():
        cos_inc = np.maximum(sinz * np.cos(az - math.radians(azimuth)), 0.0)
        out[f] = dni * cos_inc + 0.5 * dhi + 0.5 * ALBEDO * np.maximum(ghi, 0.0)
    return out


# ---- network ------------------------------------------------------------------------------------


class _Network:
    """Nodes with heat capacities [J/K], conductances between them and to the boundaries
    (``T_amb``, ``T_gnd``) [W/K], and heat inputs (columns of :data:`_INPUTS`)."""

    def __init__(self):
        self.caps: list[float] = []
        self.names: list[str] = []
        self.edges: list[tuple[int, int | str, float]] = []
        self.inject: list[tuple[int, str, float]] = []

    def node(self, name: str, cap: float) -> int:
        self.caps.append(float(cap))
        self.names.append(name)
        return len(self.caps) - 1

    def link(self, i: int, j: int | str, g: float) -> None:
        self.edges.append((i, j, float(g)))

    def heat(self, i: int, column: str, factor: float) -> None:
        self.inject.append((i, column, float(factor)))

    def layers(self, inner: int, layers, area: float, outer: int | str, name: str) -> list[int]:
        """A wall of ``layers`` ``(thickness m, conductivity W/(m·K), ρc J/(m³·K), nodes)``
        from the node ``inner`` (through the interior surface resistance) to ``outer`` (through
        the exterior one when a boundary); each layer cut in equal slices, a node at each
        slice's middle. Returns the nodes (inside out) and the outermost node's conductance to
        ``outer`` [W/K]."""
        nodes = []
        prev, r_prev = inner, R_SI / area
        for k, (d, lam, rc, m) in enumerate(layers):
            r = d / (lam * area) / m
            for s in range(m):
                i = self.node(f"{name}{k + 1}.{s + 1}", rc * d * area / m)
                self.link(prev, i, 1.0 / (r_prev + 0.5 * r))
                nodes.append(i)
                prev, r_prev = i, 0.5 * r
        r_out = R_SE / area if isinstance(outer, str) else 0.0
        self.link(prev, outer, 1.0 / (r_prev + r_out))
        return nodes, 1.0 / (r_prev + r_out)

    def matrices(self, h_ven: float) -> tuple[np.ndarray, np.ndarray]:
        """``(A [1/s], B)`` of ``dx/dt = A x + B u`` (u: :data:`_INPUTS`) with the air (node 0)
        ventilated by ``h_ven`` [W/K] to the ambient."""
        n = len(self.caps)
        K = np.zeros((n, n))
        Bq = np.zeros((n, len(_INPUTS)))
        for i, j, g in [*self.edges, (0, "T_amb", h_ven)]:
            K[i, i] += g
            if isinstance(j, str):
                Bq[i, _INPUTS.index(j)] += g
            else:
                K[j, j] += g
                K[i, j] -= g
                K[j, i] -= g
        for i, col, f in self.inject:
            Bq[i, _INPUTS.index(col)] += f
        c = np.asarray(self.caps)
        return -K / c[:, None], Bq / c[:, None]


def _foh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple:
    """Exact first-order-hold discretisation: ``x⁺ = Φ x + Γ1 u_k + Γ2 (u_{k+1} − u_k)``."""
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n] = A * dt
    M[:n, n : n + m] = B * dt
    M[n : n + m, n + m :] = np.eye(m)
    F = scipy.linalg.expm(M)
    return F[:n, :n], F[:n, n : n + m], F[:n, n + m :]


def static_hlc(A: np.ndarray, caps: Sequence[float], air: int = 0) -> float:
    """The heat-loss coefficient [W/K] of a network ``dx/dt = A x + …`` with heat capacities
    ``caps`` [J/K]: the heat put into the air per kelvin of its steady rise, every boundary
    held, no other gain (the inverse of the static gain from a heat input at the air node to
    the air temperature)."""
    e = np.zeros(len(caps))
    e[air] = 1.0 / float(caps[air])
    return float(1.0 / np.linalg.solve(-A, e)[air])


# ---- schedules ----------------------------------------------------------------------------------


def _occupancy(index: pd.DatetimeIndex, use: str) -> np.ndarray:
    """Occupancy and appliance gains as a fraction of the peak (0–1) at the times ``index``."""
    h = np.asarray(index.hour + index.minute / 60.0, float)
    weekend = np.asarray(index.day_of_week >= 5)
    if use == "office":
        day = (h >= 8) & (h < 18)
        return np.where(~weekend & day, 1.0, np.where(~weekend & (h >= 7) & (h < 19), 0.4, 0.08))
    night = (h < 6.5) | (h >= 23)
    morning = (h >= 6.5) & (h < 8.5)
    evening = (h >= 17) & (h < 23)
    work = np.where(weekend, 0.7, 0.15)
    return np.where(night, 0.3, np.where(morning, 0.8, np.where(evening, 1.0, work)))


def _setpoints(index: pd.DatetimeIndex, use: str, day: float, night: float) -> np.ndarray:
    """Thermostat setpoints [°C]: ``day`` from 6 to 22 h at home (office: 7 to 19 h on
    weekdays), ``night`` otherwise."""
    h = np.asarray(index.hour + index.minute / 60.0, float)
    if use == "office":
        on = (h >= 7) & (h < 19) & np.asarray(index.day_of_week < 5)
    else:
        on = (h >= 6) & (h < 22)
    return np.where(on, day, night)


def _ar1(n: int, dt: float, sigma: float, tau: float, rng) -> np.ndarray:
    """A stationary AR(1) series of standard deviation ``sigma`` and correlation time ``tau``
    [s] at steps ``dt`` [s]."""
    a = math.exp(-dt / tau)
    e = rng.normal(0.0, sigma * math.sqrt(1.0 - a * a), n)
    out = np.empty(n)
    out[0] = rng.normal(0.0, sigma)
    for k in range(1, n):
        out[k] = a * out[k - 1] + e[k]
    return out


# ---- one building -------------------------------------------------------------------------------


def _weather_at(house: str, dt: float) -> pd.DataFrame:
    """The bundled weather at ``dt`` (30 min: means of three 10-minute intervals, stamped at
    each interval's end)."""
    if dt != 1800.0:
        return _weather(house, dt)
    w = _weather(house, 600.0)
    return w.resample("30min", label="right", closed="right").mean().dropna().round(4)


def _draw_envelope(rng) -> tuple[_Network, dict, dict]:
    """A random house: geometry, constructions, windows, ventilation, heater; returns the
    network (without ventilation, node 0 the air), its parameters [SI] and layout."""
    p: dict[str, float] = {}
    storeys = int(rng.integers(1, 3))
    floor_area = float(rng.uniform(50.0, 220.0))
    footprint = floor_area / storeys
    aspect = float(rng.uniform(1.0, 2.0))
    width = math.sqrt(footprint / aspect)
    length = width * aspect
    height = 2.7 * storeys
    volume = floor_area * 2.5
    p.update(floor_area=floor_area, volume=volume, storeys=storeys)
    # facades: long sides south/north or east/west
    ns_long = bool(rng.random() < 0.7)
    sides = {"s": length, "n": length, "e": width, "w": width}
    if not ns_long:
        sides = {"s": width, "n": width, "e": length, "w": length}
    gross = {f: s * height for f, s in sides.items()}
    wwr = {
        "s": float(rng.uniform(0.15, 0.4)),
        "n": float(rng.uniform(0.05, 0.15)),
        "e": float(rng.uniform(0.05, 0.25)),
        "w": float(rng.uniform(0.05, 0.25)),
    }
    win = {f: gross[f] * wwr[f] for f in FACADES}
    opaque = {f: gross[f] - win[f] for f in FACADES}
    wall_area = sum(opaque.values())
    # constructions (thickness m, conductivity W/(m·K), ρc J/(m³·K)); nodes per layer later
    heavy = bool(rng.random() < 0.6)
    wall = [
        (
            float(rng.uniform(0.15, 0.3)),
            float(rng.uniform(0.4, 1.6) if heavy else rng.uniform(0.13, 0.25)),
            float(rng.uniform(1.4e6, 2.0e6) if heavy else rng.uniform(0.5e6, 0.9e6)),
        ),
        (float(rng.uniform(0.04, 0.2)), float(rng.uniform(0.032, 0.045)), 4.0e4),
    ]
    if rng.random() < 0.5:  # a render or a brick leaf outside
        wall.append((float(rng.uniform(0.02, 0.12)), 0.8, 1.6e6))
    roof = [
        (
            float(rng.uniform(0.02, 0.2)),
            float(rng.uniform(0.13, 1.8)),
            float(rng.uniform(0.6e6, 2.0e6)),
        ),
        (float(rng.uniform(0.08, 0.3)), float(rng.uniform(0.032, 0.045)), 4.0e4),
    ]
    floor_layers = [(float(rng.uniform(0.05, 0.08)), 1.3, 2.0e6)]  # screed
    floor_layers.append((float(rng.uniform(0.15, 0.25)), 1.8, 2.1e6))  # concrete slab
    # nodes per layer (2–4), cut back to MAX_STATES in all
    counts = [[int(rng.integers(2, 5)) for _ in c] for c in (wall, roof, floor_layers)]
    fixed = 3  # air, internal mass, heater (radiator or screed top)
    while fixed + sum(map(sum, counts)) > MAX_STATES:
        flat = [(c, i, j) for i, row in enumerate(counts) for j, c in enumerate(row)]
        c, i, j = max(flat)
        counts[i][j] = c - 1
    cellar = bool(rng.random() < 0.3)
    floor_ins = float(rng.uniform(0.0, 0.12))
    r_ground = float(rng.uniform(0.3, 1.0)) + floor_ins / 0.04  # below the slab [m²·K/W]
    heater = HEATERS[int(rng.random() < 0.3)]
    net = _Network()
    air = net.node("air", RHO_C_AIR * volume * float(rng.uniform(2.0, 5.0)))  # air + furniture
    mass = net.node("internal", floor_area * float(rng.uniform(2.0e4, 8.0e4)) * (storeys - 0.5))
    net.link(air, mass, floor_area * storeys * float(rng.uniform(2.0, 5.0)))
    wnodes, g_wall = net.layers(
        air, [(*c, m) for c, m in zip(wall, counts[0], strict=True)], wall_area, "T_amb", "wall"
    )
    rnodes, g_roof = net.layers(
        air, [(*c, m) for c, m in zip(roof, counts[1], strict=True)], footprint, "T_amb", "roof"
    )
    # floor: screed, slab, then insulation and soil (or the cellar ceiling) as a resistance
    fnodes = []
    prev, r_prev = air, R_SI / footprint
    for k, ((d, lam, rc), m) in enumerate(zip(floor_layers, counts[2], strict=True)):
        r = d / (lam * footprint) / m
        for s in range(m):
            i = net.node(f"floor{k + 1}.{s + 1}", rc * d * footprint / m)
            net.link(prev, i, 1.0 / (r_prev + 0.5 * r))
            fnodes.append(i)
            prev, r_prev = i, 0.5 * r
    net.link(prev, "T_gnd", 1.0 / (r_prev + r_ground / footprint))
    # windows: a conductance to the ambient; sun through the glass onto floor, mass and air
    u_win = float(rng.uniform(0.8, 2.8))
    shade = float(rng.uniform(0.4, 0.9))  # obstruction, reveals, curtains
    g_win = float(rng.uniform(0.35, 0.65)) * 0.75 * shade  # a quarter frame
    win_area = sum(win.values())
    net.link(air, "T_amb", u_win * win_area)
    to_floor = float(rng.uniform(0.3, 0.6))
    to_air = float(rng.uniform(0.1, 0.3))
    for f in FACADES:
        ga = g_win * win[f]
        net.heat(fnodes[0], f"I_{f}", ga * to_floor)
        net.heat(air, f"I_{f}", ga * to_air)
        net.heat(mass, f"I_{f}", ga * (1.0 - to_floor - to_air))
        p[f"A_win_{f}"] = win[f]
    # sun absorbed on the opaque envelope
    alpha_wall, alpha_roof = float(rng.uniform(0.3, 0.7)), float(rng.uniform(0.5, 0.9))
    # (the sol-air temperature T_amb + α I R_se seen through the outermost conductance)
    for f in FACADES:
        net.heat(wnodes[-1], f"I_{f}", alpha_wall * R_SE * g_wall * opaque[f] / wall_area)
    net.heat(rnodes[-1], "I_hor", alpha_roof * R_SE * g_roof)
    # occupancy: half to the air, half to the internal mass
    net.heat(air, "q_occ", 0.5)
    net.heat(mass, "q_occ", 0.5)
    # heater
    if heater == "radiator":
        cap = floor_area * float(rng.uniform(1.0e3, 3.0e3))
        rad = net.node("radiator", cap)
        g_rad = cap / float(rng.uniform(15 * 60.0, 45 * 60.0))
        conv = float(rng.uniform(0.6, 0.8))
        net.link(rad, air, g_rad * conv)
        net.link(rad, mass, g_rad * (1.0 - conv))
        net.heat(rad, "Q_hea", 1.0)
    else:  # water pipes in the screed, with their own water
        pipes = net.node("pipes", floor_area * float(rng.uniform(300.0, 800.0)))
        net.link(pipes, fnodes[0], floor_area * float(rng.uniform(20.0, 60.0)))
        net.heat(pipes, "Q_hea", 1.0)
    p.update(
        wall_area=wall_area,
        roof_area=footprint,
        floor_area_ground=footprint,
        window_area=win_area,
        U_window=u_win,
        g_window=g_win,
        alpha_wall=alpha_wall,
        alpha_roof=alpha_roof,
        R_ground=r_ground,
        heavy=float(heavy),
    )
    layout = {
        "counts": counts,
        "wall": wall,
        "roof": roof,
        "floor": floor_layers,
        "cellar": cellar,
        "heater": heater,
        "win_area": win_area,
        "u_win": u_win,
        "r_ground": r_ground,
        "wall_area": wall_area,
        "footprint": footprint,
    }
    return net, p, layout


def _series_u(layers, area: float, outside: float) -> float:
    """Conductance [W/K] of layers ``(d, λ, ρc)`` in series with the surface resistances."""
    r = R_SI + sum(d / lam for d, lam, _ in layers) + outside
    return area / r


def hlc_parts(layout: dict, h_ven: float) -> dict[str, float]:
    """The steady loss [W/K] of every element, by series resistances (independent of the
    network's matrices)."""
    return {
        "walls": _series_u(layout["wall"], layout["wall_area"], R_SE),
        "roof": _series_u(layout["roof"], layout["footprint"], R_SE),
        "floor": _series_u(layout["floor"], layout["footprint"], layout["r_ground"]),
        "windows": layout["u_win"] * layout["win_area"],
        "ventilation": h_ven,
    }


def _building(k: int, name: str, rng, opts) -> DetailedBuilding:
    from ..data import Dataset

    step = opts["step"]
    if isinstance(step, list | tuple):  # hourly and half-hourly mostly
        weights = np.array([{"10min": 0.15, "30min": 0.35, "60min": 0.5}.get(s, 1.0) for s in step])
        step = step[int(rng.choice(len(step), p=weights / weights.sum()))]
    dt = float(pd.Timedelta(step) / pd.Timedelta(seconds=1))
    if dt not in DETAILED_STEPS:
        raise ValueError(f"make_detailed_zoo steps are 10min, 30min or 60min; got {step!r}")
    kinds = opts["heating"]
    if isinstance(kinds, list | tuple):
        pk = np.array([0.4 if c == "thermostat" else 0.3 for c in kinds])
        kind = str(kinds[int(rng.choice(len(kinds), p=pk / pk.sum()))])
    else:
        kind = str(kinds)
    if kind not in HEATING_KINDS:
        raise ValueError(f"unknown heating kind {kind!r}; choose from {HEATING_KINDS}")
    days = opts["days"]
    if days is None:
        days = float(rng.uniform(10.0, 28.0)) if dt > 600.0 else float(rng.uniform(10.0, 14.0))
    house = str(("N2", "O5")[int(rng.integers(2))])
    use = "office" if rng.random() < 0.3 else "home"
    # share of a week ventilated at the higher level
    a_week = pd.date_range("2013-09-02", periods=int(7 * 86400 / dt), freq=f"{int(dt)}s")
    on = 1.0 if opts["occupancy"] else 0.0
    week = float(np.mean(on * _occupancy(a_week + pd.Timedelta(seconds=dt / 2.0), use) > 0.5))
    # the house: redrawn until its loss is plausible
    for _ in range(200):
        net, p, layout = _draw_envelope(rng)
        ach_base = float(rng.uniform(0.1, 0.4))
        ach_extra = float(rng.uniform(0.1, 0.6))
        h_base = RHO_C_AIR * p["volume"] * ach_base / 3600.0
        h_extra = RHO_C_AIR * p["volume"] * ach_extra / 3600.0
        h_mean = h_base + h_extra * week
        parts = hlc_parts(layout, h_mean)
        if 40.0 <= sum(parts.values()) <= 400.0:
            break
    else:  # pragma: no cover - the ranges above make this practically impossible
        raise RuntimeError("no plausible detailed building")
    # weather window, with a warm-up of 5 days before the data
    weather = _weather_at(house, dt)
    n = int(round(days * 86400.0 / dt)) + 1
    warm = int(round(5 * 86400.0 / dt))
    if n + warm > len(weather):
        raise ValueError(f"days={days} with a 5-day warm-up exceeds the weather's {len(weather)}")
    first = int(rng.integers(0, len(weather) - n - warm + 1))
    w = weather.iloc[first : first + n + warm]
    index = w.index
    N = len(index)
    mid = index - pd.Timedelta(seconds=dt / 2.0)
    occ = on * _occupancy(mid, use)
    # ventilation levels per interval: the base, and the base plus the extra while occupied
    vent = (occ > 0.5).astype(int)
    h_ven = (h_base, h_base + h_extra)
    # the truth: the network at the mean ventilation of the data's window
    h_mean = h_base + h_extra * float(np.mean(vent[warm + 1 :]))
    A_mean, B_mean = net.matrices(h_mean)
    hlc = static_hlc(A_mean, net.caps)
    parts = hlc_parts(layout, h_mean)
    # inputs at the time stamps
    ghi = np.maximum(w["I_glo_hor"].to_numpy(float), 0.0)
    sun = facade_irradiance(index, ghi, dt)
    t_amb = w["T_amb"].to_numpy(float)
    if layout["cellar"]:  # an unheated cellar: the ambient smoothed over 2–5 days, warmer
        tau = float(rng.uniform(2.0, 5.0)) * 86400.0
        a = math.exp(-dt / tau)
        t_gnd = np.empty(N)
        t_gnd[0] = float(np.mean(t_amb[: max(1, int(86400 / dt))])) + 4.0
        lift = float(rng.uniform(3.0, 7.0))
        for i in range(1, N):
            t_gnd[i] = a * t_gnd[i - 1] + (1 - a) * (t_amb[i] + lift)
    else:
        t_gnd = np.full(N, float(rng.uniform(9.0, 13.0)))
    peak = p["floor_area"] * float(rng.uniform(2.0, 6.0))  # [W]
    q_occ = on * peak * _occupancy(index, use)
    U = np.zeros((N, len(_INPUTS)))
    U[:, _INPUTS.index("T_amb")] = t_amb
    U[:, _INPUTS.index("T_gnd")] = t_gnd
    for f in FACADES:
        U[:, _INPUTS.index(f"I_{f}")] = sun[f]
    U[:, _INPUTS.index("I_hor")] = ghi
    U[:, _INPUTS.index("q_occ")] = q_occ
    # heating
    jq = _INPUTS.index("Q_hea")
    setpoints = sp = None
    qmax = hlc * float(rng.uniform(20.0, 30.0))
    if kind == "thermostat":
        day_sp = round(float(rng.uniform(20.5, 23.0)), 1)
        night_sp = round(day_sp - float(rng.uniform(2.0, 4.0)), 1)
        setpoints = (day_sp, night_sp)
        sp = _setpoints(index, use, day_sp, night_sp)
    else:
        level = hlc * float(rng.uniform(5.0, 10.0))
        if kind == "prbs":
            bit = max(1, int(round(float(rng.uniform(1.0, 4.0)) * 3600.0 / dt)))
            U[:, jq] = np.round(level * _prbs(N, bit, rng), 1)
        else:
            U[:, jq] = np.round(level * _rolbs(N, dt, rng), 1)
    # sensor noise on the zone temperature: white, at times with an AR(1) part
    sigma = float(rng.uniform(0.02, 0.1))
    coloured = float(rng.uniform(0.03, 0.15)) if rng.random() < 0.5 else 0.0
    noise = rng.normal(0.0, sigma, N)
    if coloured:
        noise += _ar1(N, dt, coloured, float(rng.uniform(1.0, 6.0)) * 3600.0, rng)
    # discretisations per ventilation level
    disc = [_foh(*net.matrices(h), dt) for h in h_ven]
    # initial state: steady state of the first day's mean weather with the air at 20 °C
    u0 = U[: max(2, int(86400 / dt))].mean(axis=0)
    u0[jq] = 0.0
    A0, B0 = A_mean, B_mean
    x_free = np.linalg.solve(-A0, B0 @ u0)
    x_q = np.linalg.solve(-A0, B0[:, jq])
    q0 = max(0.0, (20.0 - x_free[0]) / x_q[0])
    x = x_free + q0 * x_q
    kp = hlc * float(rng.uniform(4.0, 10.0))  # [W/K]
    ti = float(rng.uniform(1.0, 4.0)) * 3600.0  # [s]
    integral = q0
    X = np.empty((N, len(x)))
    for i in range(N):
        X[i] = x
        if i == N - 1:
            break
        if kind == "thermostat":
            # PI on the measured air temperature at t_i sets the power at t_{i+1}
            e = sp[min(i + 1, N - 1)] - (x[0] + noise[i])
            q = integral + kp * e
            if 0.0 < q < qmax or (q >= qmax and e < 0) or (q <= 0 and e > 0):
                integral += kp * e * dt / ti
            integral = min(max(integral, 0.0), qmax)
            U[i + 1, jq] = round(min(max(integral + kp * e, 0.0), qmax), 1)
            if i == 0:
                U[0, jq] = U[1, jq]
        Phi, G1, G2 = disc[vent[i + 1] if i + 1 < N else 0]
        x = Phi @ x + G1 @ U[i] + G2 @ (U[i + 1] - U[i])
    # drop the warm-up
    sl = slice(warm, N)
    index = index[sl]
    y = X[sl, 0]
    U = U[sl]
    noise = noise[sl]
    clean_cols = {
        "T_zon": y,
        "T_amb": t_amb[sl],
        "I_glo_hor": w["I_glo_hor"].to_numpy(float)[sl],
    }
    facades = bool(rng.random() < opts["facades"])
    if facades:
        for f in ("s", "e", "w"):
            clean_cols[f"I_{f}"] = U[:, _INPUTS.index(f"I_{f}")]
    clean_cols["Q_hea"] = U[:, jq]
    if layout["cellar"]:
        clean_cols["T_bou"] = t_gnd[sl]
    frame = pd.DataFrame(clean_cols, index=index)
    clean = Dataset(frame)
    measured = frame.copy()
    measured["T_zon"] = np.round(y + noise, 1)  # 0.1 K resolution
    if facades:  # pyranometers: a calibration error of up to 3 %, 1 W/m² resolution
        for f in ("s", "e", "w"):
            gain = 1.0 + float(rng.uniform(-0.03, 0.03))
            measured[f"I_{f}"] = np.round(gain * clean_cols[f"I_{f}"], 0)
    if layout["cellar"]:
        measured["T_bou"] = np.round(t_gnd[sl] + rng.normal(0.0, 0.05, len(index)), 2)
    # the heat meter: 1 % noise, 1 W resolution
    measured["Q_hea"] = np.round(U[:, jq] * (1.0 + rng.normal(0.0, 0.01, len(index))), 0)
    # what a better-instrumented building would add (no random draw: the same building)
    if "gains" in opts["reveal"]:
        measured["P_ele"] = np.round(U[:, _INPUTS.index("q_occ")], 0)
    if "ground" in opts["reveal"] and not layout["cellar"]:
        measured["T_gro"] = np.round(t_gnd[sl], 2)
    data = Dataset(measured)
    A = A_mean
    tau = np.sort(-1.0 / np.linalg.eigvals(A).real)
    counts = layout["counts"]
    desc = (
        f"detailed: wall {'+'.join(map(str, counts[0]))}, roof {'+'.join(map(str, counts[1]))}, "
        f"floor {'+'.join(map(str, counts[2]))}, {layout['heater']}"
    )
    params = dict(p)
    params.update(
        {f"hlc_{k}": v for k, v in parts.items()},
        H_ven_base=h_base,
        H_ven_extra=h_extra,
        q_occ_peak=peak,
        Q_max=qmax if kind == "thermostat" else float(np.max(U[:, jq])),
        C_total=float(np.sum(net.caps)),
    )
    if kind == "thermostat":
        params.update(K_p=kp, T_i=ti)
    return DetailedBuilding(
        name=name,
        data=data,
        structure=desc,
        params=params,
        noise=sigma,
        offset=0.0,
        step=DETAILED_STEPS[dt],
        heating=kind,
        gaps=(),
        outages=(),
        kpis={
            "hlc": hlc,
            "apertures": {},
            "solar_aperture": None,
            "time_constants": [float(t) / 3600.0 for t in tau],
        },
        clean=clean,
        house=house,
        states=len(net.caps),
        heater=layout["heater"],
        use=use,
        setpoints=setpoints,
        hlc_parts=parts,
        coloured=coloured,
    )


def make_detailed_zoo(
    n: int,
    directory: str | os.PathLike | None = None,
    *,
    seed: int = 0,
    step: str | Sequence[str] = ("10min", "30min", "60min"),
    days: float | None = None,
    heating: str | Sequence[str] = HEATING_KINDS,
    facades: float = 0.4,
    occupancy: bool = True,
    reveal: Sequence[str] = (),
    prefix: str = "d",
) -> list[DetailedBuilding]:
    """``n`` detailed synthetic buildings whose truth is outside the component grammar.

    Every building draws from its own random stream (building ``k`` does not depend on ``n``):

    * a house: 50–220 m² of floor on one or two storeys, a rectangular footprint (aspect
      1–2) with its long sides south/north (70 %) or east/west; window-to-wall ratios south
      15–40 %, east and west 5–25 %, north 5–15 %; windows of U 0.8–2.8 W/(m²·K) and g
      0.35–0.65 (a quarter frame), shaded to 40–90 %;
    * walls of a heavy (60 %: 0.15–0.3 m, λ 0.4–1.6 W/(m·K)) or light masonry leaf, 4–20 cm
      of insulation and, half the time, a render or brick leaf outside; a roof of a deck and
      8–30 cm of insulation; a floor of screed and a concrete slab on insulation (0–12 cm) and
      soil (0.3–1 m²·K/W) to a ground at 9–13 °C or (30 %) to an unheated cellar whose
      temperature ``T_bou`` (the ambient smoothed over 2–5 days, 3–7 K warmer) is measured;
      every layer cut into 2–4 nodes, cut back to at most 20 states in all, with the air
      (and furniture, 2–5 times the air's capacity), an internal mass (20–80 kJ/(m²·K)) and
      the heater — 15 to 20 states;
    * the sun: the measured global horizontal irradiance split into direct and diffuse (Erbs)
      at the solar position of Holzkirchen (47.85° N, 11.72° E, time stamps UTC+1) and cast on
      each facade (isotropic sky, ground reflectance 0.2): through the windows onto the floor
      (30–60 %), the air (10–30 %) and the internal mass; absorbed on the opaque walls
      (0.3–0.7) and the roof (0.5–0.9);
    * unmeasured occupancy gains of 2–6 W/m² at their peak, on a home (mornings, evenings,
      weekends) or an office (weekdays 8–18 h) schedule, half to the air, half to the mass;
    * ventilation of 0.1–0.4 air changes per hour, plus 0.1–0.6 while occupied;
    * a radiator (1–3 kJ/(m²·K), time constant 15–45 min, 60–80 % convective) or (30 %) a
      floor heating in the screed;
    * heating: ``"thermostat"`` (40 % of the draws): a PI controller (gain 4–10 W/K per W/K of
      loss, integral time 1–4 h, anti-windup) stepped per sample on the measured zone
      temperature, holding 20.5–23 °C by day (home 6–22 h; office weekdays 7–19 h) and 2–4 K
      less otherwise, the heater saturating at 20–30 K worth of loss; ``"prbs"`` (bits of
      1–4 h) or ``"rolbs"`` (1 h to 60 h) in open loop at 5–10 K worth of loss;
    * the zone sensor: white noise of 0.02–0.1 K plus, half the time, an AR(1) part of
      0.03–0.15 K with a correlation time of 1–6 h, quantised to 0.1 K; the heat meter 1 %
      noise and 1 W resolution; facade pyranometers (``facades``) a gain error of up to 3 %.

    The network is simulated exactly (first-order hold per sample, a matrix exponential per
    ventilation level) over a window of the bundled weather, after a 5-day warm-up from the
    steady state of the first day. The true heat-loss coefficient (``kpis["hlc"]``, 40–400 W/K,
    redrawn otherwise) is the static one of the network's matrices at the mean ventilation with
    every gain off: the heat input per kelvin of steady zone-air rise with the ambient and
    the ground (or cellar) held, :func:`static_hlc`; it equals the sum of the elements' series
    conductances (``hlc_parts``).

    Args:
        n: number of buildings.
        directory: if given, write ``<name>.csv`` per building and the answer keys there (as
            :func:`~jaxbox.datasets.write_zoo`).
        seed: seed of every random draw.
        step: ``"10min"``, ``"30min"``, ``"60min"``, or a list to draw from (weights 15, 35
            and 50 %).
        days: length of each building's data [days]; by default 10–28 days (10–14 at 10 min).
        heating: heating kind, or a list to draw from (see
            :data:`~jaxbox.datasets.HEATING_KINDS`).
        facades: probability of the facade irradiance columns ``I_s``, ``I_e``, ``I_w``.
        occupancy: ``False`` for the same buildings without occupancy gains and with the
            ventilation at its base rate throughout (to measure what the unmeasured gains do).
        reveal: what the data leave unmeasured, measured after all, to show what its absence
            costs (the same buildings otherwise): ``"gains"`` adds the occupancy gains as a
            column ``P_ele`` [W] (token ``Ele``), ``"ground"`` the ground temperature as
            ``T_gro`` [°C] (token ``Gro``) where the floor lies on the ground.
        prefix: names are ``prefix`` + a zero-padded number.

    Returns:
        One :class:`DetailedBuilding` per building.

    Raises:
        ValueError: ``n < 1``, an unknown step, heating kind or ``reveal`` word, or more days
            than the weather holds (about 40 with the warm-up).
    """
    n = check_count(n, "n (buildings)")
    seed = check_count(seed, "seed", 0)
    if days is not None:
        days = check_real(days, "days", "days")
        if not days > 0:
            raise ValueError(f"days must be > 0, got {days}")
    opts = {
        "step": tuple(step) if isinstance(step, list | tuple) else step,
        "days": days,
        "heating": tuple(heating) if isinstance(heating, list | tuple) else heating,
        "facades": float(facades),
        "occupancy": bool(occupancy),
        "reveal": tuple(reveal),
    }
    unknown = set(opts["reveal"]) - {"gains", "ground"}
    if unknown:
        raise ValueError(f"reveal takes 'gains' and 'ground'; got {sorted(unknown)}")
    width = max(3, len(str(int(n) - 1)))
    zoo = []
    for k in range(int(n)):
        rng = np.random.default_rng([int(seed), 1_000_003, k])
        zoo.append(_building(k, f"{prefix}{k:0{width}d}", rng, opts))
    if directory is not None:
        write_zoo(zoo, directory)
    return zoo
