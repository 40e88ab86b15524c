"""Derivatives of the estimates with respect to the data, checked against re-fits."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest
from _reference import van_loan_states

from jaxbox.data import Dataset
from jaxbox.fit import FitError, fit_model, make_problem
from jaxbox.fit._sensitivity import FitSensitivity, fit_sensitivity
from jaxbox.models import get_model
from jaxbox.validate import uncertainty

N = 150
TRUE = {"C_zon": 5e6, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0}
#: tight Levenberg–Marquardt settings for fits whose optimum is differentiated
TIGHT = {"rtol": 1e-12, "atol": 1e-12, "max_steps": 500}


@pytest.fixture(scope="module")
def data() -> Dataset:
    rng = np.random.default_rng(3)
    t = np.arange(N) * 3600.0
    day = 2 * np.pi * t / 86400.0
    inputs = {
        "T_amb": 8.0 + 4.0 * np.sin(day - 2.0) + 0.2 * np.cumsum(rng.standard_normal(N)),
        "Q_hea": np.repeat(np.arange(N) % 2, rng.integers(3, 10, size=N))[:N] * 800.0,
        "I_glo_hor": np.maximum(0.0, 450.0 * np.sin(day - np.pi / 2)),
    }
    blank = Dataset.from_arrays(t, {**inputs, "T_zon": np.zeros(N)})
    y = van_loan_states(get_model("Zon"), TRUE, blank)[:, 0] + 0.1 * rng.standard_normal(N)
    return blank.with_columns(T_zon=y)


@pytest.fixture(scope="module")
def fitted(data):
    result = fit_model("Zon", data, starts=1, **TIGHT)
    assert result.converged
    return result


@pytest.fixture(scope="module")
def sens(fitted) -> FitSensitivity:
    return fit_sensitivity(fitted, inputs=True)


@pytest.fixture(scope="module")
def sens_gn(fitted) -> FitSensitivity:
    return fit_sensitivity(fitted, hessian="gauss-newton")


def refit(result, data, **kw) -> np.ndarray:
    """Re-fit from the optimum (same compiled solve) and return the free estimates.

    Restarted twice from its own result: one Levenberg–Marquardt run stops ~1e-8 (relative)
    short of the optimum, which would swamp the small changes differenced here.
    """
    p = np.asarray([result.params[n] for n in result.free])
    for _ in range(3):
        again = fit_model("Zon", data, starts=p[None], **TIGHT, **kw)
        assert again.converged
        p = np.asarray([again.params[n] for n in again.free])
    return p


def central_difference(result, data, column: str, direction: np.ndarray, delta: float, **kw):
    """d θ̂ / d ε of re-fits to ``data[column] + ε · direction``: central differences at steps
    δ and 2δ, Richardson-extrapolated (the estimates are far from linear in the data)."""
    base = data[column]

    def at(eps):
        return refit(result, data.with_columns(**{column: base + eps * direction}), **kw)

    d1 = (at(delta) - at(-delta)) / (2 * delta)
    d2 = (at(2 * delta) - at(-2 * delta)) / (4 * delta)
    return (4 * d1 - d2) / 3


def test_shapes_and_names(sens, fitted) -> None:
    assert sens.names == fitted.free == ("C_zon", "R_wal", "gA", "T_zon0")
    assert sens.outputs == ("T_zon",) and sens.inputs == ("T_amb", "Q_hea", "I_glo_hor")
    assert sens.values.shape == (4, N, 1) and sens.input_values.shape == (4, N, 3)
    assert sens.held == () and sens.positive_definite and sens.hessian == "exact"
    np.testing.assert_array_equal(sens["gA"], sens.values[2])
    np.testing.assert_allclose(sens.relative()[0], sens.values[0] / fitted.params["C_zon"])
    with pytest.raises(KeyError, match="not a free parameter"):
        sens["C_wal"]
    json.dumps(sens.to_dict())
    assert "hessian='exact'" in repr(sens)


def test_random_measurement_perturbation_matches_refits(sens, fitted, data) -> None:
    v = np.random.default_rng(7).standard_normal(N)
    fd = central_difference(fitted, data, "T_zon", v, delta=0.05)
    predicted = np.asarray(list(sens.predicted_change(v).values()))
    np.testing.assert_allclose(predicted, fd, rtol=1e-4)


def test_single_measurement_matches_refits(sens, fitted, data) -> None:
    k = int(np.argmax(np.abs(sens["C_zon"][:, 0])))  # the sample C_zon rests on most
    e = np.zeros(N)
    e[k] = 1.0
    fd = central_difference(fitted, data, "T_zon", e, delta=0.1)
    np.testing.assert_allclose(sens.values[:, k, 0], fd, rtol=1e-3)


@pytest.mark.parametrize(("column", "size"), [("Q_hea", 50.0), ("T_amb", 0.5)])
def test_input_perturbation_matches_refits(sens, fitted, data, column, size) -> None:
    v = size * np.random.default_rng(11).standard_normal(N)
    fd = central_difference(fitted, data, column, v, delta=0.1)
    du = np.zeros((N, 3))
    du[:, sens.inputs.index(column)] = v
    predicted = np.asarray(list(sens.predicted_change(np.zeros(N), du).values()))
    np.testing.assert_allclose(predicted, fd, rtol=1e-3)


def test_exact_hessian_is_what_refits_reproduce(sens, sens_gn, fitted, data) -> None:
    v = np.random.default_rng(7).standard_normal(N)
    fd = central_difference(fitted, data, "T_zon", v, delta=0.05)
    exact = np.asarray(list(sens.predicted_change(v).values()))
    gn = np.asarray(list(sens_gn.predicted_change(v).values()))
    err_exact = np.max(np.abs(exact - fd) / np.abs(fd))
    err_gn = np.max(np.abs(gn - fd) / np.abs(fd))
    assert err_gn < 0.2  # close: the residuals are small
    assert err_exact < 1e-2 * err_gn


def test_hessian_matches_central_differences(sens, fitted, data) -> None:
    """The exact Hessian of the cost against second differences of an independent simulator."""
    model, free = fitted.model, fitted.free
    y = data["T_zon"]
    p0 = np.asarray([fitted.params[n] for n in free])

    def cost(p):
        theta = {**fitted.params, **dict(zip(free, p, strict=True))}
        e = van_loan_states(model, theta, data)[:, 0] - y
        return np.mean(e * e)

    h = 1e-4 * np.abs(p0)
    H = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            di, dj = np.eye(4)[i] * h[i], np.eye(4)[j] * h[j]
            H[i, j] = (
                cost(p0 + di + dj) - cost(p0 + di - dj) - cost(p0 - di + dj) + cost(p0 - di - dj)
            ) / (4 * h[i] * h[j])
    scale = np.outer(np.abs(p0), np.abs(p0))
    np.testing.assert_allclose(sens.hessian_matrix * scale, H * scale, rtol=1e-5, atol=1e-9)


def test_gauss_newton_covariance_is_the_classic_one(sens_gn, fitted) -> None:
    """With the Gauss–Newton Hessian, Σ_k σ² (dθ̂/dy_k)(dθ̂/dy_k)ᵀ = σ² (JᵀJ)⁻¹."""
    unc = uncertainty(fitted, include_initial_states=True)
    assert unc.free == sens_gn.names
    np.testing.assert_allclose(sens_gn.covariance(unc.sigma2), unc.cov_free, rtol=1e-8)


def test_parameter_on_a_bound_is_held(fitted, data) -> None:
    bounds = {"gA": (3.5, 50.0)}  # the truth (3) and the free optimum lie below
    result = fit_model("Zon", data, starts=1, bounds=bounds, **TIGHT)
    assert result.at_bound()["gA"]
    sens = fit_sensitivity(result)
    assert sens.held == ("gA",)
    np.testing.assert_array_equal(sens["gA"], 0.0)
    v = np.random.default_rng(5).standard_normal(N)
    fd = central_difference(result, data, "T_zon", v, delta=0.05, bounds=bounds)
    predicted = np.asarray(list(sens.predicted_change(v).values()))
    assert abs(fd[2]) < 1e-6 * result.params["gA"]
    np.testing.assert_allclose(predicted[[0, 1, 3]], fd[[0, 1, 3]], rtol=1e-3)


def test_misuse(sens, fitted, data) -> None:
    with pytest.raises(FitError, match="unknown hessian"):
        fit_sensitivity(fitted, hessian="bfgs")
    diffrax_result = types.SimpleNamespace(
        problem=make_problem(get_model("Zon"), data, simulator="diffrax"),
        params=fitted.params,
        data=data,
    )
    with pytest.raises(FitError, match="input derivatives need reverse-mode"):
        fit_sensitivity(diffrax_result, inputs=True)
    with pytest.raises(ValueError, match="dy must have shape"):
        sens.predicted_change(np.zeros(N - 1))
    with pytest.raises(ValueError, match="du must have shape"):
        sens.predicted_change(np.zeros(N), np.zeros((N, 2)))
