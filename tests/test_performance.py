"""Performance properties that can be asserted without timing anything.

Compilation is reused across datasets of the same shape; a start's result does not depend on the
batch it ran in; a long series fits with memory bounded by the chunk of sensitivities; the
parallel-in-time simulation agrees with the sequential one. Speed itself lives in
``benchmarks/``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _reference import synthetic_building

from jaxbox.fit import compile_cache_info, fit_model, make_problem, problem_arrays
from jaxbox.fit._fit import solve_jobs, solve_starts
from jaxbox.models import get_model, list_models
from jaxbox.simulate import discretize_foh
from jaxbox.simulate._exact import discretize_foh_numpy, discretize_foh_rc, simulate_exact
from jaxbox.simulate._parallel import linear_recurrence, simulate_parallel

TRUTH = {"C_zon": 3.0e6, "C_wal": 4.0e7, "R_wal": 0.012, "gA": 2.5, "T_zon0": 26.0, "T_wal0": 19.0}


def _synthetic(n, seed=0, noise=0.02, step=3600.0, truth=TRUTH):
    return synthetic_building(get_model("ZonWal"), truth, n=n, seed=seed, noise=noise, step=step)


@pytest.fixture(scope="module")
def two_datasets():
    return _synthetic(200, seed=1), _synthetic(200, seed=2, truth=TRUTH | {"R_wal": 0.02})


def test_same_shape_reuses_the_compiled_solve(two_datasets):
    a, b = two_datasets
    # 12 starts: the shape of the fit in the next test, which then reuses this compiled solve
    fit_model("ZonWal", a, starts=12, seed=1)
    before = compile_cache_info()
    r = fit_model("ZonWal", b, starts=12, seed=4, bounds={"R_wal": (1e-4, 1.0)})
    after = compile_cache_info()
    assert after["compiles"] == before["compiles"]
    assert after["hits"] == before["hits"] + 1
    assert r.timing["compile_s"] == 0.0
    assert r.params["R_wal"] == pytest.approx(0.02, rel=0.05)


def test_a_start_does_not_depend_on_its_batch(two_datasets):
    data = two_datasets[0]
    problem = make_problem(get_model("ZonWal"), data)
    arrays = problem_arrays(problem, data)
    r = fit_model("ZonWal", data, starts=12, seed=0)
    x0s = r.starts.initial
    batched = {s: solve_starts(problem, x0s, arrays, slots=s) for s in (12, 4)}
    # the same steps and cost; the parameters to rounding: a batch of another shape is
    # vectorised differently (on AVX-512, 12 slots are a vector of 8 and one of 4), and the last
    # digits of a point in a flat valley carry ~1e-8 of it
    for s, out in batched.items():
        np.testing.assert_array_equal(out["steps"], r.starts.steps, err_msg=f"slots={s}")
        np.testing.assert_allclose(out["cost"], r.starts.cost, rtol=1e-10, err_msg=f"slots={s}")
        np.testing.assert_allclose(out["p"], r.starts.params, rtol=1e-7, err_msg=f"slots={s}")
    for i in range(0, 12, 5):
        alone = solve_starts(problem, x0s[i : i + 1], arrays)
        np.testing.assert_allclose(alone["p"][0], r.starts.params[i], rtol=1e-7)
        assert alone["cost"][0] == pytest.approx(r.starts.cost[i], rel=1e-9)
        assert alone["steps"][0] == r.starts.steps[i]


def test_datasets_batched_together_match_separate_fits(two_datasets):
    jobs = []
    for data in two_datasets:
        problem = make_problem(get_model("ZonWal"), data)
        x0 = np.asarray([[problem.guess_dict[n] for n in problem.free]])
        jobs.append(
            (
                problem,
                np.repeat(x0, 3, axis=0) * [[1.0], [1.3], [0.8]],
                problem_arrays(problem, data),
            )
        )
    together = solve_jobs(jobs)
    np.testing.assert_array_equal(together["job"], [0, 0, 0, 1, 1, 1])
    for j, job in enumerate(jobs):
        alone = solve_jobs([job])
        sl = together["job"] == j
        np.testing.assert_allclose(together["p"][sl], alone["p"], rtol=1e-7)
        np.testing.assert_allclose(together["cost"][sl], alone["cost"], rtol=1e-9)


def test_records_of_different_lengths_batch_together_and_share_a_program():
    """Buildings whose records differ in length (193 and 200 samples, one bucket of 208) go in
    one batched call, each padded at its end with samples of weight 0: each result is the one
    of its fit alone, to rounding; a later batch of other lengths in the same bucket (197, 205)
    runs the same compiled program, and lengths in another bucket (100) a batch of their own."""
    from jaxbox.fit import fit_batch
    from jaxbox.fit._fit import _pad_samples, bucket_samples

    assert [bucket_samples(n) for n in (193, 200, 208, 209, 492, 1250)] == [
        208,
        208,
        208,
        224,
        496,
        1280,
    ]
    truths = (TRUTH, TRUTH | {"R_wal": 0.02})
    datas = [_synthetic(n, seed=5 + k, truth=truths[k % 2]) for k, n in enumerate((193, 200))]
    requests = [{"model": "ZonWal", "data": d, "starts": 2, "seed": 1} for d in datas]
    together = fit_batch(requests)
    assert [r.timing["batch"] for r in together] == [2, 2]
    for req, r in zip(requests, together, strict=True):
        alone = fit_model(req["model"], req["data"], starts=2, seed=1)
        assert alone.timing.get("batch", 1) == 1
        assert r.n_samples == alone.n_samples == len(req["data"])
        assert r.cost == pytest.approx(alone.cost, rel=1e-9)
        for name, value in alone.params.items():
            assert r.params[name] == pytest.approx(value, rel=1e-6), name
    before = compile_cache_info()
    others = [_synthetic(n, seed=9 + k) for k, n in enumerate((197, 205))]
    again = fit_batch([{"model": "ZonWal", "data": d, "starts": 2, "seed": 1} for d in others])
    assert compile_cache_info()["compiles"] == before["compiles"]
    assert [r.timing["compile_s"] for r in again] == [0.0, 0.0]
    short = _synthetic(100, seed=11)
    apart = fit_batch([{"model": "ZonWal", "data": d, "starts": 2} for d in (short, datas[0])])
    assert [r.timing["batch"] for r in apart] == [1, 1]
    # the padding: times on at the step, inputs and outputs held, weights 0
    t, u, y, w = (np.arange(3.0) * 60.0, np.ones((3, 2)), np.ones((3, 1)), np.ones((3, 1)))
    tp, up, yp, wp = _pad_samples((t, u, y, w), 5)
    np.testing.assert_array_equal(tp, [0.0, 60.0, 120.0, 180.0, 240.0])
    assert up.shape == (5, 2) and yp.shape == (5, 1)
    np.testing.assert_array_equal(wp[:, 0], [1.0, 1.0, 1.0, 0.0, 0.0])


@pytest.mark.slow  # 20,000 samples
def test_long_series_memory_is_bounded():
    """20,000 samples (a scaled-down year of 10-minute data): the solve's memory stays a few bytes
    per sample, no Jacobian or reverse-mode tape of the series is kept."""
    truth = TRUTH | {"T_zon0": 20.0, "T_wal0": 15.0}
    short, long = (_synthetic(n, seed=3, step=600.0, truth=truth) for n in (2_000, 20_000))
    mem = {}
    for data in (short, long):
        problem = make_problem(get_model("ZonWal"), data)
        x0 = np.asarray([[problem.guess_dict[n] for n in problem.free]])
        out = solve_starts(problem, x0, problem_arrays(problem, data))
        mem[len(data)] = out["memory_bytes"]
        p = dict(zip(problem.free, out["p"][0], strict=True))
        assert out["code"][0] == 0
        assert p["R_wal"] == pytest.approx(truth["R_wal"], rel=0.02)
    if mem[20_000] < 0:
        pytest.skip("the backend reports no memory analysis")
    # the data (4 columns) plus chunked sensitivities: well under 2 kB a sample
    assert mem[20_000] < 2_000 * 20_000
    assert mem[20_000] < 12 * mem[2_000]


@pytest.mark.parametrize("n", [2, 7, pytest.param(481, marks=pytest.mark.slow)])
def test_parallel_and_sequential_simulation_agree(n):
    model = get_model("ZonWalIntInfWinBouC")
    theta = model.defaults()
    A, B, C, D = model.state_space(theta)
    x0 = model.initial_state(theta)
    rng = np.random.default_rng(0)
    u = jnp.asarray(rng.normal(size=(n, len(model.inputs))) * [5, 5, 400, 150, 150] + 15)
    # compiled, as in a fit (op by op, the associative scan's levels dispatch one at a time)
    ys, xs = jax.jit(simulate_exact)(A, B, C, D, x0, u, 3600.0)
    yp, xp = jax.jit(simulate_parallel)(A, B, C, D, x0, u, 3600.0)
    np.testing.assert_allclose(xp, xs, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(yp, ys, rtol=1e-12, atol=1e-10)


def test_parallel_in_time_through_the_public_api(two_datasets):
    from jaxbox.simulate import simulate_model

    data = two_datasets[0]
    seq = simulate_model("ZonWal", TRUTH, data)
    par = simulate_model("ZonWal", TRUTH, data, method="parallel")
    np.testing.assert_allclose(par.x, seq.x, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(par.y, seq.y, rtol=1e-12, atol=1e-10)


def test_linear_recurrence_carries_trailing_axes():
    rng = np.random.default_rng(1)
    Phi = jnp.asarray(0.3 * rng.normal(size=(3, 3)))
    d = jnp.asarray(rng.normal(size=(50, 3, 4)))
    x0 = jnp.asarray(rng.normal(size=(3, 4)))
    xs = [np.asarray(x0)]
    for k in range(50):
        xs.append(np.asarray(Phi) @ xs[-1] + np.asarray(d[k]))
    got = jax.jit(linear_recurrence)(Phi, d, x0)
    np.testing.assert_allclose(got, np.stack(xs), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", list_models())
def test_rc_route_matches_the_model_and_the_block_exponential(name):
    """The model's one assembly of A, B (incidence matrices) and the fit's discretisation
    through eigh: the same numbers as the Van Loan exponential (SciPy's) for every library
    model, and ``state_space`` is that assembly."""
    model = get_model(name)
    rng = np.random.default_rng(7)
    theta = {k: v * (1 + 0.3 * rng.random()) for k, v in model.defaults().items()}
    A, B, caps, held = model.rc_form(theta)
    A0, B0, _, _ = model.state_space(theta)
    np.testing.assert_allclose(A, A0, rtol=1e-13, atol=1e-20)
    np.testing.assert_allclose(B, B0, rtol=1e-13, atol=1e-20)
    for dt in (600.0, 3600.0):
        for got, ref in zip(
            discretize_foh_rc(A, B, caps, dt, held), discretize_foh_numpy(A0, B0, dt), strict=True
        ):
            scale = float(jnp.max(jnp.abs(ref)))
            np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12 * scale)


def test_rc_discretisation_is_cheap_to_differentiate_under_vmap():
    """The eigh route differentiates through a custom JVP: its forward Jacobian matches the one
    through the block-matrix exponential."""
    model = get_model("ZonWalIntInfWinBouC")
    names = model.param_names

    def disc(route):
        def f(p):
            theta = dict(zip(names, p, strict=True))
            A, B, caps, held = model.rc_form(theta)
            if route == "rc":
                return discretize_foh_rc(A, B, caps, 3600.0, held)
            return discretize_foh(A, B, 3600.0)

        return f

    p = jnp.asarray([model.defaults()[n] for n in names])
    J_rc = jax.jit(jax.jacfwd(disc("rc")))(p)
    J_vl = jax.jit(jax.jacfwd(disc("vanloan")))(p)
    for a, b in zip(J_rc, J_vl, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-9 * float(jnp.max(jnp.abs(b))))


def test_same_shaped_model_variants_in_one_call(two_datasets):
    """Two 3-state structures with 10 parameters each, several starts each, one compilation:
    each job's results match its own solve."""
    data = two_datasets[0]
    jobs = []
    for name in ("ZonWalIntInf", "BM_TiTmTe"):
        problem = make_problem(get_model(name), data)
        x0 = np.asarray([[problem.guess_dict[n] for n in problem.free]])
        jobs.append(
            (problem, np.repeat(x0, 2, axis=0) * [[1.0], [1.2]], problem_arrays(problem, data))
        )
    before = compile_cache_info()["compiles"]
    together = solve_jobs(jobs)
    assert compile_cache_info()["compiles"] == before + 1
    for j, job in enumerate(jobs):
        alone = solve_jobs([job])
        sl = together["job"] == j
        np.testing.assert_allclose(together["cost"][sl], alone["cost"], rtol=1e-8)
        # a sloppy direction (an internal mass the data hardly sees) amplifies round-off
        np.testing.assert_allclose(together["p"][sl], alone["p"], rtol=1e-4)


def test_fit_batch_groups_by_shape_and_reports_failures(two_datasets):
    """Requests of one shape share a compiled call, another length gets its own; a request that
    cannot be set up is returned as its error while the others are solved."""
    from jaxbox.fit import FitError, fit_batch

    a, b = two_datasets
    short = _synthetic(120, seed=5)
    requests = [
        {"model": "ZonWal", "data": a, "starts": 3, "seed": 2},
        {"model": "ZonWal", "data": short, "starts": 2},
        {"model": "ZonWal", "data": b, "starts": 3, "seed": 2, "bounds": {"R_wal": (1e-4, 1.0)}},
        {"model": "ZonWal", "data": a, "free": ["C_zon", "no_such_parameter"]},
    ]
    out = fit_batch(requests, errors="return")
    assert isinstance(out[3], FitError) and "no_such_parameter" in str(out[3])
    assert [r.timing["batch"] for r in out[:3]] == [2, 1, 2]
    for req, res in zip(requests[:3], out[:3], strict=True):
        alone = fit_model(
            req["model"],
            req["data"],
            **{k: v for k, v in req.items() if k not in ("model", "data")},
        )
        assert res.cost == pytest.approx(alone.cost, rel=1e-9)
        np.testing.assert_allclose(res.starts.params, alone.starts.params, rtol=1e-7)
    with pytest.raises(FitError, match="no_such_parameter"):
        fit_batch(requests)
    with pytest.raises(FitError, match="unknown fit argument"):
        fit_batch([{"model": "ZonWal", "data": a, "start": 3}])
