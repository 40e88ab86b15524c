"""Experiment design: the Fisher information, its gradient, the planned schedule, the baselines,
and a Monte-Carlo check of the predicted standard deviations against repeated fits."""

import json
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbox
from jaxbox import design
from jaxbox.cli._main import main
from jaxbox.models import ModelError

# ZonWal with the values fitted on the bundled twin-house data (house N2, first half)
PRIOR = {"C_zon": 2.615e7, "C_wal": 3.115e8, "R_wal": 7.129e-3, "gA": 1.79}
DAYS = 2
STARTS = 4


@pytest.fixture(scope="module")
def planned():
    return design.plan(
        "ZonWal",
        PRIOR,
        sigma=0.05,
        days=DAYS,
        power=(0.0, 3000.0),
        comfort=(15.0, 35.0),
        criterion="hlc",
        starts=STARTS,
    )


def _solver_args(ctx, rho=100.0, mu=0.0, lo=0.0, hi=3000.0):
    extra = (lo, hi, 15.1, 34.9, np.inf, ctx.step, rho, mu)
    return (*ctx.args(), *(jnp.asarray(float(v)) for v in extra))


def _loss(ctx, criterion):
    """The solver's loss, rebuilt here to differentiate it outside the compiled solver."""
    setup = ctx.setup

    def loss(z, args):
        mats, tangents, c, U0, sigma, lo, hi, tlo, thi, emax, dt, rho, mu = args
        s = 0.5 * (1.0 + jnp.sin(z))
        u = lo + (hi - lo) * s
        U = U0.at[:, setup.heat_index].set(u)
        F = setup.information(mats, tangents, U, sigma)
        value = jnp.mean(jax.vmap(lambda f, cc: setup.criterion(criterion, f, cc))(F, c))
        y = setup.simulate(jax.tree_util.tree_map(lambda a: a[0], mats), U)
        comfort = jnp.mean(jax.nn.relu(y - thi) ** 2 + jax.nn.relu(tlo - y) ** 2)
        return value + rho * comfort + mu * jnp.mean(s * (1.0 - s))

    return loss


# ---- sequences ---------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [3, 5, 7, 9])
def test_prbs_is_a_maximum_length_sequence(k):
    n = (1 << k) - 1
    p = design.prbs(n, 1, seed=3).astype(int)
    assert p.sum() == 1 << (k - 1)  # 2^(k-1) ones, 2^(k-1) - 1 zeros
    ring = np.concatenate([p, p[: k - 1]])
    windows = {tuple(ring[i : i + k]) for i in range(n)}
    assert len(windows) == n  # every non-zero k-bit state once: period 2^k - 1
    assert np.array_equal(design.prbs(2 * n, 2, seed=3)[::2][:n], p)  # the clock holds bits


