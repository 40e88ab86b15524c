"""Detailed synthetic buildings outside the grammar (jaxbox.datasets.make_detailed_zoo)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import jaxbox
from jaxbox.datasets import DetailedBuilding, make_detailed_zoo
from jaxbox.datasets import _detailed as D


@pytest.fixture(scope="module")
def zoo():
    return make_detailed_zoo(4, seed=3)


def test_reproducible_by_seed(zoo):
    again = make_detailed_zoo(4, seed=3)
    for a, b in zip(zoo, again, strict=True):
        pd.testing.assert_frame_equal(a.data.frame, b.data.frame)
        assert a.kpis == b.kpis
    other = make_detailed_zoo(1, seed=4)[0]
    assert other.kpis["hlc"] != zoo[0].kpis["hlc"]


def test_building_k_independent_of_n(zoo):
    two = make_detailed_zoo(2, seed=3)
    for a, b in zip(zoo[:2], two, strict=True):
        assert a.name == b.name
        pd.testing.assert_frame_equal(a.data.frame, b.data.frame)
        assert a.params == b.params


def test_plausible_buildings(zoo):
    for b in zoo:
        assert isinstance(b, DetailedBuilding)
        assert 15 <= b.states <= 20
        assert 40.0 <= b.kpis["hlc"] <= 400.0
        assert b.step in ("10min", "30min", "60min")
        days = (b.data.index[-1] - b.data.index[0]) / pd.Timedelta(days=1)
        assert 9.9 <= days <= 28.1
        cols = set(b.data.columns)
        assert {"T_zon", "T_amb", "I_glo_hor", "Q_hea"} <= cols
        assert cols <= {"T_zon", "T_amb", "I_glo_hor", "I_s", "I_e", "I_w", "Q_hea", "T_bou"}
        assert not b.data.frame.isna().any().any()
        t = b.data.frame["T_zon"]
        assert 10.0 < t.min() and t.max() < 45.0
        tau = b.kpis["time_constants"]
        assert all(x > 0 for x in tau) and len(tau) == b.states
        d = b.to_dict()
        assert d["states"] == b.states and d["hlc_parts"]


def test_hlc_matches_series_conductances(zoo):
    for b in zoo:
        assert b.kpis["hlc"] == pytest.approx(sum(b.hlc_parts.values()), rel=1e-9)


def test_hlc_matches_a_long_steady_run():
    """The static HLC of the matrices equals the heat per kelvin measured at the end of a long
    simulation with constant inputs (exact discretisation, steps of one day)."""
    rng = np.random.default_rng(11)
    net, _, layout = D._draw_envelope(rng)
    h_ven = 40.0
    A, B = net.matrices(h_ven)
    hlc = D.static_hlc(A, net.caps)
    assert hlc == pytest.approx(sum(D.hlc_parts(layout, h_ven).values()), rel=1e-9)
    Phi, G1, G2 = D._foh(A, B, 86400.0)
    u = np.zeros(len(D._INPUTS))
    u[D._INPUTS.index("T_amb")] = 5.0
    u[D._INPUTS.index("T_gnd")] = 5.0
    u[D._INPUTS.index("q_occ")] = 1500.0  # half to the air, half to the internal mass
    x = np.full(len(net.caps), 5.0)
    for _ in range(400):
        x = Phi @ x + G1 @ u
    assert 1500.0 / (x[0] - 5.0) == pytest.approx(hlc, rel=1e-6)


def test_static_hlc_of_a_single_layer_wall():
    net = D._Network()
    air = net.node("air", 1.0e6)
    d, lam, area = 0.2, 0.5, 30.0
    net.layers(air, [(d, lam, 1.8e6, 3)], area, "T_amb", "wall")
    A, _ = net.matrices(25.0)
    u_wall = area / (D.R_SI + d / lam + D.R_SE)
    assert D.static_hlc(A, net.caps) == pytest.approx(u_wall + 25.0, rel=1e-12)
    assert len(net.caps) == 4


def test_foh_is_exact_for_a_ramp():
    """First-order hold against fine stepping of a ramp input."""
    A = np.array([[-1.0e-3, 5.0e-4], [2.0e-4, -4.0e-4]])
    B = np.array([[1.0e-3], [0.0]])
    dt = 3600.0
    Phi, G1, G2 = D._foh(A, B, dt)
    x = np.array([1.0, 0.0])
    u0, u1 = 2.0, 6.0
    exact = Phi @ x + G1 @ [u0] + G2 @ [u1 - u0]
    m = 3600
    h = dt / m
    y = x.copy()
    import scipy.linalg

    E = scipy.linalg.expm(A * h)
    for i in range(m):
        uu = u0 + (u1 - u0) * (i + 0.5) / m
        y = E @ y + np.linalg.solve(A, (E - np.eye(2)) @ B[:, 0]) * uu
    np.testing.assert_allclose(exact, y, rtol=1e-6, atol=1e-8)


def test_sun_position_and_split():
    noon = pd.DatetimeIndex(["2013-09-01 12:10", "2013-09-01 08:00", "2013-09-01 17:00"])
    cosz, az = D.solar_position(noon)
    assert np.degrees(az[0]) == pytest.approx(180.0, abs=5.0)  # south at noon
    assert np.degrees(az[1]) < 150.0 and np.degrees(az[2]) > 210.0  # east, then west
    assert 0.6 < cosz[0] < 0.8  # ~ 90 − 47.85 + 8.2 ≈ 50° elevation
    ghi = np.array([600.0, 200.0, 150.0])
    dni, dhi = D.split_irradiance(ghi, cosz, np.full(3, 244.0))
    assert np.all(dni >= 0) and np.all((dhi >= 0) & (dhi <= ghi))
    np.testing.assert_allclose(dni * cosz + dhi, ghi, rtol=1e-9)


def test_zone_temperature_quantised(zoo):
    for b in zoo:
        t = b.data.frame["T_zon"].to_numpy()
        np.testing.assert_allclose(t * 10.0, np.round(t * 10.0), atol=1e-9)
        assert np.abs(t - b.clean.frame["T_zon"].to_numpy()).max() < 1.0


def test_thermostat_holds_the_setpoint_open_loop_does_not():
    held = make_detailed_zoo(4, seed=5, heating="thermostat", step="60min", days=12.0)
    spread = []
    for b in held:
        assert b.heating == "thermostat" and b.setpoints is not None
        f = b.clean.frame
        sp = D._setpoints(f.index, b.use, *b.setpoints)
        q = f["Q_hea"].to_numpy()
        active = (q > 0) & (q < b.params["Q_max"] - 1.0)
        assert np.all(q >= 0) and np.all(q <= b.params["Q_max"] + 0.1)
        if active.mean() > 0.1:
            dev = f["T_zon"].to_numpy()[active] - sp[active]
            spread.append(float(np.median(np.abs(dev))))
    assert spread and max(spread) < 0.5
    free = make_detailed_zoo(4, seed=5, heating=["prbs", "rolbs"], step="60min", days=12.0)
    for b in free:
        assert b.heating in ("prbs", "rolbs") and b.setpoints is None
        q = b.data.frame["Q_hea"].to_numpy()
        assert len(np.unique(np.round(q, -2))) <= 4  # on/off (with the meter's noise)
        assert b.clean.frame["T_zon"].std() > 2.0 * max(spread)


def test_heating_kinds_drawn():
    kinds = [b.heating for b in make_detailed_zoo(12, seed=0, step="60min", days=10.0)]
    assert kinds.count("thermostat") >= 3
    assert {"prbs", "rolbs"} <= set(kinds)


def test_written_csv_loads(tmp_path, zoo):
    out = tmp_path / "detailed"
    write = jaxbox.datasets.write_zoo(zoo[:2], out)
    keys = json.loads((write / "truth.json").read_text())
    assert [k["name"] for k in keys] == [b.name for b in zoo[:2]]
    assert keys[0]["kpis"]["hlc"] == pytest.approx(zoo[0].kpis["hlc"])
    for b in zoo[:2]:
        data = jaxbox.load(out / f"{b.name}.csv")
        assert list(data.columns) == list(b.data.columns)
        np.testing.assert_allclose(data.frame["T_zon"].to_numpy(), b.data.frame["T_zon"].to_numpy())


def test_bad_arguments():
    with pytest.raises(ValueError, match="steps"):
        make_detailed_zoo(1, step="5min")
    with pytest.raises(ValueError, match="heating"):
        make_detailed_zoo(1, heating="boiler")
    with pytest.raises(ValueError):
        make_detailed_zoo(1, days=60.0)


def test_without_occupancy_the_same_building(zoo):
    quiet = make_detailed_zoo(2, seed=3, occupancy=False)
    for a, b in zip(zoo[:2], quiet, strict=True):
        assert a.structure == b.structure and a.states == b.states
        assert a.params["q_occ_peak"] == b.params["q_occ_peak"]
        assert b.kpis["hlc"] <= a.kpis["hlc"]  # the ventilation at its base rate
        assert b.hlc_parts["ventilation"] == pytest.approx(b.params["H_ven_base"])


def test_revealed_gains_and_ground_are_the_same_building(zoo):
    """``reveal`` measures what the data leave out (the occupancy gains as ``P_ele``, the
    ground's temperature as ``T_gro`` where the floor lies on the ground) without changing the
    building or its other columns."""
    known = make_detailed_zoo(2, seed=3, reveal=("gains", "ground"))
    for a, b in zip(zoo[:2], known, strict=True):
        assert a.kpis["hlc"] == b.kpis["hlc"] and a.structure == b.structure
        for col in a.data.columns:
            np.testing.assert_array_equal(a.data.frame[col], b.data.frame[col])
        gains = b.data.frame["P_ele"].to_numpy()
        assert gains.min() >= 0.0 and gains.max() == pytest.approx(b.params["q_occ_peak"], abs=1)
        assert ("T_gro" in b.data.columns) == ("T_bou" not in a.data.columns)
        if "T_gro" in b.data.columns:  # a ground at a constant temperature
            assert 9.0 <= b.data.frame["T_gro"].iloc[0] <= 13.0
            assert np.ptp(b.data.frame["T_gro"].to_numpy()) == 0.0
    with pytest.raises(ValueError, match="reveal"):
        make_detailed_zoo(1, reveal=("weather",))
