"""Validity verdict (bounds, physics, time constants, intervals, convergence), multistart view."""

import dataclasses
import json

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.fit import StartReport, fit_model
from jaxbox.models import get_model
from jaxbox.simulate import simulate_model
from jaxbox.validate import (
    analyse_residuals,
    check_validity,
    heat_loss_coefficients,
    multistart_view,
    time_constants,
    uncertainty,
    validate,
)

N = 200
STEP = 3600.0
TRUTH = {"C_zon": 5e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0}
FREE = ("C_zon", "R_wal", "gA", "T_zon0")


def _data(seed=7, sigma=0.1):
    rng = np.random.default_rng(0)
    t = np.arange(N) * STEP
    day = 2 * np.pi * t / 86400.0
    u = {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, N),
        "Q_hea": 1500.0 * (rng.random(N) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
    }
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(N)})
    y = simulate_model("Zon", TRUTH, clean).y[:, 0]
    return clean.with_columns(T_zon=y + np.random.default_rng(seed).normal(0, sigma, N))


def _start(factor=1.1):
    return np.asarray([[TRUTH[n] * factor for n in FREE]])


@pytest.fixture(scope="module")
def good():
    return fit_model("Zon", _data(), starts=_start())


def test_a_good_fit_is_valid(good):
    v = check_validity(good)
    assert v.valid and bool(v)
    assert v.reasons == ()
    assert v.time_constants == pytest.approx([TRUTH["R_wal"] * TRUTH["C_zon"]], rel=0.05)
    d = v.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["valid"] is True and d["reasons"] == []


def test_parameter_driven_onto_its_bound_is_flagged():
    res = fit_model("Zon", _data(), starts=_start(0.4), bounds={"gA": (0.0, 1.0)})
    assert res.params["gA"] == pytest.approx(1.0, abs=1e-3)
    v = check_validity(res)
    assert not v.valid
    assert v.flagged("at_bound") == ("gA",)
    (reason,) = [r for r in v.reasons if "gA" in r]
    assert "upper bound" in reason


def test_near_a_bound_but_significantly_away_from_it_is_a_warning():
    """gA = 2 with bounds [0, 250]: within 1 % of the lower bound, yet its interval excludes 0."""
    res = fit_model("Zon", _data(sigma=0.02), starts=_start(), bounds={"gA": (0.0, 250.0)})
    assert res.bound_position()["gA"] < 0.01
    v = check_validity(res)
    assert v.valid, v.reasons
    assert any("gA" in w and "excludes the bound" in w for w in v.warnings)
    # without intervals the same position counts against the model
    assert not check_validity(res, check_intervals=False).valid


def test_initial_temperature_pinned_at_its_bound():
    res = fit_model(
        "Zon", _data(), starts=np.asarray([[5e6, 0.01, 2.0, 27.0]]), bounds={"T_zon0": (25.0, 37.0)}
    )
    v = check_validity(res)
    assert not v.valid
    assert "T_zon0" in v.flagged("at_bound")
    (reason,) = [r for r in v.reasons if "T_zon0" in r]
    assert "initial temperature" in reason and "lower bound" in reason and "narrow" in reason


def test_non_physical_values_and_time_constants(good):
    absurd = dataclasses.replace(good, params={**good.params, "C_zon": 1e12, "R_wal": 1e3})
    v = check_validity(absurd, check_intervals=False)
    assert not v.valid
    assert set(v.flagged("non_physical")) == {"C_zon", "R_wal"}
    assert any(f.kind == "time_constant" for f in v.flags)  # τ = 1e15 s, far beyond years
    assert any("years" in r for r in v.reasons)
    negative = dataclasses.replace(good, params={**good.params, "R_wal": -0.01})
    v = check_validity(negative, check_intervals=False)
    assert "R_wal" in v.flagged("non_physical")
    assert any("does not decay" in r for r in v.reasons)


