"""Parameter uncertainty: exact sensitivities, covariance, interval coverage, identifiability."""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import optimize, stats

from jaxbox.data import Dataset
from jaxbox.fit import fit_model, problem_arrays
from jaxbox.models import RCNetwork
from jaxbox.simulate import simulate_model
from jaxbox.validate import check_validity, sensitivities, uncertainty

N = 200
STEP = 3600.0
TRUTH = {"C_zon": 5e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0}
SIGMA = 0.1  # K, white measurement noise


def _inputs(seed=0, n=N):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    return t, {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "Q_hea": 1500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
    }


def _dataset(model, theta, noise_seed, sigma=SIGMA, inputs=None):
    t, u = inputs if inputs is not None else _inputs()
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(len(t))})
    y = simulate_model(model, theta, clean).y[:, 0]
    y = y + np.random.default_rng(noise_seed).normal(0.0, sigma, len(t))
    return clean.with_columns(T_zon=y)


def _start(theta, free, factor=1.1):
    return np.asarray([[theta[n] * factor for n in free]])


FREE = ("C_zon", "R_wal", "gA", "T_zon0")


@pytest.mark.slow
def test_coverage_of_95_percent_intervals():
    """The 95 % intervals cover the true parameters about 95 % of the time.

    200 seeded datasets of the one-state model ``Zon`` (200 hourly samples, white noise of
    0.1 K, the same inputs) are fitted from one start 10 % off the truth, reusing one compiled
    fit. Intervals of all four free parameters (initial state included) are checked: 800
    intervals. Observed coverage: 0.955 over all (C_zon 0.945, R_wal 0.960, gA 0.955,
    T_zon0 0.960). Tolerance: the two-sided 99.9 % binomial interval of the count for a true
    rate of 0.95, i.e. [0.9225, 0.9738] over the 800 intervals and [0.895, 0.990] per parameter
    (200 intervals).
    """
    n_sets = 200
    inputs = _inputs()
    hits = np.zeros((n_sets, len(FREE)), dtype=bool)
    for k in range(n_sets):
        data = _dataset("Zon", TRUTH, noise_seed=1000 + k, inputs=inputs)
        res = fit_model("Zon", data, starts=_start(TRUTH, FREE))
        assert res.converged
        unc = uncertainty(res, include_initial_states=True)
        assert unc.names == FREE
        truth = np.asarray([TRUTH[n] for n in FREE])
        hits[k] = (unc.ci95[:, 0] <= truth) & (truth <= unc.ci95[:, 1])
    rate_all = hits.mean()
    per = hits.mean(axis=0)
    lo, hi = stats.binom.interval(0.999, hits.size, 0.95)
    assert lo / hits.size <= rate_all <= hi / hits.size, (rate_all, per)
    lo1, hi1 = stats.binom.interval(0.999, n_sets, 0.95)
    assert np.all((per >= lo1 / n_sets) & (per <= hi1 / n_sets)), per


@pytest.fixture(scope="module")
def zon_fit():
    data = _dataset("Zon", TRUTH, noise_seed=7)
    return fit_model("Zon", data, starts=_start(TRUTH, FREE))


def test_jacobian_matches_central_differences(zon_fit):
    res = zon_fit
    p0 = np.asarray([res.params[n] for n in res.free])
    ysim, J = sensitivities(res)
    assert J.shape == (N, 1, len(p0))
    for i in range(len(p0)):
        h = 1e-5 * abs(p0[i])
        up, dn = p0.copy(), p0.copy()
        up[i] += h
        dn[i] -= h
        fd = (sensitivities(res, up)[0] - sensitivities(res, dn)[0]) / (2 * h)
        scale = np.max(np.abs(J[:, 0, i]))
        assert np.max(np.abs(fd[:, 0] - J[:, 0, i])) < 1e-6 * scale, res.free[i]


