"""Stochastic grey-box models against independent references: the dense Gaussian likelihood of
the stacked outputs, scipy's matrix exponential and quadrature, Euler–Maruyama moments, finite
differences, dense conditioning for the smoother."""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sla

import jaxbox
from jaxbox.data import Dataset, DataWarning
from jaxbox.fit import FitError
from jaxbox.models import RCNetwork
from jaxbox.stochastic import (
    estimate_states,
    make_stochastic_problem,
    noise_names,
    process_noise,
    process_noise_van_loan,
    simulate_sde,
    stochastic_arrays,
)

TITE = {
    "C_zon": 3e6,
    "C_wal": 3e7,
    "R_wal": 2e-2,
    "fra_wal": 0.3,
    "gA": 3.0,
    "T_zon0": 20.0,
    "T_wal0": 12.0,
    "sigma_zon": 2e-3,
    "sigma_wal": 5e-4,
    "sigma_y_zon": 0.05,
}


def _inputs(n, dt=1800.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    return t, {
        "T_amb": 5 + 3 * np.sin(2 * np.pi * t / 86400) + 0.3 * rng.standard_normal(n),
        "Q_hea": 2000.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.clip(400 * np.sin(2 * np.pi * t / 86400), 0, None),
    }


def _dataset(model, params, n, seed=0, dt=1800.0, x0_std=0.0):
    t, u = _inputs(n, dt, seed)
    base = Dataset.from_arrays(t, {**u, **{o: np.zeros(n) for o in model.outputs}})
    y, _ = simulate_sde(model, params, base, seed=seed + 100, x0_std=x0_std)
    return base.with_columns({o: y[:, j] for j, o in enumerate(model.outputs)})


def _scipy_system(model, params, dt, hold):
    """Φ, Γ0, Γ1 and Q from scipy's expm (Van Loan blocks), independent of the package."""
    A, B, C, D = (np.asarray(a) for a in model.state_space(params))
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n], M[:n, n : n + m], M[n : n + m, n + m :] = A * dt, B * dt, np.eye(m)
    E = sla.expm(M)
    Phi, G0, G1 = E[:n, :n], E[:n, n : n + m], E[:n, n + m :]
    if hold == "zoh":
        G1 = np.zeros_like(G1)
    sig = np.asarray(
        [0.0 if node.constant else params[f"sigma_{node.name}"] for node in model.network.nodes]
    )
    V = np.zeros((2 * n, 2 * n))
    V[:n, :n], V[:n, n:], V[n:, n:] = -A * dt, np.diag(sig**2) * dt, A.T * dt
    F = sla.expm(V)
    Q = F[n:, n:].T @ F[:n, n:]
    r = np.asarray([params[f"sigma_y_{o[2:]}"] for o in model.outputs])
    return Phi, G0, G1, 0.5 * (Q + Q.T), C, D, r


def _dense(model, params, data, hold="foh", x0_std=1.0):
    """Mean and covariance of the stacked states and outputs, computed directly."""
    dt, u, y = stochastic_arrays(model, data)
    Phi, G0, G1, Q, C, D, r = _scipy_system(model, params, dt, hold)
    n, N = Phi.shape[0], len(u)
    m = np.asarray(model.initial_state(params))
    means, P = [m], [np.eye(n) * x0_std**2]
    for k in range(N - 1):
        m = Phi @ m + G0 @ u[k] + G1 @ (u[k + 1] - u[k])
        means.append(m)
        P.append(Phi @ P[-1] @ Phi.T + Q)
    Sx = np.zeros((N * n, N * n))
    for j in range(N):
        for k in range(j, N):
            c = np.linalg.matrix_power(Phi, k - j) @ P[j]  # Cov(x_k, x_j)
            Sx[k * n : (k + 1) * n, j * n : (j + 1) * n] = c
            Sx[j * n : (j + 1) * n, k * n : (k + 1) * n] = c.T
    mx = np.concatenate(means)
    Cb = np.kron(np.eye(N), C)
    my = Cb @ mx + (u @ D.T).ravel()
    Sy = Cb @ Sx @ Cb.T + np.kron(np.eye(N), np.diag(r**2))
    Sxy = Sx @ Cb.T
    return mx, Sx, my, Sy, Sxy, y.ravel()


def _dense_nll(my, Sy, yv):
    ok = np.isfinite(yv)
    e = (yv - my)[ok]
    S = Sy[np.ix_(ok, ok)]
    _, logdet = np.linalg.slogdet(S)
    return 0.5 * (logdet + e @ np.linalg.solve(S, e) + ok.sum() * np.log(2 * np.pi))


