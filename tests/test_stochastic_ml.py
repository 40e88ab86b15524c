"""Maximum likelihood of stochastic grey-box models: recovery on synthetic SDE data, the
output-error limit, the exact Hessian against finite differences, priors, likelihood ratios."""

import numpy as np
import pytest
from scipy import stats
from test_stochastic import _dataset

import jaxbox
from jaxbox.fit import FitError
from jaxbox.stochastic import (
    estimate_states,
    fit_ml,
    fit_ml_many,
    forward_selection_lr,
    likelihood_ratio_test,
    make_stochastic_problem,
    parent_starts,
)

TI = {
    "C_zon": 5e6,
    "R_wal": 1e-2,
    "gA": 3.0,
    "T_zon0": 20.0,
    "sigma_zon": 1e-3,
    "sigma_y_zon": 0.1,
}
N = 150
STARTS = 4


@pytest.fixture(scope="module")
def ti():
    return jaxbox.get_model("BM_Ti")


@pytest.fixture(scope="module")
def data(ti):
    return _dataset(ti, TI, N, seed=5, x0_std=1.0)


@pytest.fixture(scope="module")
def fit(ti, data):
    return fit_ml(ti, data, starts=STARTS)


@pytest.fixture(scope="module")
def fit_quiet(ti, data):
    """Diffusion fixed at (almost) zero and a sharp initial state: the output-error limit."""
    return fit_ml(ti, data, starts=STARTS, fixed={"sigma_zon": 1e-10}, x0_std=1e-5)


@pytest.mark.slow
def test_ml_recovers_parameters_and_reports_statistics(fit, ti, data):
    assert fit.converged
    assert fit.free == ("C_zon", "R_wal", "gA", "T_zon0", "sigma_zon", "sigma_y_zon")
    for n in fit.free:
        assert abs(fit.params[n] - TI[n]) < 4 * fit.sd[n], n
    # the likelihood through the state estimator (another compiled path) at the estimate
    est = estimate_states(ti, fit.params, data)
    assert abs(est.loglik - fit.loglik) < 1e-9 * abs(fit.loglik)
    k, n_obs = 6, N
    assert fit.aic == pytest.approx(2 * k - 2 * fit.loglik, rel=1e-12)
    assert fit.bic == pytest.approx(k * np.log(n_obs) - 2 * fit.loglik, rel=1e-12)
    # stationarity: the gradient in scaled coordinates is tiny
    p = np.asarray([fit.params[n] for n in fit.free])
    assert np.all(np.abs(fit.gradient * p) < 1e-3)
    # t statistics, p-values, intervals and correlations are consistent with the covariance
    t, pv, ci = fit.tstat(), fit.pvalue(), fit.intervals(0.9)
    q = stats.t.ppf(0.95, fit.dof)
    for n in fit.free:
        assert t[n] == pytest.approx(fit.params[n] / fit.sd[n])
        assert pv[n] == pytest.approx(2 * stats.t.sf(abs(t[n]), n_obs - k))
        assert ci[n][1] - ci[n][0] == pytest.approx(2 * q * fit.sd[n])
    R = fit.correlation
    assert np.allclose(np.diag(R), 1.0) and np.all(np.abs(R) <= 1 + 1e-12)
    # the objective per observation is negative here: starts at the best are still counted
    assert fit.starts.cost[fit.best] < 0
    assert 1 <= fit.n_at_best() <= STARTS
    assert fit.n_at_best() == int(np.sum(fit.starts.cost <= fit.starts.cost[fit.best] + 1e-6))
    table = fit.params_table()
    assert table["sigma_zon"]["unit"] == "K/√s" and table["sigma_y_zon"]["unit"] == "K"
    assert "log-likelihood" in fit.summary()