def test_covariance_matches_scipy_curve_fit(zon_fit):
    """σ̂²(JᵀJ)⁻¹ agrees with scipy's curve_fit (finite-difference Jacobian) on the same model."""
    res = zon_fit
    problem = res.problem
    t, u, y, _ = problem_arrays(problem, res.data)
    fixed = jnp.zeros(0)
    sim = jax.jit(lambda p: problem.simulate(p, fixed, jnp.asarray(t), jnp.asarray(u))[:, 0])

    def f(_, *p):
        return np.asarray(sim(jnp.asarray(p)))

    p0 = np.asarray([res.params[n] for n in res.free])
    popt, pcov = optimize.curve_fit(
        f,
        t,
        y[:, 0],
        p0=p0,
        method="trf",
        jac="3-point",
        x_scale=np.abs(p0),
        ftol=1e-14,
        xtol=1e-14,
        gtol=1e-14,
    )
    np.testing.assert_allclose(popt, p0, rtol=1e-5)
    unc = uncertainty(res, include_initial_states=True)
    std_scipy = np.sqrt(np.diag(pcov))
    np.testing.assert_allclose(unc.std, std_scipy, rtol=1e-4)
    corr_scipy = pcov / np.outer(std_scipy, std_scipy)
    np.testing.assert_allclose(unc.correlation, corr_scipy, atol=1e-4)
    # σ̂² = SSE / (N - p), Student-t intervals
    assert unc.dof == N - 4
    assert unc.sigma2 == pytest.approx(res.cost * N / (N - 4), rel=1e-6)
    half = stats.t.ppf(0.975, N - 4) * unc.std
    np.testing.assert_allclose(unc.ci95[:, 1] - unc.values, half)
    np.testing.assert_allclose(unc.rel_ci, half / np.abs(unc.values))


def test_initial_states_get_no_interval_by_default(zon_fit):
    unc = uncertainty(zon_fit)
    full = uncertainty(zon_fit, include_initial_states=True)
    assert unc.names == ("C_zon", "R_wal", "gA")
    # the marginal covariance of the other parameters, not one conditioned on T_zon0
    np.testing.assert_allclose(unc.cov, full.cov[:3, :3])
    assert np.all(unc.identifiable)
    assert unc.combinations == ()
    assert unc.table()["R_wal"]["std"] == pytest.approx(float(unc.std[1]))
    d = unc.to_dict()
    assert set(d["params"]) == {"C_zon", "R_wal", "gA"}
    assert d["non_identifiable"] == []


def test_common_output_weight_does_not_change_the_covariance(zon_fit):
    res4 = fit_model("Zon", zon_fit.data, starts=_start(TRUTH, FREE), weights={"T_zon": 4.0})
    a = uncertainty(zon_fit)
    b = uncertainty(res4)
    np.testing.assert_allclose(b.std, a.std, rtol=1e-5)


def _parallel_model():
    return (
        RCNetwork("ZonPar", "zone with two resistances to ambient in parallel")
        .node("zon", output=True)
        .resistance("zon", "T_amb", "R_a")
        .resistance("zon", "T_amb", "R_b")
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA")
        .build()
    )


def test_two_resistances_in_parallel_are_flagged():
    model = _parallel_model()
    theta = {"C_zon": 5e6, "R_a": 0.02, "R_b": 0.02, "gA": 2.0, "T_zon0": 20.0}
    data = _dataset(model, theta, noise_seed=3)
    res = fit_model(model, data, starts=_start(theta, model.param_names, 1.05))
    unc = uncertainty(res)
    assert set(unc.not_identifiable) == {"R_a", "R_b"}
    assert len(unc.combinations) == 1
    combo = unc.combinations[0]
    assert combo.singular and set(combo.parameters) == {"R_a", "R_b"}
    # equal resistances: +1 % on one is compensated by -1 % on the other
    np.testing.assert_allclose(sorted(combo.changes), [-1.0, 1.0], atol=1e-3)
    assert "R_a" in combo.text and "R_b" in combo.text
    tab = unc.table()
    assert np.isnan(tab["R_a"]["std"]) and np.isnan(tab["R_b"]["std"])
    assert not tab["R_a"]["identifiable"]
    # the identifiable parameters keep finite, sensible error bars
    assert np.isfinite(tab["C_zon"]["std"]) and tab["C_zon"]["rel_ci"] < 0.2
    assert np.isfinite(tab["gA"]["std"])
    assert np.isnan(unc.correlation[1, 0])
    assert unc.to_dict()["params"]["R_a"]["std"] is None
    verdict = check_validity(res, unc)
    assert not verdict.valid
    assert set(verdict.flagged("not_identifiable")) == {"R_a", "R_b"}
    assert any("R_a" in r and "R_b" in r for r in verdict.reasons)