def test_rolbs_durations_are_log_spaced_and_balanced():
    p = design.rolbs(10_000, shortest=1, longest=64, durations=7, seed=2)
    edges = np.flatnonzero(np.diff(p) != 0)
    runs = np.diff(edges)
    assert set(np.unique(runs)) <= {1, 2, 4, 8, 16, 32, 64}
    assert set(np.unique(runs)) == {1, 2, 4, 8, 16, 32, 64}
    cycle = 2 * (1 + 2 + 4 + 8 + 16 + 32 + 64)
    whole = p[: (len(p) // cycle) * cycle].reshape(-1, cycle)
    np.testing.assert_array_equal(whole.sum(axis=1), cycle // 2)  # on as long as off


# ---- the information and its derivatives -------------------------------------------------------


def test_information_matches_finite_difference_sensitivities(planned):
    """F from the AD sensitivity recursion vs F from central differences of simulate_model (the
    Van Loan discretisation, another code path)."""
    ctx = planned.context
    u = planned.power
    rep = ctx.report(u)
    mats, tangents, c, U0, sigma = ctx.args()
    U = np.array(U0)
    U[:, ctx.setup.heat_index] = u
    F = np.asarray(ctx.setup.information(mats, tangents, jnp.asarray(U), sigma))[0]
    data = jaxbox.Dataset.from_arrays(
        ctx.index, {n: U[:, i] for i, n in enumerate(ctx.setup.model.inputs)}
    )
    phi0 = ctx.phis[0]

    def y(phi):
        th = ctx.setup.theta(jnp.asarray(phi), ctx.fixed)
        th = {k: float(v) for k, v in th.items()}
        return jaxbox.simulate_model("ZonWal", th, data).y.ravel()

    cols = []
    for i in range(len(phi0)):
        h = 1e-5 if ctx.setup.log[i] else 1e-4
        e = np.zeros_like(phi0)
        e[i] = h
        cols.append((y(phi0 + e) - y(phi0 - e)) / (2 * h))
    J = np.stack(cols, axis=1)
    F_fd = J.T @ J / ctx.sigma**2
    np.testing.assert_allclose(F, F_fd, rtol=2e-5, atol=1e-6 * np.abs(F_fd).max())
    # the reported stds are the square roots of the diagonal of F⁻¹ (in SI)
    sd = np.sqrt(np.diag(np.linalg.inv(F_fd)))
    th = ctx.theta(0)
    for i, n in enumerate(ctx.setup.free):
        expected = th[n] * sd[i] if ctx.setup.log[i] else sd[i]
        assert rep["std"][n] == pytest.approx(expected, rel=1e-4)


def test_hlc_and_its_gradient(planned):
    """ZonWal: HLC = 1/R_wal, so ∂ log HLC/∂ log R_wal = −1 and nothing else."""
    ctx = planned.context
    _, _, c, hlc = ctx.linear
    assert float(hlc[0]) == pytest.approx(1.0 / PRIOR["R_wal"], rel=1e-10)
    expected = np.zeros(len(ctx.setup.free))
    expected[ctx.setup.free.index("R_wal")] = -1.0
    np.testing.assert_allclose(np.asarray(c[0]), expected, atol=1e-10)
    # and the same as the verdict's steady-state UA for a larger model
    from jaxbox.validate import heat_loss_coefficients

    model = jaxbox.get_model("ZonWalIntInf")
    theta = model.defaults()
    setup = design.make_setup(model, model.param_names)
    ua = heat_loss_coefficients(model, theta)["Q_hea"][0]
    assert float(setup.hlc(theta)) == pytest.approx(ua, rel=1e-9)
    assert ua == pytest.approx(1 / theta["R_wal"] + 1 / theta["R_inf"], rel=1e-9)


def test_criterion_gradient_matches_finite_differences(planned):
    """The gradient of every criterion (with the comfort penalty) vs central differences."""
    ctx = planned.context
    losses = [_loss(ctx, c) for c in design.CRITERIA]
    args = _solver_args(ctx)

    def stacked(z, a):
        return jnp.stack([f(z, a) for f in losses])

    # one compiled program gives the values (for the differences) and the reverse-mode gradient
    both = jax.jit(lambda z, a: (stacked(z, a), jax.jacrev(stacked)(z, a)))

    def value(z, a):
        return both(z, a)[0]

    z = jnp.asarray(np.random.default_rng(0).normal(0.0, 1.0, ctx.n))
    g = np.asarray(both(z, args)[1])  # [criteria, N]
    h = 1e-3  # smaller steps lose more to round-off than they gain
    for k in (0, 5, ctx.n // 2, ctx.n - 1):
        e = np.zeros(ctx.n)
        e[k] = h
        fd = (np.asarray(value(z + e, args)) - np.asarray(value(z - e, args))) / (2 * h)
        np.testing.assert_allclose(g[:, k], fd, rtol=1e-5, atol=1e-9)
    # without penalties each is the criterion that the report gives for the same powers
    u = np.asarray(1500.0 * (1.0 + jnp.sin(z)))
    rep = ctx.report(u)["loss"]
    free = np.asarray(value(z, _solver_args(ctx, rho=0.0)))
    np.testing.assert_allclose(free, [rep[c] for c in design.CRITERIA], rtol=1e-10)


# ---- the plan ----------------------------------------------------------------------------------


def test_designed_beats_baselines_and_respects_constraints(planned):
    reps = planned.reports
    u = planned.power
    assert len(u) == DAYS * 24
    assert np.all(u >= 0.0) and np.all(u <= 3000.0)
    rep = reps["designed"]
    assert 15.0 <= rep["t_min"] and rep["t_max"] <= 35.0
    for name in ("prbs", "rolbs", "step"):
        assert rep["loss"]["hlc"] < reps[name]["loss"]["hlc"], name
        assert rep["hlc_std"] < reps[name]["hlc_std"], name
        # equal length and (up to the power cap) energy
        assert len(planned.schedules[name]) == len(u)
        assert reps[name]["energy_kwh"] <= rep["energy_kwh"] * (1 + 1e-9)
    for name in ("prbs", "rolbs"):  # the same energy, unless the on level is capped at 3 kW
        same = reps[name]["energy_kwh"] == pytest.approx(rep["energy_kwh"], rel=1e-9)
        assert same or planned.schedules[name].max() == 3000.0, name
    assert reps["step"]["energy_kwh"] == pytest.approx(rep["energy_kwh"], rel=1e-9)
    frame = planned.schedule(baselines=True)
    assert list(frame.columns[:2]) == ["Q_hea", "T_zon_predicted"]
    assert "Q_hea_prbs" in frame.columns


@pytest.mark.slow
def test_binary_robust_design_with_energy_budget():
    budget = 30 * 3.6e6  # 30 kWh over two days: less than the unconstrained design uses
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the budget and the comfort band are met
        d = design.plan(
            "ZonWal",
            PRIOR,
            days=DAYS,
            power=(200.0, 2500.0),
            binary=True,
            max_energy=budget,
            comfort=(15.0, 35.0),
            robust=3,
            spread=0.3,
            seed=1,
            starts=STARTS,
            max_steps=200,
        )
    assert set(np.unique(d.power)) <= {200.0, 2500.0}
    assert d.rounding_loss is not None and np.isfinite(d.rounding_loss)
    assert d.relaxed is not None and np.all((d.relaxed >= 200.0) & (d.relaxed <= 2500.0))
    rep = d.reports["designed"]
    assert rep["energy_kwh"] * 3.6e6 <= budget * (1 + 1e-12)  # on/off rounding kept to it
    assert 15.0 <= rep["t_min"] and rep["t_max"] <= 35.0
    assert rep["loss"]["hlc"] < d.reports["prbs"]["loss"]["hlc"]
    # robust: three prior samples, the first the nominal one, the others spread log-normally
    phis = d.context.phis
    assert phis.shape[0] == 3
    np.testing.assert_allclose(phis[0][:4], np.log(list(PRIOR.values())), rtol=1e-12)
    assert np.all(np.abs(phis[1:, :4] - phis[0][:4]) > 1e-3)


def test_robust_loss_is_the_average_over_samples(planned):
    """The criterion of a robust context is the mean of those of one-sample contexts."""
    from jaxbox.design._context import make_context
    from jaxbox.design._prior import load_prior, prior_samples

    ctx = planned.context
    prior = load_prior("ZonWal", PRIOR)
    names = ("C_zon", "C_wal", "R_wal", "gA")
    samples = prior_samples(prior, names, 3, 0.3, seed=4)
    args = (prior, ctx.setup, design._plan.default_weather(3600.0), ctx.n, 3600.0, 0.05, 25.0)
    robust = make_context(*args, samples, names).report(planned.power)["loss"]
    single = [
        make_context(*args, samples[i : i + 1], names).report(planned.power)["loss"]
        for i in range(3)
    ]
    for c in design.CRITERIA:
        assert robust[c] == pytest.approx(np.mean([s[c] for s in single]), rel=1e-10)
    assert np.std([s["hlc"] for s in single]) > 1e-3  # the samples differ


def test_bad_input_is_named():
    with pytest.raises(ModelError, match="criterion"):
        design.plan("ZonWal", PRIOR, criterion="E")
    with pytest.raises(ModelError, match="power"):
        design.plan("ZonWal", PRIOR, power=(3000.0, 0.0))
    with pytest.raises(ModelError, match="no parameter"):
        design.plan("ZonWal", {"R_foo": 1.0})
    with pytest.raises(ModelError, match="sigma"):
        design.plan("ZonWal", PRIOR, sigma=0.0)
    with pytest.raises(jaxbox.DataError, match="horizon"):
        design.plan("ZonWal", PRIOR, days=400)


@pytest.mark.parametrize(
    "kwargs, error, words",
    [
        ({"days": np.nan}, ModelError, "days must be a horizon > 0"),
        ({"days": np.inf}, ModelError, "days must be a horizon > 0"),
        ({"days": "2"}, TypeError, "days must be a number"),
        ({"days": 1.01}, ModelError, r"24.24 steps of 3600 s; give a whole number"),
        ({"step": 7 * 3600.0}, ModelError, "6.857 steps of 25200 s"),
        ({"seed": -1}, ModelError, "seed must be an integer ≥ 0"),
        ({"starts": 2.5}, TypeError, "starts must be an integer"),
        ({"robust": -3}, ModelError, "robust must be an integer ≥ 0"),
        ({"robust": 2.5, "spread": 0.3}, TypeError, "robust must be an integer"),
        ({"prbs_clock": 0}, ModelError, "prbs_clock must be an integer ≥ 1"),
        ({"power": (0.0, 10.0, 20.0)}, ModelError, "power must be a pair"),
        ({"power": {"lo": 0, "hi": 10}}, ModelError, "power must be a pair"),
        ({"comfort": (15.0, 35.0, 40.0)}, ModelError, "comfort must be a pair"),
        ({"binary": "no"}, TypeError, "binary must be True"),
        ({"start_temperature": np.nan}, ModelError, "start_temperature must be a finite"),
        ({"sigma": "0.05"}, TypeError, "sigma must be a number"),
        # the minimum power alone exceeds the energy budget: a design could only break it
        (
            {"power": (1000.0, 3000.0), "max_energy": 10 * 3.6e6},
            ModelError,
            r"max_energy .* \(10 kWh\) is below .* minimum power 1000 W .* \(48 kWh\)",
        ),
        ({"heating": "T_amb"}, ModelError, "heating='T_amb' is not a heat flow input"),
        # the HLC does not depend on the free parameters: nothing to minimise
        ({"free": ["C_zon", "C_wal", "gA"]}, ModelError, "HLC of ZonWal depends on no free"),
    ],
)
def test_bad_plan_arguments_are_named(kwargs, error, words):
    with pytest.raises(error, match=words):
        design.plan("ZonWal", PRIOR, **{"days": DAYS, "starts": 1, "max_steps": 5, **kwargs})


def test_unmet_constraints_are_warned():
    """100 W cannot hold the zone at 40 °C: the design breaks the comfort band, and says so."""
    with pytest.warns(UserWarning, match="30.7–41 °C leaves the comfort band 40–45 °C"):
        d = design.plan(
            "ZonWal",
            PRIOR,
            days=DAYS,
            power=(0.0, 100.0),
            comfort=(40.0, 45.0),
            start_temperature=41.0,
            starts=STARTS,
        )
    assert d.reports["designed"]["t_min"] < 40.0


def test_bad_sequence_arguments_are_named():
    with pytest.raises(TypeError, match="prbs needs an integer n"):
        design.prbs(2.5)
    with pytest.raises(TypeError, match="rolbs needs an integer longest"):
        design.rolbs(100, 1, float("nan"))
    with pytest.raises(ValueError, match="seed ≥ 0"):
        design.rolbs(100, 1, 10, 3, seed=-1)
    with pytest.raises(ValueError, match="step needs n ≥ 1"):
        design.step(-1)
    with pytest.raises(ModelError, match="seed must be an integer ≥ 0"):
        design.prior_samples(design.load_prior("ZonWal"), ["R_wal"], 3, 0.3, seed=-1)


def test_bad_prior_values_are_named(tmp_path):
    """Every prior value is checked, fixed ones included (a negative fixed R gave an HLC
    criterion of -inf), and a free gA must be > 0 (its coordinate is log gA)."""
    cases = [
        ({"R_wal": -1.0}, ["C_zon", "gA"], "R_wal is -1; resistances"),
        ({"R_wal": np.nan}, ["C_zon", "gA"], "R_wal is nan"),
        ({"gA": 0.0}, None, "gA is 0; a free gA .* needs a value > 0"),
        ({"R_wal": "abc"}, None, "R_wal is 'abc'; give a number"),
        (PRIOR, ["R_foo"], "no parameter.*R_foo; its parameters are C_zon"),
    ]
    for params, free, words in cases:
        with pytest.raises(ModelError, match=words):
            design.load_prior("ZonWal", params, free)
    assert design.load_prior("ZonWal", {"gA": 0.0}, ["C_zon", "R_wal"]).theta["gA"] == 0.0
    with pytest.raises(TypeError, match="free must be a list of parameter names"):
        design.load_prior("ZonWal", PRIOR, "R_wal")
    with pytest.raises(TypeError, match="params must be a mapping"):
        design.load_prior("ZonWal", [("R_wal", 0.01)])
    fit = {"model": "ZonWal", "params": {n: {"value": v} for n, v in PRIOR.items()}}
    fit["params"]["T_zon0"] = {"value": None}
    fit["params"]["T_wal0"] = {"value": 20.0, "std": "n/a"}
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(fit))
    with pytest.raises(ModelError, match="fit.json: prior value of T_zon0 is None"):
        design.load_prior(params=str(path))
    with pytest.raises(ModelError, match="no parameter.*R_foo"):
        design.prior_samples(design.load_prior("ZonWal"), ["R_foo"], 3, 0.3)
    for n in (0, -3, 2.5):
        with pytest.raises(ModelError, match="prior_samples needs n, an integer ≥ 1"):
            design.prior_samples(design.load_prior("ZonWal"), ["R_wal"], n, 0.3)


def test_baseline_schedules_check_their_arguments(planned):
    ctx = planned.context
    for args, kwargs, error, words in [
        ((3000.0, 0.0, None), {}, ModelError, "power must be finite with low < high"),
        ((-5.0, 3000.0, None), {}, ModelError, "power bounds must be ≥ 0 W"),
        ((0.0, 3000.0, -1.0), {}, ModelError, "energy_j must be ≥ 0"),
        ((0.0, 3000.0, None), {"rolbs_longest": 0}, ModelError, "rolbs_longest must be"),
        ((0.0, 3000.0, None), {"prbs_clock": 1.5}, TypeError, "prbs_clock must be"),
        ((0.0, 3000.0, None), {"criterion": "Z"}, ModelError, "unknown criterion 'Z'"),
    ]:
        with pytest.raises(error, match=words):
            design.baseline_schedules(ctx, *args, **kwargs)


def test_missing_power_or_weather_is_named():
    """A NaN in the schedule or a gap in the weather within the horizon: an error naming the
    sample or the column and time stamp, not NaN criteria (or a 'check the prior values')."""
    u = np.full(DAYS * 24, 1000.0)
    u[5] = np.nan
    with pytest.raises(ModelError, match="first at sample 5"):
        design.evaluate(u, "ZonWal", PRIOR)
    with pytest.raises(ModelError, match="at least 4 samples"):
        design.evaluate([1000.0, 0.0], "ZonWal", PRIOR)
    weather = jaxbox.datasets.twinhouse_exp1("N2")
    for k in (3, 30):  # in the preconditioning day, and later
        frame = weather.frame
        frame.iloc[k, frame.columns.get_loc("T_amb")] = np.nan
        gappy = jaxbox.Dataset(frame)
        with pytest.raises(jaxbox.DataError, match=f"'T_amb' has 1 missing.*{weather.index[k]}"):
            design.evaluate(np.full(DAYS * 24, 1000.0), "ZonWal", PRIOR, weather=gappy)
    # a gap after the horizon does not matter
    frame = weather.frame
    frame.iloc[100, frame.columns.get_loc("T_amb")] = np.nan
    design.evaluate(np.full(DAYS * 24, 1000.0), "ZonWal", PRIOR, weather=jaxbox.Dataset(frame))
    with pytest.raises(TypeError, match="weather must be a jaxbox Dataset"):
        design.evaluate(np.full(DAYS * 24, 1000.0), "ZonWal", PRIOR, weather=weather.frame)


# ---- singular Fisher information: unidentifiable parameters are named, never NaN ---------------


def test_singular_information_is_reported_as_such(planned):
    """No heating (or a negligible one): the heat flows have no scale, C, 1/R and gA are only
    seen together; their std and every criterion are inf (not NaN, nor a std of 0 from a
    negative variance), and the parameters are named."""
    ctx = planned.context
    for u in (np.zeros(ctx.n), np.full(ctx.n, 1e-3)):
        rep = ctx.report(u)
        assert rep["unidentifiable"] == ["C_zon", "C_wal", "R_wal", "gA"]
        assert all(v == np.inf for v in rep["loss"].values())
        assert all(rep["std"][n] == np.inf for n in rep["unidentifiable"])
        assert np.isfinite(rep["std"]["T_zon0"]) and rep["hlc_std"] == np.inf
    # a PRBS baseline of no energy: compared as infinitely bad, not as NaN
    base = design.baseline_schedules(ctx, 0.0, 3000.0, 0.0)
    assert all(ctx.report(u)["loss"]["hlc"] == np.inf for u in base.values())
    assert planned.reports["designed"]["unidentifiable"] == []
    with pytest.warns(UserWarning, match="C_zon, C_wal, R_wal, gA unidentifiable"):
        design.evaluate(np.zeros(ctx.n), "ZonWal", PRIOR)


def test_parameter_the_outputs_do_not_see():
    """Weather without sun: gA is unidentifiable, the others are as precise as with gA fixed
    (its column of the sensitivities is zero); a plan with gA free is refused, naming it."""
    weather = jaxbox.datasets.twinhouse_exp1("N2")
    dark = weather.with_columns(I_glo_hor=np.zeros(len(weather)))
    u = np.full(DAYS * 24, 1000.0)
    with pytest.warns(UserWarning, match="gA"):
        rep = design.evaluate(u, "ZonWal", PRIOR, weather=dark)
    fixed = design.evaluate(
        u, "ZonWal", PRIOR, weather=dark, free=["C_zon", "C_wal", "R_wal", "T_zon0", "T_wal0"]
    )
    assert rep["unidentifiable"] == ["gA"] and rep["std"]["gA"] == np.inf
    assert rep["loss"]["D"] == np.inf and rep["loss"]["A"] == np.inf
    for name, sd in fixed["std"].items():
        assert rep["std"][name] == pytest.approx(sd, rel=1e-8), name
    assert rep["loss"]["hlc"] == pytest.approx(fixed["loss"]["hlc"], rel=1e-8)
    with pytest.raises(ModelError, match="gA of ZonWal unidentifiable"):
        design.plan("ZonWal", PRIOR, weather=dark, days=DAYS, starts=2, max_steps=5)


# ---- Monte Carlo: predicted vs observed spread of repeated fits --------------------------------


def test_predicted_std_matches_monte_carlo_fits(planned):
    ctx = planned.context
    theta = ctx.theta(0)
    model = ctx.setup.model
    rng = np.random.default_rng(7)
    R = 30
    requests, names = [], []
    for name in ("designed", "prbs"):
        signals = {n: ctx.inputs[:, i] for i, n in enumerate(model.inputs)}
        signals["Q_hea"] = planned.schedules[name]
        base = jaxbox.Dataset.from_arrays(ctx.index, signals)
        y = jaxbox.simulate_model(model, theta, base).y[:, 0]
        for _ in range(R):
            noisy = base.with_columns(T_zon=y + rng.normal(0.0, ctx.sigma, len(y)))
            requests.append({"model": model, "data": noisy, "starts": 1, "guess": theta})
            names.append(name)
    results = jaxbox.fit_batch(requests)
    names = np.asarray(names)
    for name in ("designed", "prbs"):
        rs = [r for r, n in zip(results, names, strict=True) if n == name]
        P = np.asarray([[r.params[p] for p in ctx.setup.free] for r in rs])
        rep = planned.reports[name]
        checked = 0
        for i, p in enumerate(ctx.setup.free):
            # the linearised prediction holds where the estimate is precise (a few % of
            # relative std); over two days the envelope capacity (time constant ~ two weeks)
            # and, from a PRBS, the HLC are not
            if rep["rel_std"][p] > 0.02:
                continue
            checked += 1
            ratio = P[:, i].std(ddof=1) / rep["std"][p]
            # 99.9 % interval of s/σ for 30 normal samples is [0.64, 1.39]
            assert 0.6 < ratio < 1.45, (name, p, ratio)
        assert checked >= 3
        hlc = 1.0 / P[:, ctx.setup.free.index("R_wal")]
        if name == "designed" or rep["hlc_std"] / rep["hlc"] <= 0.02:
            assert rep["hlc_std"] / rep["hlc"] <= 0.02  # the design makes the HLC precise
            assert 0.6 < hlc.std(ddof=1) / rep["hlc_std"] < 1.45
    # and the designed experiment is observed to pin the HLC down better
    observed = {
        name: (
            1.0
            / np.asarray(
                [r.params["R_wal"] for r, n in zip(results, names, strict=True) if n == name]
            )
        ).std(ddof=1)
        for name in ("designed", "prbs")
    }
    assert observed["designed"] < observed["prbs"]


# ---- command line ------------------------------------------------------------------------------


def test_cli_design_writes_schedule(tmp_path, capsys):
    fit = {
        "model": "ZonWal",
        "free": ["C_zon", "C_wal", "R_wal", "gA", "T_zon0", "T_wal0"],
        "params": {
            **{n: {"value": v, "std": 0.05 * v} for n, v in PRIOR.items()},
            "T_zon0": {"value": 25.0, "std": None},
            "T_wal0": {"value": 20.0, "std": None},
        },
        "correlation": {},
    }
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(fit))
    out = tmp_path / "schedule.csv"
    code = main(
        [
            "design",
            "--params",
            str(path),
            "--days",
            str(DAYS),
            "--sigma",
            "0.05",
            "--power",
            "0:3000",
            "--comfort",
            "15:35",
            "--starts",
            str(STARTS),
            "--out",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "designed" in text and "prbs" in text and "HLC [W/K]" in text
    import pandas as pd

    frame = pd.read_csv(out, index_col=0)
    assert len(frame) == DAYS * 24 and frame["Q_hea"].between(0, 3000).all()


@pytest.mark.parametrize(
    "args, words",
    [
        (["--model", "ZonWal", "--power", "3000:0"], "--power"),
        (["--model", "ZonWal", "--step", "soon"], "--step"),
        (["--params", "/nonexistent/fit.json"], "no such file"),
        (["--model", "NoSuchModel"], "NoSuchModel"),
        (["--model", "ZonWal", "--max-energy", "-3kWh"], "--max-energy"),
        (["--model", "ZonWal", "--seed", "-1"], "--seed"),
        (["--model", "ZonWal", "--start-temperature", "nan"], "--start-temperature"),
        (["--model", "ZonWal", "--days", "1", "--step", "7h"], "whole number of steps"),
    ],
)
def test_cli_bad_input_exits_2(tmp_path, capsys, args, words):
    assert main(["design", *args, "--out", str(tmp_path / "s.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and words in err[0]
    assert not (tmp_path / "s.csv").exists()