@pytest.fixture(scope="module")
def tite():
    return jaxbox.get_model("BM_TiTe")


@pytest.fixture(scope="module")
def short(tite):
    data = _dataset(tite, TITE, 14, seed=1, x0_std=1.0)
    y = data["T_zon"].copy()
    y[[3, 7, 8]] = np.nan  # missing outputs
    return Dataset(data.frame.assign(T_zon=y), check=False)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_kalman_nll_equals_dense_gaussian_likelihood(tite, short, hold):
    est = estimate_states(tite, TITE, short, hold=hold, x0_std=0.7)
    _, _, my, Sy, _, yv = _dense(tite, TITE, short, hold, x0_std=0.7)
    ref = _dense_nll(my, Sy, yv)
    assert abs(est.nll - ref) < 1e-9
    assert np.isnan(est.innovations[[3, 7, 8], 0]).all()
    assert np.isfinite(est.innovations[[0, 1, 2, 4], 0]).all()


def test_two_outputs_and_held_node_against_dense():
    net = (
        RCNetwork("TwoOut")
        .node("zon", output=True)
        .node("wal", output=True)
        .constant("gro")
        .resistance("zon", "wal", "R_int")
        .resistance("wal", "T_amb", "R_wal")
        .resistance("zon", "gro", "R_gro")
        .heat("zon", "Q_hea")
        .heat("zon", "I_glo_hor", gain="gA")
    )
    model = net.build()
    params = {
        "C_zon": 2e6,
        "C_wal": 2e7,
        "R_int": 3e-3,
        "R_wal": 2e-2,
        "R_gro": 5e-2,
        "gA": 2.0,
        "T_zon0": 20.0,
        "T_wal0": 15.0,
        "T_gro0": 10.0,
        "sigma_zon": 1e-3,
        "sigma_wal": 3e-4,
        "sigma_y_zon": 0.05,
        "sigma_y_wal": 0.1,
    }
    assert set(noise_names(model)) == {"sigma_zon", "sigma_wal", "sigma_y_zon", "sigma_y_wal"}
    data = _dataset(model, params, 10, seed=4)
    y = data["T_wal"].copy()
    y[[2, 5]] = np.nan  # one of two outputs missing
    data = Dataset(data.frame.assign(T_wal=y), check=False)
    est = estimate_states(model, params, data, x0_std=0.5)
    _, _, my, Sy, _, yv = _dense(model, params, data, x0_std=0.5)
    assert abs(est.nll - _dense_nll(my, Sy, yv)) < 1e-9
    # covariances stay symmetric positive definite; the held node never diffuses
    for P in (est.filtered_cov, est.predicted_cov, est.smoothed_cov):
        assert np.allclose(P, np.swapaxes(P, 1, 2), atol=0)
        assert (np.linalg.eigvalsh(P) > 0).all()
    Q = est.matrices[3]
    assert np.all(Q[2] == 0) and np.all(Q[:, 2] == 0)


def test_smoother_equals_dense_conditioning(tite, short):
    est = estimate_states(tite, TITE, short, x0_std=0.7)
    mx, Sx, my, Sy, Sxy, yv = _dense(tite, TITE, short, x0_std=0.7)
    ok = np.isfinite(yv)
    G = Sxy[:, ok] @ np.linalg.inv(Sy[np.ix_(ok, ok)])
    mean = mx + G @ (yv - my)[ok]
    cov = Sx - G @ Sxy[:, ok].T
    n = tite.n_states
    np.testing.assert_allclose(est.smoothed.ravel(), mean, rtol=0, atol=1e-8)
    for k in range(len(yv)):
        blk = cov[k * n : (k + 1) * n, k * n : (k + 1) * n]
        np.testing.assert_allclose(est.smoothed_cov[k], blk, rtol=1e-6, atol=1e-10)
    # the last filtered state is the last smoothed one
    np.testing.assert_allclose(est.filtered[-1], est.smoothed[-1])