def test_unexcited_input_is_flagged():
    """Without irradiance in the data the solar aperture has no effect on the output."""
    t, u = _inputs()
    u = {**u, "I_glo_hor": np.zeros(N)}
    data = _dataset("Zon", TRUTH, noise_seed=5, inputs=(t, u))
    res = fit_model("Zon", data, starts=_start(TRUTH, FREE))
    unc = uncertainty(res)
    assert unc.not_identifiable == ("gA",)
    assert np.isnan(unc.std[2]) and np.all(np.isfinite(unc.std[:2]))
    assert "gA" in unc.combinations[0].text
    verdict = check_validity(res, unc)
    assert not verdict.valid and "gA" in verdict.flagged()


def test_poorly_identifiable_direction_is_flagged(zon_fit):
    """With a strict collinearity limit the most collinear direction is reported, with numbers."""
    unc = uncertainty(zon_fit, max_collinearity=1.0)
    assert unc.combinations and not any(c.singular for c in unc.combinations)
    assert np.all(np.isfinite(unc.std))
    assert unc.flagged
    assert unc.collinearity == pytest.approx(1 / unc.singular_values[-1])


@pytest.mark.parametrize("name", ["ZonWalIntInf", "BM_TiTeThRia", "Zon+Wal+Int+Hea"])
def test_shared_program_equals_the_per_structure_derivatives(name):
    """The sensitivities come from one program per padded network size (the network as
    arrays, the eigendecomposition discretisation); they equal forward-mode autodiff through the
    model's own simulator (the Van Loan matrix exponential), also for data in segments."""
    from _reference import synthetic_building

    from jaxbox.models import get_model
    from jaxbox.validate._uncertainty import _jacobian_fn, _rc_jacobian

    model = get_model(name)
    theta = {p.name: p.default for p in model.parameters}
    data = synthetic_building(model, theta, n=96, seed=3, noise=0.05)
    sets = [data]
    if name == "ZonWalIntInf":  # a 12-hour hole in the inputs: two segments
        frame = data.frame
        frame.iloc[40:52, [frame.columns.get_loc(c) for c in model.inputs]] = np.nan
        sets.append(Dataset(frame))
    for d in sets:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit_model(model, d, starts=1, max_steps=3)
        assert res.problem.model.segments == (2 if d is not data else 1)
        t, u, _, _ = problem_arrays(res.problem, res.data)
        p = jnp.asarray([res.params[n] for n in res.free])
        fv = jnp.asarray([v for _, v in res.problem.fixed], dtype=float)
        shared = _rc_jacobian(res.problem, t, u, p, fv)
        assert shared is not None
        own = _jacobian_fn(res.problem, len(t))(p, fv, jnp.asarray(t), jnp.asarray(u))
        np.testing.assert_allclose(shared[0], own[0], rtol=0, atol=1e-9)
        scale = np.max(np.abs(np.asarray(own[1])), axis=(0, 1))
        np.testing.assert_allclose(shared[1] / scale, np.asarray(own[1]) / scale, atol=1e-8)