def test_the_physical_limits_grow_with_the_fitted_building(good):
    """A capacity of 2e11 J/K is absurd for a 100 W/K house and physical for a building of
    10 kW/K (the upper limits of C_* and gA* are sized by UA over REFERENCE_HLC, as the
    naming convention's bounds are for a large building); a user's own limits stay as given."""
    from jaxbox.models import REFERENCE_HLC
    from jaxbox.validate import PHYSICAL_LIMITS, physical_limits

    limits, size = physical_limits(good.model, good.params)
    assert size == 1.0 and limits == PHYSICAL_LIMITS
    k = 100.0  # the same building 100 times as large: UA 10 kW/K
    big = {**good.params, "R_wal": good.params["R_wal"] / k, "gA": good.params["gA"] * k}
    big["C_zon"] = 2e11
    ua = 1.0 / big["R_wal"]
    limits, size = physical_limits(good.model, big)
    assert size == pytest.approx(ua / REFERENCE_HLC)
    assert limits["C_"] == pytest.approx((1e3, 1e11 * size)) and limits["R_"] == (0.0, 100.0)
    assert limits["gA"] == pytest.approx((0.0, 500.0 * size))
    large = dataclasses.replace(good, params=big)
    assert "C_zon" not in check_validity(large, check_intervals=False).flagged("non_physical")
    small = dataclasses.replace(good, params={**good.params, "C_zon": 2e11})
    v = check_validity(small, check_intervals=False)
    assert v.flagged("non_physical") == ("C_zon",)
    (reason,) = [r for r in v.reasons if r.startswith("C_zon") and "physical" in r]
    assert "≤ 1e+11 J/K" in reason, reason
    big["C_zon"] = 1e11 * size * 3
    v = check_validity(dataclasses.replace(good, params=big), check_intervals=False)
    (reason,) = [r for r in v.reasons if r.startswith("C_zon") and "physical" in r]
    assert f"{size:.3g} × the reference's" in reason, reason
    v = check_validity(large, limits={"C_": (1e3, 1e11)}, check_intervals=False)
    assert v.flagged("non_physical") == ("C_zon",)
    assert not any("reference's" in r for r in v.reasons)


def test_custom_limits(good):
    v = check_validity(good, limits={"C_zon": (1e7, 1e8)}, check_intervals=False)
    assert v.flagged("non_physical") == ("C_zon",)


def test_fast_time_constant_is_a_warning(good):
    fast = dataclasses.replace(good, params={**good.params, "C_zon": 2e5})  # τ = 2000 s < 1 h
    v = check_validity(fast, check_intervals=False)
    assert v.valid
    assert any("shorter than the sampling step" in w for w in v.warnings)


def test_a_building_that_settles_within_minutes_is_not_valid(good):
    """τ = 200 s as the slowest (here the only) mode: no building settles that fast."""
    fast = dataclasses.replace(good, params={**good.params, "C_zon": 2e4})
    v = check_validity(fast, check_intervals=False)
    assert not v.valid
    assert any("slowest time constant" in r and "3.34 min" in r for r in v.reasons)
    assert any("total heat capacity 2e+04 J/K (C_zon)" in r for r in v.reasons)
    loose = check_validity(
        fast, check_intervals=False, slowest_tau_range=(60.0, 1e8), capacity_range=(1e4, 1e12)
    )
    assert loose.valid


def test_unconverged_optimum_is_invalid(good):
    st = good.starts
    report = dataclasses.replace(st, status=("max_steps",))
    res = dataclasses.replace(good, starts=report, converged=False)
    v = check_validity(res, check_intervals=False)
    assert not v.valid and any("step cap" in r for r in v.reasons)
    failed = dataclasses.replace(
        good, starts=dataclasses.replace(st, status=("nonfinite",)), cost=float("nan")
    )
    v = check_validity(failed)
    assert not v.valid and v.flags[0].kind == "failed"


def test_wide_intervals_are_flagged(good):
    unc = uncertainty(good)
    v = check_validity(good, unc, max_rel_ci=1e-4)
    assert not v.valid
    assert set(v.flagged("wide_interval")) == {"C_zon", "R_wal", "gA"}
    assert check_validity(good, unc, max_rel_ci=10.0).valid


