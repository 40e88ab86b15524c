"""Radau IIA collocation: the scheme itself, its order, and agreement with the shooting fit."""

from __future__ import annotations

import numpy as np
import pytest
from _reference import van_loan_states

from jaxbox.data import Dataset
from jaxbox.datasets import twinhouse_exp1
from jaxbox.fit import FitError, fit_model, make_problem
from jaxbox.models import get_model
from jaxbox.reference import (
    MAX_POINTS,
    CollocationResult,
    collocation_fit,
    collocation_simulate,
    radau_iia,
)
from jaxbox.simulate import simulate_model

SQ6 = np.sqrt(6.0)
#: Radau IIA nodes from the literature (Hairer & Wanner, Solving ODEs II, IV.5; 4 and 5 points
#: are the roots of P_s(2x−1) − P_{s−1}(2x−1) to 15 digits).
KNOWN_NODES = {
    1: [1.0],
    2: [1.0 / 3.0, 1.0],
    3: [(4.0 - SQ6) / 10.0, (4.0 + SQ6) / 10.0, 1.0],
    4: [0.088587959512704, 0.409466864440735, 0.787659461760847, 1.0],
    5: [0.057104196114518, 0.276843013638124, 0.583590432368917, 0.860240135656219, 1.0],
}

WELL_IDENTIFIED = ("C_zon", "C_wal", "R_wal", "gA")


