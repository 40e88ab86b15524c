"""Maximum likelihood shared across model structures: the stochastic form in array form equals
the per-structure one (and its padding stays inert), the filter's small products equal the dense
Gaussian likelihood, and structures of one padded size compile one solve and one Hessian."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_stochastic import _dense, _dense_nll, _inputs

import jaxbox
from jaxbox import _compiled
from jaxbox.data import Dataset
from jaxbox.stochastic import (
    estimate_states,
    fit_ml,
    make_stochastic_problem,
    noise_parameters,
    simulate_sde,
    solve_ml,
    stochastic_arrays,
    system,
)
from jaxbox.stochastic._arrays import ml_arrays, padded_sizes, system_from_arrays
from jaxbox.stochastic._kalman import kalman_scan


def _params(model, seed=0):
    """Every parameter of the stochastic form: defaults of the physical ones, moved at random
    within their bounds (initial states around 20 °C), and the noise defaults."""
    rng = np.random.default_rng(seed)
    out = {}
    for name in model.param_names:
        spec = model.parameter(name)
        if name.startswith("T_"):
            out[name] = 20.0 + 3.0 * rng.standard_normal()
        elif np.isfinite(spec.upper) and spec.lower > 0:
            out[name] = float(
                np.clip(spec.default * np.exp(0.3 * rng.standard_normal()), spec.lower, spec.upper)
            )
        else:
            out[name] = float(spec.default)
    out.update({p.name: p.default for p in noise_parameters(model)})
    return out


def _dataset(model, params, n, seed=0, x0_std=0.0):
    """Synthetic SDE data of ``model`` at half-hourly samples (inputs the test module's
    weather and heating; any other input a smooth daily signal)."""
    t, u = _inputs(n, seed=seed)
    day = np.sin(2 * np.pi * t / 86400)
    for name in model.inputs:
        if name not in u:
            u[name] = 12.0 + 2.0 * day if name.startswith("T_") else np.clip(300.0 * day, 0, None)
    base = Dataset.from_arrays(t, {**u, **{o: np.zeros(n) for o in model.outputs}})
    y, _ = simulate_sde(model, params, base, seed=seed + 100, x0_std=x0_std)
    return base.with_columns({o: y[:, j] for j, o in enumerate(model.outputs)})


@pytest.mark.parametrize(
    ("name", "hold"),
    [
        ("BM_TiTmTeThTs", "foh"),
        ("BM_TiTmTeThTs", "zoh"),
        ("ZonWalIntInfWinBouC", "foh"),
        ("BM_TiTe", "foh"),
    ],
)
def test_array_form_equals_the_structure_and_its_padding_is_inert(name, hold):
    model = jaxbox.get_model(name)
    params = _params(model, seed=len(name))
    data = _dataset(model, params, 40, seed=2, x0_std=0.5)
    sp = make_stochastic_problem(model, data, hold=hold, x0_std=0.7)
    dt, u, y = stochastic_arrays(model, data)
    sizes = padded_sizes([sp])
    n, m = model.n_states, len(model.inputs)
    arrays = ml_arrays(sp, sizes)
    values = [params[k] for k in sp.param_names]
    v = np.concatenate([values, np.zeros(sizes["params"] - len(values)), [1.0, 0.0]])
    got = jax.jit(lambda v, a: system_from_arrays(v, a, dt, hold))(jnp.asarray(v), arrays)
    ref = jax.jit(lambda p: system(model, p, dt, hold, sp.x0_std))(params)
    (Phi, G0, G1, Q), C, D, r, m0, P0 = (jax_tree_np(a) for a in got)
    (Phi_r, G0_r, G1_r, Q_r), C_r, D_r, r_r, m0_r, P0_r = (jax_tree_np(a) for a in ref)
    for a, b in ((Phi, Phi_r), (G0, G0_r), (G1, G1_r), (Q, Q_r)):
        block = a[:n, : b.shape[1]]
        assert np.max(np.abs(block - b)) <= 1e-12 * max(np.max(np.abs(b)), 1e-300)
    # padding: no input, no coupling, no diffusion, no initial mean or variance, not measured
    assert np.all(G0[n:] == 0) and np.all(G1[n:] == 0) and np.all(G0[:, m:] == 0)
    assert np.all(Phi[:n, n:] == 0) and np.all(Phi[n:, :n] == 0)
    assert np.all(Q[n:] == 0) and np.all(Q[:, n:] == 0)
    assert np.all(m0[n:] == 0) and np.all(P0[n:] == 0) and np.all(C[:, n:] == 0)
    np.testing.assert_array_equal(C[:, :n], C_r)
    np.testing.assert_allclose(m0[:n], m0_r, rtol=0, atol=0)
    np.testing.assert_allclose(P0[:n, :n], P0_r, rtol=1e-15)
    np.testing.assert_array_equal(r, r_r)
    u_pad = np.concatenate([u, np.zeros((len(u), sizes["inputs"] - m))], axis=1)
    nll = float(jax.jit(kalman_scan)((Phi, G0, G1, Q), C, D, r, m0, P0, u_pad, y))
    nll_ref = float(jax.jit(kalman_scan)((Phi_r, G0_r, G1_r, Q_r), C_r, D_r, r_r, m0_r, P0_r, u, y))
    assert abs(nll - nll_ref) <= 1e-10 * abs(nll_ref)


def jax_tree_np(a):
    return tuple(np.asarray(x) for x in a) if isinstance(a, tuple) else np.asarray(a)


def test_five_state_filter_equals_the_dense_gaussian_likelihood():
    """Five states: the filter's products written as broadcast sums (the small-state form)
    against the dense likelihood of the stacked outputs, with missing outputs."""
    model = jaxbox.get_model("BM_TiTmTeThTs")
    params = _params(model, seed=3)
    data = _dataset(model, params, 12, seed=6, x0_std=0.5)
    y = data["T_zon"].copy()
    y[[2, 9]] = np.nan
    data = Dataset(data.frame.assign(T_zon=y), check=False)
    est = estimate_states(model, params, data, x0_std=0.5)
    _, _, my, Sy, _, yv = _dense(model, params, data, x0_std=0.5)
    ref = _dense_nll(my, Sy, yv)
    assert abs(est.nll - ref) < 1e-9 * max(1.0, abs(ref))


@pytest.fixture(scope="module")
def short_n2():
    data = jaxbox.datasets.twinhouse_exp1("N2", "1h")
    return data.slice(None, data.index[79])


@pytest.mark.slow
def test_structures_of_one_padded_size_compile_once(short_n2):
    """BM_TiTe and BM_TiTh (two states, ten parameters each) share the compiled solve and the
    compiled Hessian: the second fit adds nothing to the cache, whatever ran before."""
    fit_ml("BM_TiTe", short_n2, starts=2, max_steps=60)
    before = _compiled.info("stochastic")["entries"]
    second = fit_ml("BM_TiTh", short_n2, starts=2, max_steps=60)
    assert _compiled.info("stochastic")["entries"] == before
    assert second.timing["compile_s"] == 0.0
    assert np.isfinite(second.loglik) and np.all(np.isfinite(second.hessian))


def _two_starts(model, data):
    """A job of ``model`` on ``data``: its guess and a start moved from it."""
    sp = make_stochastic_problem(model, data)
    guess = np.asarray([sp.guess_dict[k] for k in sp.free])
    starts = np.stack([guess, sp.transform.to_physical(sp.transform.to_internal(guess) + 0.3)])
    return sp, starts, stochastic_arrays(model, data)


def _together_equals_alone(jobs):
    """Each job's estimates and objective in one solve of all are its solve alone's."""
    together = solve_ml(jobs, max_steps=60)
    for i, job in enumerate(jobs):
        alone = solve_ml([job], max_steps=60)
        np.testing.assert_allclose(together["p_jobs"][i], alone["p_jobs"][0], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(
            together["objective"][together["job"] == i], alone["objective"], rtol=1e-10
        )


def test_jobs_of_different_structures_in_one_solve_equal_separate_solves(short_n2):
    """Two starts each (the shape of the fits above: the solve alone is already compiled)."""
    jobs = [_two_starts(jaxbox.get_model(name), short_n2) for name in ("BM_TiTe", "BM_TiTh")]
    _together_equals_alone(jobs)


def test_records_of_different_lengths_in_one_solve_equal_separate_solves(short_n2):
    """Records of 80 and 67 samples in one maximum-likelihood solve: the shorter is padded with
    missing samples to the longer's bucket, which add nothing to its likelihood; each record's
    estimates and objective are its solve alone's (the first alone has the shape of the solves
    above: already compiled). A record's Hessian is padded to its bucket of samples too; held
    against second differences of the unpadded likelihood in test_stochastic_ml."""
    from jaxbox.stochastic._fit import _pad_rows

    model = jaxbox.get_model("BM_TiTe")
    jobs = [_two_starts(model, d) for d in (short_n2, short_n2.slice(None, short_n2.index[66]))]
    assert [len(job[2][1]) for job in jobs] == [80, 67]
    _together_equals_alone(jobs)
    # the padding: inputs held, outputs missing, nothing changed before
    _, u, y = jobs[1][2]
    up, yp = _pad_rows(u, y, 80)
    assert up.shape == (80, u.shape[1]) and yp.shape == (80, y.shape[1])
    np.testing.assert_array_equal(up[:67], u)
    np.testing.assert_array_equal(up[67:], np.repeat(u[-1:], 13, axis=0))
    assert np.all(np.isnan(yp[67:])) and np.array_equal(yp[:67], y, equal_nan=True)


@pytest.mark.slow
def test_a_network_with_a_held_node_keeps_a_program_of_its_own():
    """A node at a constant temperature has no array form: its fit runs the per-structure
    program and still recovers a finite optimum with its intervals."""
    from jaxbox.models import RCNetwork
    from jaxbox.stochastic._arrays import has_array_form

    model = (
        RCNetwork("HeldGround")
        .node("zon", output=True)
        .constant("gro")
        .resistance("zon", "T_amb", "R_wal")
        .resistance("zon", "gro", "R_gro")
        .heat("zon", "Q_hea")
        .build()
    )
    assert not has_array_form(model)
    params = {"C_zon": 5e6, "R_wal": 1e-2, "R_gro": 4e-2, "T_zon0": 20.0, "T_gro0": 10.0}
    params.update(sigma_zon=1e-3, sigma_y_zon=0.05)
    data = _dataset(model, params, 60, seed=8)
    fit = fit_ml(model, data, starts=2, max_steps=80, fixed={"T_gro0": 10.0})
    assert np.isfinite(fit.loglik) and np.all(np.isfinite(fit.hessian))
    assert fit.timing["compile_s"] > 0