def test_non_white_residuals_are_a_warning(good):
    rng = np.random.default_rng(1)
    e = np.cumsum(rng.standard_normal(N))
    v = check_validity(good, residuals=analyse_residuals(e, output_names=["T_zon"]))
    assert v.valid and any("not white" in w for w in v.warnings)


def test_time_constants_of_two_states():
    model = get_model("ZonWal")
    p = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0, "T_wal0": 15.0}
    tau, lam = time_constants(model, p)
    g = 1 / (0.5 * p["R_wal"])
    A = np.array([[-g / p["C_zon"], g / p["C_zon"]], [g / p["C_wal"], -2 * g / p["C_wal"]]])
    expected = np.sort(-1 / np.linalg.eigvals(A).real)
    np.testing.assert_allclose(tau, expected, rtol=1e-10)
    assert np.all(lam.real < 0)


def _with_starts(res, costs, params=None):
    costs = np.asarray(costs, dtype=float)
    s = len(costs)
    p = np.tile(res.starts.params[res.best], (s, 1)) if params is None else params
    report = StartReport(
        initial=p * 1.3,
        params=p,
        cost=costs,
        steps=np.full(s, 10),
        status=("converged",) * (s - 1) + ("nonfinite",),
    )
    best = report.best_index()
    return dataclasses.replace(res, starts=report, best=best, cost=float(costs[best]))


def test_multistart_view_groups_optima(good):
    c0 = good.cost
    costs = [c0 * 3, c0, c0 * (1 + 1e-6), c0 * 3 * (1 + 1e-7), c0 * 10, c0, float("nan")]
    res = _with_starts(good, costs)
    ms = multistart_view(res)
    assert ms.n_starts == 7 and ms.n_usable == 6
    assert [o.count for o in ms.optima] == [3, 2, 1]
    assert ms.n_at_best == 3 and ms.optima[0].cost == pytest.approx(c0)
    assert ms.fraction_at_best == pytest.approx(0.5)
    assert ms.miss_probability == pytest.approx(0.5**7)
    assert "3 of 7 starts" in ms.text()
    d = ms.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["n_at_best"] == 3 and len(d["optima"]) == 3
    assert all(v == 0 for v in ms.spread_at_best().values())


def test_single_start_at_the_best_cost_warns(good):
    c0 = good.cost
    res = _with_starts(good, [c0, 2 * c0, 3 * c0, 4 * c0, float("nan")])
    ms = multistart_view(res)
    assert ms.n_at_best == 1 and "too small" in ms.text()
    v = check_validity(res, check_intervals=False)
    assert any("only 1 of 5 starts" in w for w in v.warnings)


def test_no_degrees_of_freedom_is_reported(good):
    short = dataclasses.replace(good, data=good.data.slice(end=good.data.index[3]))
    with pytest.raises(ValueError, match="degrees of freedom"):
        uncertainty(short)
    v = check_validity(short)
    assert not v.valid and any("degrees of freedom" in r for r in v.reasons)


# -- the prediction, the heat-loss coefficient and the data are judged too -----------------------


@pytest.fixture(scope="module")
def halves():
    return _data().split()


@pytest.fixture(scope="module")
def fitted_half(halves):
    return fit_model("Zon", halves[0], starts=_start())


def _spiked(valid, size, at=50):
    y = valid["T_zon"]
    y[at] += size
    return valid.with_columns(T_zon=y)


def test_heat_loss_coefficient_of_one_zone_is_one_over_r(good):
    ((name, (ua, output)),) = heat_loss_coefficients(good.model, good.params).items()
    assert (name, output) == ("Q_hea", "T_zon")
    assert ua == pytest.approx(1.0 / good.params["R_wal"], rel=1e-10)