def synthetic_inputs(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Hourly weather and a random binary heating sequence (0 / 800 W), n samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 3600.0
    day = 2 * np.pi * t / 86400.0
    T_amb = 8.0 + 4.0 * np.sin(day - 2.0) + 0.2 * np.cumsum(rng.standard_normal(n))
    I_glo = np.maximum(0.0, 450.0 * np.sin(day - np.pi / 2))
    lengths = rng.integers(3, 10, size=n)
    Q = np.repeat(np.arange(n) % 2, lengths)[:n] * 800.0
    return {"T_amb": T_amb, "Q_hea": Q, "I_glo_hor": I_glo}


def synthetic(model_name: str, theta: dict, n: int = 150, noise: float = 0.05, seed: int = 0):
    """(dataset, true θ): outputs simulated exactly, plus white noise [K]."""
    model = get_model(model_name)
    inputs = synthetic_inputs(n, seed)
    t = np.arange(n) * 3600.0
    blank = Dataset.from_arrays(t, {**inputs, "T_zon": np.zeros(n)})
    y = van_loan_states(model, theta, blank)[:, 0]
    y = y + noise * np.random.default_rng(seed + 1).standard_normal(n)
    return blank.with_columns(T_zon=y), theta


ZON = {"C_zon": 5e6, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0}
ZONWAL = {"C_zon": 3e6, "C_wal": 2e7, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0, "T_wal0": 17.0}
#: faster zone dynamics (time constant ~1.4 h at 1 h elements) for the convergence order
ZONWAL_FAST = {**ZONWAL, "C_zon": 1e6, "C_wal": 1e7, "T_wal0": 15.0}


# ---- the Radau IIA scheme ------------------------------------------------------------------------


@pytest.mark.parametrize("n_c", range(1, MAX_POINTS + 1))
def test_radau_nodes_match_the_literature(n_c: int) -> None:
    rad = radau_iia(n_c)
    np.testing.assert_allclose(rad.c, KNOWN_NODES[n_c], rtol=0, atol=1e-14)
    assert rad.c[-1] == 1.0
    assert rad.order == 2 * n_c - 1 and rad.stage_order == n_c


def test_radau_tableaux_match_the_literature() -> None:
    np.testing.assert_allclose(radau_iia(2).A, [[5 / 12, -1 / 12], [3 / 4, 1 / 4]], atol=1e-15)
    b3 = [(16 - SQ6) / 36, (16 + SQ6) / 36, 1 / 9]
    np.testing.assert_allclose(radau_iia(3).b, b3, atol=1e-15)
    a3 = [
        [(88 - 7 * SQ6) / 360, (296 - 169 * SQ6) / 1800, (-2 + 3 * SQ6) / 225],
        [(296 + 169 * SQ6) / 1800, (88 + 7 * SQ6) / 360, (-2 - 3 * SQ6) / 225],
        [(16 - SQ6) / 36, (16 + SQ6) / 36, 1 / 9],
    ]
    np.testing.assert_allclose(radau_iia(3).A, a3, atol=1e-15)


@pytest.mark.parametrize("n_c", range(1, MAX_POINTS + 1))
def test_radau_order_conditions(n_c: int) -> None:
    rad = radau_iia(n_c)
    k = np.arange(1, 2 * n_c)  # B(2 n_c − 1): the quadrature is exact to degree 2 n_c − 2
    np.testing.assert_allclose(rad.b @ rad.c[:, None] ** (k - 1), 1.0 / k, atol=1e-14)
    for q in range(1, n_c + 1):  # C(n_c): stage order n_c
        np.testing.assert_allclose(rad.A @ rad.c ** (q - 1), rad.c**q / q, atol=1e-14)
    np.testing.assert_allclose(rad.A[-1], rad.b, atol=0)  # stiffly accurate
    # the differentiation matrix is the inverse of A on the collocation points ...
    np.testing.assert_allclose(rad.D[:, 1:] @ rad.A, np.eye(n_c), atol=1e-13)
    np.testing.assert_allclose(rad.D.sum(axis=1), 0.0, atol=1e-13)
    # ... and differentiates polynomials of degree ≤ n_c exactly
    for q in range(n_c + 1):
        np.testing.assert_allclose(rad.D @ rad.tau**q, q * rad.c ** max(q - 1, 0), atol=1e-12)


@pytest.mark.parametrize("bad", [0, 6, 2.5, "3"])
def test_radau_rejects_bad_point_counts(bad) -> None:
    with pytest.raises(ValueError, match="n_c must be an integer from 1 to 5"):
        radau_iia(bad)


# ---- order of convergence ------------------------------------------------------------------------

SUBDIVISIONS = (1, 2, 4, 8)


@pytest.fixture(scope="module")
def order_data():
    """The order problem (ZonWal, fast zone dynamics, two days of the agreement tests' inputs),
    its exact states at the samples and the collocation states for n_c = 1, 2, 3 and 1, 2, 4, 8
    elements per sample interval."""
    data, _ = synthetic("ZonWal", ZONWAL, n=48)
    theta = ZONWAL_FAST
    model = get_model("ZonWal")
    exact = van_loan_states(model, theta, data)
    xs = {
        n_c: [
            collocation_simulate(model, theta, data, n_c=n_c, subdivide=s).x for s in SUBDIVISIONS
        ]
        for n_c in (1, 2, 3)
    }
    return model, theta, data, exact, xs


def observed_orders(errors: np.ndarray) -> np.ndarray:
    """log2 of the error ratio between successive halvings of the element length."""
    return np.log2(errors[:-1] / errors[1:])


@pytest.mark.parametrize("n_c", [1, 2, 3])
def test_state_error_shrinks_at_the_radau_order(order_data, n_c: int) -> None:
    *_, exact, xs = order_data
    errors = np.array([np.max(np.abs(x - exact)) for x in xs[n_c]])
    theory = 2 * n_c - 1
    orders = observed_orders(errors)
    # asymptotic order from the last halving, and a least-squares slope over the last three
    assert abs(orders[-1] - theory) <= 0.5, (n_c, orders)
    slope = -np.polyfit(np.log(SUBDIVISIONS[1:]), np.log(errors[1:]), 1)[0]
    assert abs(slope - theory) <= 0.5, (n_c, slope)


@pytest.mark.slow
def test_the_radau_order_holds_against_the_adaptive_post_simulation(order_data) -> None:
    """The same orders measured against the adaptive diffrax post-simulation at tight
    tolerances (another reference than the exact solution), as long as the collocation error
    stays well above the diffrax error."""
    model, theta, data, exact, xs = order_data
    ref = simulate_model(model, theta, data, method="diffrax", rtol=1e-12, atol=1e-12).x
    diffrax_error = np.max(np.abs(ref - exact))
    assert diffrax_error < 1e-8
    for n_c in (1, 2, 3):
        errors = np.array([np.max(np.abs(x - ref)) for x in xs[n_c]])
        usable = errors > 1e2 * diffrax_error
        assert usable.sum() >= 3, n_c
        orders = observed_orders(errors[usable])
        assert abs(orders[-1] - (2 * n_c - 1)) <= 0.5, (n_c, orders)


def test_collocation_simulation_nodes() -> None:
    data, _ = synthetic("ZonWal", ZONWAL)
    theta = ZONWAL_FAST
    sim, t_nodes, x_nodes = collocation_simulate("ZonWal", theta, data, n_c=2, nodes=True)
    rad = radau_iia(2)
    assert t_nodes.shape == (149 * 3 + 1,) and x_nodes.shape == (149 * 3 + 1, 2)
    np.testing.assert_allclose(t_nodes[:3], 3600.0 * rad.tau)
    np.testing.assert_array_equal(sim.x, x_nodes[::3])
    np.testing.assert_allclose(sim.x[0], [theta["T_zon0"], theta["T_wal0"]])
    np.testing.assert_array_equal(sim.y[:, 0], sim.x[:, 0])


# ---- agreement with the shooting fit: synthetic data ---------------------------------------------


def _discretisation_error(model, params, data, result=None) -> float:
    """Largest collocation state error at the samples for the parameters (against exact)."""
    exact = van_loan_states(model, params, data)
    x = result.x if result is not None else collocation_simulate(model, params, data).x
    return float(np.max(np.abs(x - exact)))


def _check_agreement(lm, col: CollocationResult, data, rtol: float = 1e-3, atol_T: float = 1e-3):
    model = col.model
    assert col.success, col.message
    assert col.constraint_violation <= 1e-8
    for name in col.free:
        a, b = lm.params[name], col.params[name]
        if model.parameter(name).is_initial_state:
            assert abs(a - b) <= atol_T, (name, a, b)
        elif name in WELL_IDENTIFIED:
            assert abs(a - b) <= rtol * abs(a), (name, a, b)
    # costs within the discretisation error: |Δcost| ≤ 2 √cost ε + ε² with ε the largest
    # collocation state error at either estimate (one output, weight 1)
    eps = max(
        _discretisation_error(model, col.params, data, col),
        _discretisation_error(model, lm.params, data),
    )
    bound = 2 * np.sqrt(lm.cost) * eps + eps**2
    assert abs(col.cost - lm.cost) <= bound + 1e-12 * lm.cost, (col.cost, lm.cost, bound)
    return eps


@pytest.fixture(scope="module", params=["Zon", "ZonWal"])
def synthetic_pair(request):
    name = request.param
    data, theta = synthetic(name, ZON if name == "Zon" else ZONWAL)
    lm = fit_model(name, data, starts=1, rtol=1e-12, atol=1e-12, max_steps=500)
    col = collocation_fit(name, data)
    return name, data, theta, lm, col


def test_synthetic_estimates_agree(synthetic_pair) -> None:
    name, data, theta, lm, col = synthetic_pair
    assert lm.converged
    eps = _check_agreement(lm, col, data)
    assert eps < 1e-4
    # and both recover the truth within the noise
    for k in ("C_zon", "R_wal", "gA"):
        assert abs(col.params[k] - theta[k]) < 0.1 * theta[k]


def test_synthetic_trajectory_matches_the_post_simulation(synthetic_pair) -> None:
    name, data, theta, lm, col = synthetic_pair
    exact = van_loan_states(col.model, col.params, data)
    assert np.max(np.abs(exact - col.x)) < 1e-5
    if name == "ZonWal":  # adaptive diffrax, as the reference study validated (shared compile)
        post = col.post_simulate(rtol=1e-12, atol=1e-12)
        assert np.max(np.abs(post.x - col.x)) < 1e-5
        np.testing.assert_allclose(post.y, col.y, atol=1e-5)


def test_result_reports_the_solve(synthetic_pair) -> None:
    name, data, theta, lm, col = synthetic_pair
    model = get_model(name)
    n, N = model.n_states, len(data)
    problem = make_problem(model, data)
    for field in ("model", "free", "fixed", "guess", "weights", "simulator"):
        assert getattr(col.problem, field) == getattr(problem, field)
    assert col.problem.bounds == problem.bounds
    assert col.x.shape == (N, n) and col.y.shape == (N, 1) and col.t.shape == (N,)
    assert col.x_nodes.shape == ((N - 1) * 4 + 1, n)
    assert col.stats["n_elements"] == N - 1
    assert col.stats["n_constraints"] == n * (1 + 4 * (N - 1))
    assert col.stats["n_variables"] == col.stats["n_constraints"] + len(col.free)
    assert 1 <= col.iterations <= 30
    assert col.constraint_violation_raw <= 1e-8 * max(col.stats["state_scale"])
    assert col.cost == pytest.approx(col.cost_samples, rel=1e-12)
    assert col.history[-1]["constraint_violation"] == pytest.approx(col.constraint_violation)
    assert set(col.timing) == {"setup_s", "solve_s", "total_s"}
    assert col.settings["n_c"] == 3 and col.settings["objective"] == "samples"
    assert "converged" in col.summary() and repr(col).startswith("CollocationResult(")


def test_hessian_choices_reach_the_same_solution(synthetic_pair) -> None:
    name, data, theta, lm, col = synthetic_pair
    for hessian in ("gauss-newton", "exact"):
        other = collocation_fit(name, data, hessian=hessian)
        assert other.success, other.message
        for k in col.free:
            assert other.params[k] == pytest.approx(col.params[k], rel=1e-7, abs=1e-9)
        assert {h["hessian"] for h in other.history} == {hessian}
    # "auto" ends with exact Newton steps
    assert col.history[-1]["hessian"] == "exact"


@pytest.mark.parametrize("synthetic_pair", ["Zon"], indirect=True)
def test_quadrature_objective(synthetic_pair) -> None:
    name, data, theta, lm, col = synthetic_pair
    quad = collocation_fit(name, data, objective="quadrature")
    assert quad.success, quad.message
    assert quad.settings["objective"] == "quadrature"
    # the sample objective is what the fit minimises: the quadrature estimate cannot beat it there
    assert quad.cost_samples >= col.cost_samples * (1 - 1e-12)
    for k in ("C_zon", "R_wal", "gA"):
        assert quad.params[k] == pytest.approx(col.params[k], rel=0.05)


@pytest.mark.parametrize("synthetic_pair", ["Zon"], indirect=True)
def test_estimates_converge_to_the_shooting_estimates(synthetic_pair) -> None:
    """Implicit Euler (one point) has a visible discretisation bias; it shrinks with the element
    length at the method's order (1), and stays within the cost bound at every refinement."""
    name, data, theta, lm, col = synthetic_pair
    coarse = collocation_fit(name, data, n_c=1)
    fine = collocation_fit(name, data, n_c=1, subdivide=4)
    for k in ("C_zon", "R_wal", "gA"):
        e1 = abs(coarse.params[k] / lm.params[k] - 1)
        e4 = abs(fine.params[k] / lm.params[k] - 1)
        assert 1e-4 < e1 and 2.5 < e1 / e4 < 6, (k, e1, e4)
    for res in (coarse, fine):
        _check_agreement(lm, res, data, rtol=np.inf, atol_T=np.inf)


# ---- a problem it cannot solve ends with a status ------------------------------------------------


def test_nonfinite_problem_ends_with_a_status() -> None:
    data, _ = synthetic("Zon", ZON, n=30)
    # a capacity of 0 is refused up front; one of 1e-300 J/K overflows the dynamics
    with pytest.raises(FitError, match="C_zon.*> 0"):
        collocation_fit("Zon", data, fixed={"C_zon": 0.0})
    res = collocation_fit("Zon", data, fixed={"C_zon": 1e-300})
    assert res.status == "nonfinite" and not res.success
    assert "not finite" in res.message


def test_iteration_cap_ends_with_a_status(synthetic_pair) -> None:
    name, data, *_ = synthetic_pair
    res = collocation_fit(name, data, max_iterations=1)
    assert res.status == "max_iterations" and res.iterations == 1
    assert "raise max_iterations" in res.message


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_c": 0}, "n_c must be an integer from 1 to 5"),
        ({"subdivide": 0}, "subdivide must be a positive integer"),
        ({"objective": "integral"}, "unknown objective"),
        ({"hessian": "bfgs"}, "unknown hessian"),
        ({"free": ["C_foo"]}, "has no parameter"),
        ({"fixed": {"C_zon": 1e6}, "free": ["C_zon"]}, "both free and fixed"),
    ],
)
def test_misuse_raises_like_fit(kwargs, match) -> None:
    data, _ = synthetic("Zon", ZON, n=30)
    with pytest.raises(FitError, match=match):
        collocation_fit("Zon", data, **kwargs)


# ---- agreement on the twin house -----------------------------------------------------------------


@pytest.fixture(scope="module", params=["Zon", "ZonWal"])
def twinhouse_pair(request):
    data, _ = twinhouse_exp1("N2").split()  # identification half, hourly
    lm = fit_model(request.param, data, starts=1, rtol=1e-12, atol=1e-12, max_steps=500)
    col = collocation_fit(request.param, data)
    return data, lm, col


@pytest.mark.slow
def test_twinhouse_estimates_agree(twinhouse_pair) -> None:
    data, lm, col = twinhouse_pair
    assert lm.converged
    eps = _check_agreement(lm, col, data)
    assert eps < 1e-5
    assert np.max(np.abs(van_loan_states(col.model, col.params, data) - col.x)) < 1e-5