def test_process_noise_van_loan_quadrature_and_lyapunov(tite):
    A, _, _, _ = (np.asarray(a) for a in tite.state_space(TITE))
    sig = np.array([2e-3, 5e-4])
    dt = 1800.0
    # Gauss–Legendre quadrature of the smooth integrand (60 nodes: exact to round-off here)
    x, w = np.polynomial.legendre.leggauss(60)
    s_nodes, w = 0.5 * dt * (x + 1), 0.5 * dt * w
    ref = sum(
        wi * sla.expm(A * si) @ np.diag(sig**2) @ sla.expm(A * si).T
        for si, wi in zip(s_nodes, w, strict=True)
    )
    Q1 = np.asarray(process_noise_van_loan(jnp.asarray(A), jnp.asarray(sig), dt))
    Q2 = np.asarray(
        process_noise(jnp.asarray(A), jnp.asarray(sig), dt, jnp.asarray(sla.expm(A * dt)))
    )
    np.testing.assert_allclose(Q1, ref, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(Q2, ref, rtol=1e-9, atol=1e-14)


def test_discretisation_matches_euler_maruyama_moments(tite):
    """Mean and covariance after one step from a known state, inputs linear over the step."""
    A, B, _, _ = (np.asarray(a) for a in tite.state_space(TITE))
    dt, steps, paths = 1800.0, 400, 40000
    prob_sys = _scipy_system(tite, TITE, dt, "foh")
    from jaxbox.stochastic import discretize

    Ar, Br, caps, held = tite.rc_form(TITE)
    Phi, G0, G1, Q = (
        np.asarray(a) for a in discretize(Ar, Br, caps, held, jnp.asarray([2e-3, 5e-4]), dt)
    )
    np.testing.assert_allclose(Phi, prob_sys[0], rtol=1e-10)
    x0 = np.array([20.0, 12.0])
    u0, u1 = np.array([5.0, 2000.0, 100.0]), np.array([7.0, 0.0, 300.0])
    rng = np.random.default_rng(0)
    h = dt / steps
    sig = np.array([2e-3, 5e-4])
    x = np.tile(x0, (paths, 1))
    for i in range(steps):
        uu = u0 + (u1 - u0) * (i + 0.5) / steps
        x = x + h * (x @ A.T + B @ uu) + np.sqrt(h) * sig * rng.standard_normal((paths, 2))
    mean = Phi @ x0 + G0 @ u0 + G1 @ (u1 - u0)
    tol = 4 * np.sqrt(np.diag(Q) / paths) + 1e-3
    assert np.all(np.abs(x.mean(0) - mean) < tol)
    emp = np.cov(x.T)
    # Monte Carlo error of a variance ≈ sqrt(2/paths) ≈ 0.7 %; Euler's bias O(h) is smaller
    np.testing.assert_allclose(np.diag(emp), np.diag(Q), rtol=0.04)
    corr = emp[0, 1] / np.sqrt(emp[0, 0] * emp[1, 1])
    assert abs(corr - Q[0, 1] / np.sqrt(Q[0, 0] * Q[1, 1])) < 0.03


def test_nll_gradient_matches_finite_differences(tite, short):
    dataset = _dataset(tite, TITE, 14, seed=2)
    sp = make_stochastic_problem(tite, dataset)
    dt, u, y = stochastic_arrays(tite, dataset)
    fixed = jnp.asarray([v for _, v in sp.fixed])
    pm, ps = sp.prior_arrays()
    p0 = np.asarray([TITE[n] for n in sp.free])
    import jax

    vg = jax.jit(jax.value_and_grad(lambda p: sp.objective_physical(p, fixed, pm, ps, dt, u, y)))
    g = np.asarray(vg(p0)[1])
    f = lambda p: float(vg(p)[0])  # noqa: E731
    for i in range(len(p0)):
        h = 1e-5 * abs(p0[i])
        e = np.zeros_like(p0)
        e[i] = h
        fd = (f(p0 + e) - f(p0 - e)) / (2 * h)
        assert abs(g[i] - fd) <= 1e-5 * abs(fd) + 1e-7 / abs(p0[i]), sp.free[i]


def test_k_step_errors(tite, short):
    est = estimate_states(tite, TITE, short)
    ks = est.k_step_errors((1, 3))
    np.testing.assert_allclose(ks[1]["errors"], est.innovations[1:], atol=1e-10)
    Phi, G0, G1, _, C, _ = est.matrices
    u, y = est.inputs, est.measured
    i = 9
    x = est.filtered[i]
    for j in range(3):
        x = Phi @ x + G0 @ u[i + j] + G1 @ (u[i + j + 1] - u[i + j])
    assert abs(ks[3]["errors"][i, 0] - (y[i + 3, 0] - (C @ x)[0])) < 1e-10
    frame = est.to_frame()
    assert {"T_zon_filtered", "T_wal_smoothed_sd", "T_zon_innovation"} <= set(frame.columns)
    assert est.current()["states"].keys() == {"T_zon", "T_wal"}


def test_bad_input_names_the_problem(tite, short):
    data = short
    with pytest.raises(FitError, match="sigma_foo"):
        make_stochastic_problem(tite, data, fixed={"sigma_foo": 1.0})
    with pytest.raises(FitError, match="sigma_y_zon"):
        make_stochastic_problem(tite, data, fixed={"sigma_y_zon": 0.0})
    with pytest.raises(FitError, match="missing: sigma_y_zon"):
        estimate_states(tite, {k: v for k, v in TITE.items() if k != "sigma_y_zon"}, data)
    with pytest.raises(FitError, match="prior"):
        make_stochastic_problem(tite, data, priors={"gA": (1.0, -1.0)})
    bad = data.frame.copy()
    bad.iloc[4, 0] = np.nan
    with pytest.raises(FitError, match="T_amb.*row 4"):
        estimate_states(tite, TITE, Dataset(bad, check=False))


def test_time_stamps_that_jump_are_refused(tite, short):
    """The filter discretises the model for one step: periods joined with a jump between them,
    or a first step twice as long as the others, are refused with the row, not filtered as if
    the samples were evenly spaced."""
    from jaxbox.data import concat_periods
    from jaxbox.stochastic import fit_ml

    joined = concat_periods([short.slice(None, short.index[5]), short.slice(short.index[9])])
    assert len(joined.segments) == 2
    with pytest.raises(FitError, match=r"row 6\) is 7200 s.*one segment"):
        estimate_states(tite, TITE, joined)
    with pytest.raises(FitError, match=r"row 6\)"):
        fit_ml(tite, joined, starts=1)
    with pytest.raises(FitError, match=r"row 6\)"):
        simulate_sde(tite, TITE, joined)
    late = Dataset(short.frame.drop(short.index[1]), check=False)  # the first step is 1 h
    with pytest.raises(FitError, match=r"row 1\) is 3600 s"):
        estimate_states(tite, TITE, late)


def test_data_of_the_wrong_type_is_named(tite, short):
    """A DataFrame is taken as data (as everywhere in jaxbox); a list, None or one dataset
    where a list of them is expected is a TypeError naming the argument."""
    from jaxbox.stochastic import fit_ml_many

    with pytest.warns(DataWarning, match="gaps"):  # loaded: its output gaps are reported
        est = estimate_states(tite, TITE, short.frame)
    assert est.nll == pytest.approx(estimate_states(tite, TITE, short).nll, rel=1e-12)
    for bad in (None, [1, 2, 3], short.frame.to_numpy()):
        with pytest.raises(TypeError, match="data must be a jaxbox Dataset"):
            estimate_states(tite, TITE, bad)
        with pytest.raises(TypeError, match="data must be a jaxbox Dataset"):
            make_stochastic_problem(tite, bad)
    with pytest.raises(TypeError, match="datasets must be a list of datasets, got one Dataset"):
        fit_ml_many(tite, short, starts=1)
    with pytest.raises(TypeError, match=r"datasets\[1\] must be a jaxbox Dataset"):
        fit_ml_many(tite, [short, None], starts=1)


def test_initial_state_spread_is_checked_by_the_state_estimator(tite, short):
    """estimate_states checks x0_std as the fit does (0 is allowed: states known exactly):
    a negative, NaN or overflowing spread, an unknown state or a string is named, not squared
    away or turned into a NaN likelihood."""
    assert np.isfinite(estimate_states(tite, TITE, short, x0_std=0.0).nll)
    for bad, match in (
        (-1.0, "x0_std must be finite and ≥ 0"),
        (float("nan"), "x0_std must be finite"),
        (1e200, "x0_std must be finite"),
        ({"T_foo": 1.0}, "no state.*T_foo; its states are T_zon, T_wal"),
        ({"T_zon": "a"}, "x0_std of T_zon must be a number"),
        ("a", "x0_std must be a number"),
        ([1.0, 2.0], "x0_std must be a number"),
    ):
        with pytest.raises(FitError, match=match):
            estimate_states(tite, TITE, short, x0_std=bad)
    with pytest.raises(FitError, match="x0_std must be finite and > 0"):
        make_stochastic_problem(tite, short, x0_std=1e200)


def test_state_estimator_parameters_are_checked(tite, short):
    """Parameters that are not a mapping, not numbers, unknown to the model, physically
    impossible (a capacity ≤ 0) or so extreme that the filter overflows are named, not
    returned as a NaN likelihood or a traceback from float()."""
    for change, match in (
        ({"C_zon": -1e6}, "C_zon is -1e\\+06; resistances and capacities must be > 0"),
        ({"R_wal": 0.0}, "R_wal is 0"),
        ({"gA": "x"}, "parameter gA must be a number, got 'x'"),
        ({"gA": None}, "parameter gA must be a number, got None"),
        ({"R_int": 1e-2}, "has no parameter\\(s\\) R_int.*another model"),
        ({"C_zon": 1e300, "C_wal": 1e300, "sigma_zon": 1e200}, "not finite from row 1"),
    ):
        with pytest.raises(FitError, match=match):
            estimate_states(tite, {**TITE, **change}, short)
    with pytest.raises(TypeError, match="params must be a mapping"):
        estimate_states(tite, list(TITE.values()), short)


def test_smoother_of_states_known_exactly_is_finite(tite, short):
    """No diffusion and initial states known exactly: every predicted covariance is 0, which
    has no Cholesky factor; the smoother's gain is then 0 (nothing to smooth), not NaN."""
    quiet = {**TITE, "sigma_zon": 0.0, "sigma_wal": 0.0}
    est = estimate_states(tite, quiet, short, x0_std=0.0)
    assert np.all(est.predicted_cov == 0.0)
    assert np.all(np.isfinite(est.smoothed)) and np.all(np.isfinite(est.smoothed_cov))
    np.testing.assert_allclose(est.smoothed, est.filtered, rtol=0, atol=1e-12)
    assert np.all(est.smoothed_cov == 0.0)


def test_problem_values_that_are_not_numbers_are_named(tite, short):
    """fixed, guess, bounds and priors: a value that is not a number, a bound with a third
    entry, a NaN guess, a mapping argument given as a string and free given as one name are
    named (or taken as that name), not left to float() or cut to their first items."""
    for kwargs, match in (
        ({"fixed": {"sigma_zon": "abc"}}, "fixed value of sigma_zon must be a number, got 'abc'"),
        ({"fixed": {"C_zon": None}}, "fixed value of C_zon must be a number, got None"),
        ({"guess": {"sigma_y_zon": "x"}}, "guess of sigma_y_zon must be a number"),
        ({"guess": {"sigma_zon": float("nan")}}, "guess of sigma_zon is nan; give a finite"),
        ({"bounds": {"sigma_zon": (1e-6, 1.0, 2.0)}}, "bounds of sigma_zon must be a pair"),
        ({"bounds": {"R_wal": (1e-3, 1.0, 2.0)}}, "bounds of R_wal must be a pair"),
        ({"bounds": {"gA": "ab"}}, "bounds of gA must be a pair"),
        ({"priors": {"gA": (1.0, "x")}}, "priors of gA must be a number"),
    ):
        with pytest.raises(FitError, match=match):
            make_stochastic_problem(tite, short, **kwargs)
    with pytest.raises(TypeError, match="fixed must be a mapping"):
        make_stochastic_problem(tite, short, fixed="sigma_zon")
    with pytest.raises(TypeError, match="free must be a list of parameter names"):
        make_stochastic_problem(tite, short, free=3)
    sp = make_stochastic_problem(tite, short, free="C_zon")
    assert sp.free == ("C_zon",)


def test_views_and_sampling_arguments_are_checked(tite, short):
    """k of the k-step errors, which of to_frame, replications, hold, x0_std and missing inputs
    of simulate_sde: named at the boundary, not iterated, truncated or turned into NaN."""
    est = estimate_states(tite, TITE, short)
    for k in (2.5, "2", True, None):
        with pytest.raises(ValueError, match="k must be a whole number of samples"):
            est.k_step_errors(k)
    assert list(est.k_step_errors(np.asarray([1, 3]))) == [1, 3]
    with pytest.raises(ValueError, match="which: no estimate 'smooth'; choose from"):
        est.to_frame(("filtered", "smooth"))
    assert "T_zon_filtered" in est.to_frame("filtered").columns
    for kwargs, match in (
        ({"replications": 0}, "replications must be an integer ≥ 1"),
        ({"hold": "xoh"}, "unknown hold 'xoh'"),
        ({"x0_std": -1.0}, "x0_std must be finite and ≥ 0"),
    ):
        with pytest.raises(FitError, match=match):
            simulate_sde(tite, TITE, short, **kwargs)
    bad = short.frame.copy()
    bad.iloc[2, 1] = np.nan
    with pytest.raises(FitError, match="input Q_hea is missing \\(NaN\\) at row 2"):
        simulate_sde(tite, TITE, Dataset(bad, check=False))
    y, x = simulate_sde(tite, TITE, short, x0_std={"T_wal": 0.0})
    assert x[0, 1] == TITE["T_wal0"] and x[0, 0] != TITE["T_zon0"]