def test_heat_loss_coefficient_of_two_states_against_a_hand_solution():
    """ZonWal: zone and wall in series to ambient, R/2 each: UA = 1/R whatever the capacities."""
    model = get_model("ZonWal")
    p = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.02, "gA": 2.0, "T_zon0": 20.0, "T_wal0": 15.0}
    ((ua, output),) = heat_loss_coefficients(model, p).values()
    assert output == "T_zon" and ua == pytest.approx(50.0, rel=1e-10)


def test_heat_loss_coefficient_through_a_constant_ground_node():
    """Zone to ambient (R_wal) and to a ground held at a constant temperature (R_gro), in
    parallel: UA = 1/R_wal + 1/R_gro; the constant node is left out of the steady state."""
    from jaxbox.models import RCNetwork
    from jaxbox.models import components as c

    net = c.wall(c.zone(RCNetwork("t")), capacity=False).add(c.heating)
    model = c.ground(net, to=None, temperature=9.5).build()
    p = model.defaults() | {"R_wal": 0.01, "R_gro": 0.04}
    ((ua, output),) = heat_loss_coefficients(model, p).values()
    assert output == "T_zon" and ua == pytest.approx(100.0 + 25.0, rel=1e-10)


def test_a_good_fit_with_its_validation_is_valid(fitted_half, halves):
    v = check_validity(fitted_half, validation=validate(fitted_half, halves[1]))
    assert v.valid, v.reasons


@pytest.mark.parametrize(
    ("size", "words"),
    [
        (25.0, ["validation data: 'T_zon' has isolated spikes", "--train/--validate"]),
        (290.0, ["validation RMSE of T_zon", "limit 5 K", "validation data:", "kelvin"]),
    ],
    ids=["spike", "kelvin spike"],
)
def test_a_spike_in_the_validation_data_is_not_valid(fitted_half, halves, size, words):
    validation = validate(fitted_half, _spiked(halves[1], size))
    v = check_validity(fitted_half, validation=validation, check_intervals=False)
    assert not v.valid
    text = " | ".join(v.reasons)
    for word in words:
        assert word in text, text


def test_validation_error_far_above_identification_error(fitted_half, halves):
    """One +25 K sample: 2.5 K validation RMSE, under the 5 K limit but > 10× identification."""
    validation = validate(fitted_half, _spiked(halves[1], 25.0))
    cross, auto = validation.rmse_cross["T_zon"], validation.rmse_auto["T_zon"]
    assert cross / auto > 10 and cross < 5
    v = check_validity(fitted_half, validation=validation, check_data=False, check_intervals=False)
    assert [f.kind for f in v.flags if f.severe] == ["prediction"]
    assert "identification RMSE" in v.reasons[0] and "limit 10×" in v.reasons[0]
    loose = check_validity(
        fitted_half,
        validation=validation,
        check_data=False,
        check_intervals=False,
        max_rmse_ratio=cross / auto * 1.01,
    )
    assert loose.valid


def test_heating_in_kilowatts_is_flagged_by_the_heat_loss_coefficient(halves):
    ident, valid = (h.with_columns(Q_hea=h["Q_hea"] / 1000) for h in halves)
    res = fit_model("Zon", ident, starts=_start() * np.asarray([[1e-3, 1e3, 1, 1]]))
    ua = heat_loss_coefficients(res.model, res.params)["Q_hea"][0]
    assert ua < 1.0
    v = check_validity(res, validation=validate(res, valid), check_data=False)
    assert not v.valid
    (reason,) = [f.message for f in v.flags if f.kind == "heat_loss"]
    assert "below 1 W/K" in reason and "kW" in reason and "--scale Q_hea=1000" in reason
    # and the data check says the same of the data
    v = check_validity(res, check_intervals=False)
    assert any(f.kind == "implausible_data" and "looks like kW" in f.message for f in v.flags)
    (reason,) = [f.message for f in v.flags if f.kind == "capacity"]
    assert "below 1e+05 J/K" in reason and "1000× too small" in reason
    off = check_validity(
        res, check_data=False, ua_range=None, capacity_range=None, check_intervals=False
    )
    assert not any(f.kind in ("heat_loss", "capacity") for f in off.flags)