def test_hessian_matches_finite_differences(fit, ti, data):
    """Second differences of the likelihood (through the state estimator) in relative steps."""
    p0 = dict(fit.params)

    def nll(**change):
        return estimate_states(ti, {**p0, **change}, data).nll

    f0 = nll()
    H = fit.hessian
    for i, a in enumerate(fit.free):
        h = 1e-4 * p0[a]
        fd = (nll(**{a: p0[a] + h}) - 2 * f0 + nll(**{a: p0[a] - h})) / h**2
        assert fd == pytest.approx(H[i, i], rel=2e-3), a
    i, j = fit.free.index("C_zon"), fit.free.index("R_wal")
    ha, hb = 1e-4 * p0["C_zon"], 1e-4 * p0["R_wal"]
    fd = (
        nll(C_zon=p0["C_zon"] + ha, R_wal=p0["R_wal"] + hb)
        - nll(C_zon=p0["C_zon"] + ha, R_wal=p0["R_wal"] - hb)
        - nll(C_zon=p0["C_zon"] - ha, R_wal=p0["R_wal"] + hb)
        + nll(C_zon=p0["C_zon"] - ha, R_wal=p0["R_wal"] - hb)
    ) / (4 * ha * hb)
    assert fd == pytest.approx(H[i, j], rel=2e-3)


def test_vanishing_diffusion_gives_output_error_estimates(fit_quiet, ti, data):
    oe = jaxbox.fit_model(ti, data, starts=STARTS)
    for n in ti.param_names:
        assert fit_quiet.params[n] == pytest.approx(oe.params[n], rel=1e-3), n
    # the measurement noise is the RMS output error
    assert fit_quiet.params["sigma_y_zon"] == pytest.approx(np.sqrt(oe.cost), rel=1e-3)


def test_likelihood_ratio_test_of_nested_fits(fit, fit_quiet):
    lr = likelihood_ratio_test(fit_quiet, fit)
    assert lr["df"] == 1
    assert lr["statistic"] == pytest.approx(2 * (fit.loglik - fit_quiet.loglik))
    assert lr["pvalue"] == pytest.approx(stats.chi2.sf(lr["statistic"], 1))
    assert lr["pvalue"] < 0.01  # the data have a diffusion of 1e-3 K/√s
    with pytest.raises(ValueError, match="nested"):
        likelihood_ratio_test(fit, fit_quiet)


def test_map_prior_pulls_the_estimate(ti, data, fit):
    post = fit_ml(ti, data, starts=STARTS, priors={"gA": (2.0, 1e-3)})
    assert post.method == "map"
    assert post.params["gA"] == pytest.approx(2.0, abs=5e-3)
    assert post.sd["gA"] < 1e-3
    assert post.objective > post.nll
    assert post.loglik < fit.loglik


def test_fit_model_method_ml(ti, data, fit):
    res = jaxbox.fit_model(ti, data, method="ml", starts=STARTS)
    assert isinstance(res, jaxbox.MLResult)
    assert res.loglik == pytest.approx(fit.loglik, rel=1e-9)
    with pytest.raises(FitError, match="method"):
        jaxbox.fit_model(ti, data, method="mle")
    with pytest.raises(FitError, match="weights"):
        jaxbox.fit_model(ti, data, method="ml", weights=[1.0])


def test_validation_views(fit, data):
    tests = fit.innovation_tests()
    assert tests["T_zon"].ljung_box.p_value > 0.001  # innovations of the true model are white
    ks = fit.k_step_errors((1, 4))
    assert ks[1]["rmse"]["T_zon"] < ks[4]["rmse"]["T_zon"]
    sim = fit.simulation_rmse()
    assert sim["T_zon"] > ks[1]["rmse"]["T_zon"]


@pytest.mark.slow
def test_interval_coverage_small(ti):
    """95 % intervals over replications of synthetic SDE data, batched in one call."""
    sets = [_dataset(ti, TI, N, seed=100 + i, x0_std=1.0) for i in range(16)]
    fits = fit_ml_many(ti, sets, starts=STARTS)
    inside = [
        fit.intervals()[n][0] <= TI[n] <= fit.intervals()[n][1] for fit in fits for n in fit.free
    ]
    assert np.mean(inside) >= 0.75