def test_structures_with_few_and_many_heat_sources_share_one_program(monkeypatch):
    """The shared sensitivity program rounds the network's heat sources up to 8, as the fit's
    programs do: a search's small structures and those with a window per facade (7 sources)
    run one program, not one each (twin house O5's search compiled two). Compiled before any
    fit (:func:`prepare_sensitivities`, what a search does beside its first fit), then run."""
    from jaxbox.fit import make_problem
    from jaxbox.models import get_model
    from jaxbox.validate import _uncertainty

    keys = []  # the programs the sensitivities ask for
    cached = _uncertainty.cached
    monkeypatch.setattr(
        _uncertainty, "cached", lambda key, build: keys.append(key) or cached(key, build)
    )
    n = 96
    t = np.arange(n) * 3600.0
    rng = np.random.default_rng(5)
    day = 2 * np.pi * t / 86400
    sun = np.maximum(0, np.sin(day))
    columns = {
        "T_amb": 8 + 5 * np.sin(day - 2),
        "Q_hea": 500.0 * (rng.random(n) > 0.5),
        **{f"I_{f}": 300 * sun * (1 + 0.3 * k) for k, f in enumerate("sew")},
        "T_zon": 20 + rng.normal(0, 0.3, n),
    }
    data = Dataset.from_arrays(t, columns)
    small, large = get_model("Zon+Int+WinSE"), get_model("Zon+Int+Hea+WinSEW+Sol")
    assert small.array_sizes()["sources"] <= 4 < large.array_sizes()["sources"]
    for model in (small, large):
        assert _uncertainty.prepare_sensitivities(make_problem(model, data), data)
    shared = {key for key in keys if key[:2] == ("uncertainty", "rc")}
    assert len(shared) == 1 and len(keys) == 2, keys


@pytest.mark.parametrize(
    ("options", "error", "words"),
    [
        ({"level": 0.0}, ValueError, ["level", "(0, 1)"]),
        ({"level": 1.0}, ValueError, ["level", "(0, 1)"]),
        ({"level": 95}, ValueError, ["level", "0.95"]),
        ({"level": float("nan")}, ValueError, ["level", "nan"]),
        ({"level": "0.95"}, TypeError, ["level", "number"]),
        ({"rcond": 2.0}, ValueError, ["rcond", "[0, 1)"]),
        ({"rcond": float("nan")}, ValueError, ["rcond"]),
        ({"max_collinearity": 0}, ValueError, ["max_collinearity", "> 0"]),
        ({"max_collinearity": "x"}, TypeError, ["max_collinearity"]),
        ({"loading": -1.0}, ValueError, ["loading"]),
        ({"include_initial_states": "yes"}, TypeError, ["include_initial_states"]),
    ],
)
def test_bad_options_are_refused(zon_fit, options, error, words):
    """A level of 1.5, 95 or NaN gave NaN intervals, 0 zero-width ones, -0.1 reversed ones; a
    max_collinearity of 0 divided by zero; rcond 2 made every parameter unidentifiable."""
    with pytest.raises(error) as err:
        uncertainty(zon_fit, **options)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_sensitivities_refuse_bad_parameter_values(zon_fit):
    with pytest.raises(ValueError, match="4 values in result.free order"):
        sensitivities(zon_fit, [1.0, 2.0])
    with pytest.raises(ValueError, match="R_wal are not finite"):
        sensitivities(zon_fit, [5e6, np.nan, 2.0, 20.0])
    with pytest.raises(TypeError, match="result must be a FitResult"):
        sensitivities(None)


def test_a_duck_typed_result_is_taken_and_a_lacking_one_named(zon_fit):
    """Any object with the attributes read (problem, data, params) serves, as a FitResult does;
    one lacking them is refused naming what is missing (was AttributeError deep inside)."""
    import types

    duck = types.SimpleNamespace(
        problem=zon_fit.problem, data=zon_fit.data, params=dict(zon_fit.params)
    )
    np.testing.assert_allclose(sensitivities(duck)[1], sensitivities(zon_fit)[1])
    assert uncertainty(duck).names == uncertainty(zon_fit).names
    bare = types.SimpleNamespace(problem=zon_fit.problem, data=zon_fit.data)
    p = [zon_fit.params[n] for n in zon_fit.free]
    np.testing.assert_allclose(sensitivities(bare, p)[1], sensitivities(zon_fit)[1])
    with pytest.raises(TypeError, match="result must be a FitResult .* without params"):
        sensitivities(bare)
    with pytest.raises(TypeError, match="without params"):
        uncertainty(bare)