def test_a_fast_state_pinned_at_its_start_is_a_warning_a_slow_one_a_reason():
    """An unmeasured initial temperature on its bound biases the energy balance only when the
    state remembers it: a heater of 20 min in two weeks of hourly data forgets it at once."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from _reference import synthetic_building

    truth = {"C_zon": 4e6, "C_hea": 2e5, "R_wal": 0.005, "R_hea": 0.006, "gA": 2.0}
    truth.update(T_zon0=20.0, T_hea0=30.0)
    data = synthetic_building(get_model("Zon+Hea"), truth, n=336, seed=2, noise=0.05)
    fast = fit_model("Zon+Hea", data, starts=3, bounds={"T_hea0": (-3.0, 5.0)})
    assert fast.params["T_hea0"] > 4.9  # pinned at its upper bound
    v = check_validity(fast, check_intervals=False)
    assert "T_hea0" not in v.flagged("at_bound")
    assert any("T_hea0" in w and "fast state" in w for w in v.warnings)
    truth = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.01, "gA": 2.0, "T_zon0": 19.0, "T_wal0": 16.0}
    data = synthetic_building(get_model("ZonWal"), truth, n=336, seed=2, noise=0.05)
    slow = fit_model("ZonWal", data, starts=3, bounds={"T_wal0": (-3.0, 5.0)})
    v = check_validity(slow, check_intervals=False)
    assert "T_wal0" in v.flagged("at_bound")


# -- hostile input: refused early, by name ---------------------------------------------------------


def _not_a_fit():
    from jaxbox.stochastic import MLResult

    return object.__new__(MLResult)  # a stochastic fit (no fields needed to be refused)


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda fit, valid: validate(None, valid), ["result must be a FitResult", "None"]),
        (lambda fit, valid: validate(valid, valid), ["result must be a FitResult", "Dataset"]),
        (lambda fit, valid: validate(_not_a_fit(), valid), ["stochastic fit", "intervals()"]),
        (lambda fit, valid: uncertainty(_not_a_fit()), ["stochastic fit", "method='oe'"]),
        (lambda fit, valid: check_validity(None), ["result must be a FitResult"]),
        (lambda fit, valid: validate(fit, valid.frame), ["valid", "DataFrame", "Dataset(frame)"]),
        (lambda fit, valid: validate(fit, {"T_zon": [1.0]}), ["valid", "got a dict"]),
        (lambda fit, valid: validate(fit, fit), ["valid", "got a FitResult"]),
    ],
    ids=["None", "data", "ml", "ml-unc", "verdict-None", "frame", "dict", "fit"],
)
def test_validation_refuses_what_is_not_a_fit_or_data(fitted_half, halves, call, words):
    with pytest.raises(TypeError) as err:
        call(fitted_half, halves[1])
    for word in words:
        assert word in str(err.value), str(err.value)


@pytest.mark.parametrize(
    ("options", "error", "words"),
    [
        ({"rtol": -1.0}, ValueError, ["rtol", "> 0"]),
        ({"rtol": float("nan")}, ValueError, ["rtol", "nan"]),
        ({"atol": 0.0}, ValueError, ["atol", "> 0"]),
        ({"atol": float("inf")}, ValueError, ["atol", "finite"]),
        ({"rtol": "1e-6"}, TypeError, ["rtol", "number"]),
    ],
)
def test_validate_refuses_bad_tolerances(fitted_half, halves, options, error, words):
    """A tolerance of 0, inf or NaN was reported as 'non-finite values … the fit is not usable',
    a negative one accepted, a string refused by float() inside the solver."""
    with pytest.raises(error) as err:
        validate(fitted_half, halves[1], **options)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_validation_data_in_another_time_zone(halves):
    """Naive and zone-aware time stamps cannot be compared: a clear ValidationError, not
    pandas' TypeError; another time zone of the same instants is converted (it failed inside
    the data checks on a mixed index)."""
    from jaxbox.validate import ValidationError

    ident, valid = halves
    utc = Dataset(ident.frame.tz_localize("UTC"))
    fit = fit_model("Zon", utc, starts=_start())
    with pytest.raises(ValidationError, match="naive .*time zone UTC"):
        validate(fit, valid)
    berlin = Dataset(valid.frame.tz_localize("UTC").tz_convert("Europe/Berlin"))
    same = validate(fit, Dataset(valid.frame.tz_localize("UTC")), method="exact")
    other = validate(fit, berlin, method="exact")
    assert other.rmse_cross == same.rmse_cross
    assert str(other.index_cross.tz) == "UTC"


def test_validation_data_missing_a_column_is_a_validation_error(fitted_half, halves):
    from jaxbox.validate import ValidationError

    frame = halves[1].frame.rename(columns={"Q_hea": "P_heat"})
    with pytest.raises(ValidationError, match="no column 'Q_hea'"):
        validate(fitted_half, Dataset(frame))


@pytest.mark.parametrize(
    ("options", "error", "words"),
    [
        ({"max_rel_ci": -1.0}, ValueError, ["max_rel_ci", "> 0"]),
        ({"max_rel_ci": float("nan")}, ValueError, ["max_rel_ci", "nan"]),
        ({"max_rel_ci": "0.5"}, TypeError, ["max_rel_ci"]),
        ({"bound_tol": 0.7}, ValueError, ["bound_tol", "[0, 0.5)"]),
        ({"bound_tol": -0.1}, ValueError, ["bound_tol"]),
        ({"tau_range": (10.0, 1.0)}, ValueError, ["tau_range", "low < high"]),
        ({"tau_range": 5}, TypeError, ["tau_range", "pair"]),
        ({"limits": {"R_": (1.0, 0.0)}}, ValueError, ["limits['R_']"]),
        ({"limits": {"R_": 5}}, TypeError, ["limits['R_']", "pair"]),
        ({"limits": 5}, TypeError, ["limits", "mapping"]),
        ({"max_rmse": float("nan")}, ValueError, ["max_rmse", "nan"]),
        ({"max_rmse": -1.0}, ValueError, ["max_rmse", "> 0"]),
        ({"max_rmse_ratio": -1.0}, ValueError, ["max_rmse_ratio"]),
        ({"rmse_floor": "x"}, TypeError, ["rmse_floor"]),
        ({"ua_range": (1e5, 1.0)}, ValueError, ["ua_range", "low < high"]),
        ({"capacity_range": ("a", 1.0)}, TypeError, ["capacity_range"]),
        ({"slowest_tau_range": (600.0, float("nan"))}, ValueError, ["slowest_tau_range"]),
        ({"residuals": "white"}, TypeError, ["residuals", "analyse_residuals"]),
        ({"check_intervals": "no"}, TypeError, ["check_intervals", "True or False"]),
        ({"data_overrides": 5}, TypeError, ["data_overrides", "mapping"]),
    ],
)
def test_check_validity_refuses_odd_thresholds(good, options, error, words):
    """NaN thresholds passed every check (a valid verdict), negative ones failed every fit or
    none, reversed ranges judged nonsense, strings raised numpy's or Python's messages."""
    with pytest.raises(error) as err:
        check_validity(good, **options)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_check_validity_refuses_another_fits_validation_or_uncertainty(good, fitted_half, halves):
    """A Validation or Uncertainty of another fit was judged as this one's (or AttributeError
    on anything else)."""
    other = validate(fitted_half, halves[1], method="exact")
    with pytest.raises(ValueError, match="validation is of another fit"):
        check_validity(good, validation=other)
    with pytest.raises(TypeError, match="validation must be a Validation"):
        check_validity(good, validation=halves[1])
    with pytest.raises(TypeError, match="uncertainty must be an Uncertainty"):
        check_validity(good, other)
    bare = fit_model("Zon", _data(), starts=_start()[:, [0, 1, 3]], fixed={"gA": 2.0})
    with pytest.raises(ValueError, match="uncertainty is of a fit"):
        check_validity(good, uncertainty(bare))


def test_a_fast_mode_of_a_capacity_on_its_floor_names_it_and_fixed_there_is_a_note():
    """A zone node whose capacity sits on its floor (1e4 J/K) and couples tightly to a heater
    node has a mode of a fraction of a second: the node is merged (massless), not a lag. The
    flag names the capacity (so a reduction that fixes it explains it); with the capacity
    fixed on its floor the mode is a note, not a reason. A fast mode of a node whose capacity
    is not on its floor stays a reason naming nothing."""
    import types

    from jaxbox.validate._verdict import _check_time_constants

    TAU_RANGE = (1.0, 10 * 365.25 * 86400.0)  # check_validity's default

    model = get_model("ZonWal")
    specs = {s.name: s for s in model.parameters}
    lower = specs["C_zon"].lower
    g = 1.0 / 6.5e-5  # [W/K] the zone node's conductances
    A = np.array([[-g / lower, 1.0 / lower], [1.0 / 3e7, -2.0 / 3e7]])
    tau = np.sort(-1.0 / np.linalg.eigvals(A).real)
    assert tau[0] < TAU_RANGE[0]

    def ctx(free, c_zon, position):
        result = types.SimpleNamespace(
            free=free,
            params={"C_zon": c_zon, "C_wal": 3e7},
            bound_position=lambda: {n: position for n in free},
        )
        return types.SimpleNamespace(
            tau=tau,
            tau_range=TAU_RANGE,
            A=A,
            result=result,
            specs=specs,
            bound_tol=1e-3,
            model=model,
        )

    (flag,) = _check_time_constants(ctx(["C_zon", "C_wal"], lower * (1 + 1e-9), 0.0))
    assert flag.parameters == ("C_zon",) and flag.severe and "merged" in flag.message
    (flag,) = _check_time_constants(ctx(["C_wal"], lower * (1 + 1e-9), 0.5))
    assert flag.parameters == ("C_zon",) and not flag.severe
    (flag,) = _check_time_constants(ctx(["C_zon", "C_wal"], lower * (1 + 1e-9), 0.5))
    assert flag.parameters == () and flag.severe  # free, inside its bounds: a reason
    # a reduction fixes the capacity where the fit left it, a hair above its floor: still on
    # its floor (within bound_tol on the log scale of its bounds); clearly above it, not
    (flag,) = _check_time_constants(ctx(["C_wal"], lower * 1.002, 0.5))
    assert flag.parameters == ("C_zon",) and not flag.severe
    (flag,) = _check_time_constants(ctx(["C_wal"], lower * 1.2, 0.5))
    assert flag.parameters == () and flag.severe


def test_the_data_check_is_remembered_by_the_data_s_content_not_its_shape(fitted_half, halves):
    """A search judges many candidates on the same windows, so the data check's findings are
    kept by content: the same values give the same flags without checking again, and other
    values of the same shape (a validation window with a +60 K spike) are checked anew."""
    from jaxbox.validate import _verdict

    _verdict._FOUND.clear()
    clean = validate(fitted_half, halves[1])
    first = check_validity(fitted_half, validation=clean, check_intervals=False)
    assert not any(f.kind == "implausible_data" for f in first.flags)
    n = len(_verdict._FOUND)
    assert n == 2  # the identification window and the validation window
    again = check_validity(fitted_half, validation=clean, check_intervals=False)
    assert [f.message for f in again.flags] == [f.message for f in first.flags]
    assert len(_verdict._FOUND) == n
    spiked = validate(fitted_half, _spiked(halves[1], 60.0))
    v = check_validity(fitted_half, validation=spiked, check_intervals=False)
    flags = [f for f in v.flags if f.kind == "implausible_data"]
    assert flags and all(f.message.startswith("validation data") for f in flags)
    assert len(_verdict._FOUND) == n + 1
    # other options of the check are another entry too (a plausible range that admits it)
    check_validity(
        fitted_half,
        validation=spiked,
        check_intervals=False,
        data_overrides={"T_zon": (-50.0, 150.0)},
    )
    assert len(_verdict._FOUND) == n + 3