def test_forward_selection_by_likelihood_ratio(ti, data, fit, fit_quiet):
    """A model without diffusion, then the same with it: the data have one, so the second is
    accepted by the likelihood-ratio test."""
    quiet = ("BM_Ti", {"fixed": {"sigma_zon": 1e-10}, "x0_std": 1e-5})
    sel = forward_selection_lr([quiet, "BM_Ti"], data, starts=STARTS)
    first, second = sel["table"]
    assert first["accepted"] and first["loglik"] == pytest.approx(fit_quiet.loglik, rel=1e-9)
    assert second["loglik"] == pytest.approx(fit.loglik, rel=1e-9)
    assert second["df"] == 1
    assert second["statistic"] == pytest.approx(2 * (second["loglik"] - first["loglik"]))
    assert second["pvalue"] < 0.05 and second["accepted"]
    assert sel["accepted"] == "BM_Ti"
    # the second model's last starts are the first model's estimate (as many starts in all);
    # the diffusion fixed at 1e-10 there lies outside its bounds here: it is next to its floor
    # (the parent embedded), then next to its ceiling, then at its guess
    richer = sel["fits"]["BM_Ti"]
    assert len(richer.starts.initial) == STARTS
    parent = sel["fits"][first["model"]].params
    rows = [dict(zip(richer.free, r, strict=True)) for r in richer.starts.initial[-3:]]
    for row in rows:
        for name in ("C_zon", "R_wal", "gA", "T_zon0", "sigma_y_zon"):
            assert row[name] == pytest.approx(parent[name], rel=1e-12)
    lo, hi = richer.problem.bounds["sigma_zon"]
    assert rows[2]["sigma_zon"] == pytest.approx(richer.problem.guess_dict["sigma_zon"])
    assert lo < rows[0]["sigma_zon"] < 1.02 * lo and 0.98 * hi < rows[1]["sigma_zon"] < hi
    with pytest.raises(ValueError, match="alpha"):
        forward_selection_lr(["BM_Ti"], data, alpha=2.0)


def test_parent_starts_embed_the_model_a_richer_one_extends(ti, data, fit):
    """A two-state model started from a one-state fit: one of the embedding starts (the wall
    node with its new parameters next to their bounds) has the parent's likelihood, and the
    richer model's fit from these starts is not below it."""
    te = jaxbox.get_model("BM_TiTe")
    sp = make_stochastic_problem(te, data)
    rows = parent_starts(sp, fit)
    assert rows.shape == (3, len(sp.free))
    new = [n for n in sp.free if n not in fit.params]
    assert set(new) == {"C_wal", "fra_wal", "T_wal0", "sigma_wal"}
    for row in rows:
        values = dict(zip(sp.free, row, strict=True))
        for n in fit.free:
            assert values[n] == pytest.approx(fit.params[n], rel=1e-12)
        assert values["T_wal0"] == pytest.approx(sp.guess_dict["T_wal0"])
    lls = [estimate_states(te, dict(zip(sp.free, r, strict=True)), data).loglik for r in rows]
    assert max(lls[:2]) == pytest.approx(fit.loglik, abs=0.5)
    assert max(lls[:2]) > lls[2] + 1.0  # the guesses of the new parameters are worse
    richer = fit_ml(te, data, starts=np.vstack([rows, rows[-1:]]))
    assert richer.loglik >= fit.loglik - 0.5
    # in a selection they take the place of the last hypercube starts, the floor row first
    from jaxbox.stochastic._select import _with_parent_start

    for n, k in ((16, 3), (3, 2), (2, 1)):
        starts = _with_parent_start(te, data, fit, {"starts": n})
        assert starts.shape == (n, len(sp.free))
        np.testing.assert_array_equal(starts[n - k :], rows[:k])
    with pytest.raises(ValueError, match="position"):
        parent_starts(sp, fit, position=0.5)


def test_a_start_ends_when_its_objective_stalls():
    """BFGS's own test needs the coordinates settled too: on an objective whose infimum lies at
    infinity (a parameter creeping towards its bound through the transform) it runs on while the
    coordinate grows; the stall test ends it once the objective has not fallen by 1e-8 of itself
    for its window of steps. Elsewhere it changes nothing."""
    import jax
    import jax.numpy as jnp
    import optimistix as optx

    from jaxbox.stochastic._fit import ML_STALL_WINDOW, _Stalling

    def creep(z, _):
        return 1.0 + 1.0 / (1.0 + jax.nn.softplus(z[0]))

    def bowl(z, _):
        return jnp.sum((z - jnp.asarray([3.0, -1.0])) ** 2) + 2.0

    def solve(fn, stall, y0):
        inner = optx.BFGS(rtol=1e-8, atol=1e-8)
        solver = _Stalling(inner) if stall else inner
        return optx.minimise(fn, solver, y0, max_steps=2000, throw=False)

    plain, stalled = (solve(creep, s, jnp.zeros(1)) for s in (False, True))
    assert stalled.result == optx.RESULTS.successful
    assert ML_STALL_WINDOW < int(stalled.stats["num_steps"]) < int(plain.stats["num_steps"]) - 30
    assert float(creep(stalled.value, None)) == pytest.approx(float(creep(plain.value, None)))
    assert float(creep(stalled.value, None)) - 1.0 < 1e-8 * ML_STALL_WINDOW
    plain, stalled = (solve(bowl, s, jnp.zeros(2)) for s in (False, True))
    assert int(plain.stats["num_steps"]) == int(stalled.stats["num_steps"]) < 50
    np.testing.assert_array_equal(np.asarray(plain.value), np.asarray(stalled.value))


def test_fit_settings_are_checked_before_the_solve(ti, data):
    """starts, seed, concentration, max_steps and the tolerances are checked and named before
    anything is compiled: a bool or a float as a number of starts, an empty or 3-D array, an
    explicit start outside its bounds (it would fail as 'nonfinite'), max_steps 0 (a result
    that never moved), a string seed or a negative concentration."""
    sp = make_stochastic_problem(ti, data)
    guess = np.asarray([sp.guess_dict[n] for n in sp.free])
    outside = guess.copy()
    outside[sp.free.index("R_wal")] = -1.0
    for kwargs, match in (
        ({"starts": True}, "starts must be a number of starts"),
        ({"starts": 2.5}, "starts must be a number of starts"),
        ({"starts": "4"}, "starts must be a number of starts"),
        ({"starts": np.zeros((0, 6))}, "explicit starts hold no row"),
        ({"starts": np.ones((2, 6, 1))}, "one column per free parameter.*\\(2, 6, 1\\)"),
        ({"starts": np.vstack([guess, outside])}, "explicit start 1: R_wal = -1 is not"),
        ({"starts": np.full(6, np.nan)}, "explicit start 0: C_zon = nan"),
        ({"max_steps": 0}, "max_steps must be at least 1"),
        ({"max_steps": 2.5}, "max_steps must be an integer"),
        ({"seed": "x"}, "seed must be an integer or None"),
        ({"concentration": -1.0}, "concentration must be finite and ≥ 0"),
        ({"rtol": float("nan")}, "rtol must be finite"),
        ({"atol": -1.0}, "atol must be finite and ≥ 0"),
    ):
        with pytest.raises(FitError, match=match):
            fit_ml(ti, data, **{"starts": 1, **kwargs})


def test_forward_selection_checks_every_entry_before_the_first_fit(data):
    """A misspelt model, a bad pair or an unknown option in the last entry is named before the
    first model is fitted (minutes of fits are not spent on a selection that then fails); a
    string is not taken as a list of one-letter model names."""
    from jaxbox.models import ModelError

    with pytest.raises(TypeError, match="models must be a list of models"):
        forward_selection_lr("BM_Ti", data, starts=1)
    with pytest.raises(TypeError, match=r"models\[1\] must be a model or a pair"):
        forward_selection_lr(["BM_Ti", ("BM_TiTe", 3)], data, starts=1)
    with pytest.raises(TypeError, match=r"models\[1\]: unknown fit option\(s\) fixd"):
        forward_selection_lr(["BM_Ti", ("BM_TiTe", {"fixd": {}})], data, starts=1)
    with pytest.raises(TypeError, match=r"unknown fit option\(s\) start;"):
        forward_selection_lr(["BM_Ti"], data, start=1)
    with pytest.raises(ModelError, match="BM_TiXe"):
        forward_selection_lr(["BM_Ti", "BM_TiXe"], data, starts=1)


def test_result_views_check_their_arguments(fit):
    """A confidence level or significance outside (0, 1) gave NaN intervals or a test at any
    level; a likelihood-ratio test against something else than a fit raised AttributeError."""
    for level in (0.0, 1.0, 95):
        with pytest.raises(ValueError, match="level must be in \\(0, 1\\)"):
            fit.intervals(level)
    with pytest.raises(ValueError, match="alpha must be in \\(0, 1\\)"):
        fit.innovation_tests(alpha=2.0)
    with pytest.raises(TypeError, match="large must be an MLResult.*got dict"):
        likelihood_ratio_test(fit, fit.params)
