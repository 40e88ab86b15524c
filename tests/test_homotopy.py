"""The observer-gain continuation of the fit: the fused normal equations with an observer gain
against complex-step derivatives of an independent recursion, the stages of the batched
multistart, and the checks of the ``homotopy`` argument."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _reference import ZONWALINTINF_TRUTH, synthetic_building, van_loan_outputs

import jaxbox
from jaxbox.fit import DEFAULT_HOMOTOPY, fit_model
from jaxbox.models import get_model
from jaxbox.simulate._exact import normal_equations

TRUTH = ZONWALINTINF_TRUTH

N_STATES, N_INPUTS, N_SAMPLES = 3, 2, 23
OUTPUTS = (0, 2)


def _matrices(v, xp=jnp):
    """A small stable discrete system whose matrices depend smoothly on ``v`` [4] (``xp``:
    ``jax.numpy``, or ``numpy`` for the complex-step reference)."""
    a = xp.asarray([[0.80, 0.10, 0.00], [0.05, 0.90, 0.03], [0.00, 0.10, 0.70]])
    Phi = a * (1.0 + 0.1 * xp.tanh(v[0])) + 0.02 * v[1] * xp.eye(N_STATES)
    G0 = xp.asarray([[0.10, 0.02], [0.00, 0.05], [0.03, 0.00]]) * xp.exp(0.2 * v[2])
    G1 = 0.3 * G0 * v[1]
    x0 = xp.asarray([20.0, 15.0, 18.0]) + v[3] * xp.asarray([1.0, -2.0, 0.5])
    return Phi, G0, G1, x0


def _reference_residuals(v, gain, u, y, w):
    """The observer recursion written out sample by sample in NumPy (complex ``v`` allowed): the
    residual at sample k is the prediction's, then the measured states are pulled towards their
    measurements."""
    Phi, G0, G1, x = _matrices(v, np)
    out = list(OUTPUTS)
    res = []
    for k in range(u.shape[0]):
        pred = x[out]
        res.append(w[k] * (pred - y[k]))
        if k + 1 < u.shape[0]:
            corr = x.copy()
            corr[out] += -gain * (w[k] > 0) * (pred - y[k])
            x = Phi @ corr + G0 @ u[k] + G1 @ (u[k + 1] - u[k])
    return np.concatenate(res)


@pytest.fixture(scope="module")
def series():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(N_SAMPLES, N_INPUTS))
    y = 18.0 + rng.normal(size=(N_SAMPLES, len(OUTPUTS)))
    w = np.ones_like(y)
    w[5, 0] = 0.0  # a masked sample: no residual and no correction there
    w[11:14, 1] = 0.0
    return u, y, w


@jax.jit
def _fused(prim, tang, gain, u, y, w):
    """The fused pass with a per-member gain (one compiled program for every case)."""
    return normal_equations(prim, tang, OUTPUTS, u, y, w, chunk=4, gain=gain)


def _written_out(v, gain, u, y, w):
    """The written-out recursion's residuals and their Jacobian by complex steps (exact to
    rounding for this analytic recursion, and independent of JAX's differentiation)."""
    v = np.asarray(v, float)
    h = 1e-30
    J = np.stack(
        [_reference_residuals(v + 1j * h * e, gain, u, y, w).imag / h for e in np.eye(len(v))], 1
    )
    return _reference_residuals(v, gain, u, y, w), J


@pytest.mark.parametrize("gains", [(0.0, 0.0), (0.9, 0.3), (1.0, 0.05)])
def test_normal_equations_with_an_observer_gain(series, gains):
    """Cost, Jᵀr and JᵀJ of the fused pass with a per-member gain equal those of complex steps
    through the written-out recursion (chunks of 4 samples, so a chunk is padded)."""
    u, y, w = series
    V = jnp.asarray([[0.1, 0.2, -0.3, 0.4], [-0.2, 0.1, 0.2, -0.1]])
    prim = jax.vmap(_matrices)(V)
    tang = jax.vmap(jax.jacfwd(_matrices))(V)
    args = tuple(jnp.asarray(a)[:, None] for a in (u, y, w))
    cost, g, H = _fused(prim, tang, jnp.asarray(gains), *args)
    for b in range(2):
        r, J = (np.asarray(a) for a in _written_out(V[b], gains[b], u, y, w))
        np.testing.assert_allclose(cost[b], r @ r, rtol=1e-12)
        np.testing.assert_allclose(g[b], J.T @ r, rtol=1e-10, atol=1e-12 * np.abs(J.T @ r).max())
        np.testing.assert_allclose(H[b], J.T @ J, rtol=1e-10, atol=1e-12 * np.abs(J.T @ J).max())
    # a zero gain is the output error itself
    if gains == (0.0, 0.0):
        plain = normal_equations(prim, tang, OUTPUTS, *args, chunk=4)
        for a, b in zip(plain, (cost, g, H), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-13)


@pytest.fixture(scope="module")
def building():
    return synthetic_building(get_model("ZonWalIntInf"), TRUTH, n=120, noise=0.05)


@pytest.fixture(scope="module")
def fits(building):
    """ZonWalIntInf from the same 12 starts, with and without the continuation."""
    common = dict(starts=12, seed=1, max_steps=200)
    return (
        fit_model("ZonWalIntInf", building, **common),
        fit_model("ZonWalIntInf", building, homotopy=(), **common),
    )


def test_the_reported_cost_is_the_output_error(building, fits):
    """Whatever stages a start went through, its cost is the output error (no observer) of its
    parameters, against the independent Van Loan simulation."""
    cont, _ = fits
    assert cont.settings["homotopy"] == DEFAULT_HOMOTOPY
    model = get_model("ZonWalIntInf")
    for i in np.argsort(cont.starts.cost)[:3]:
        theta = dict(zip(cont.free, cont.starts.params[i], strict=True))
        sim = van_loan_outputs(model, theta, building)[:, 0]
        cost = np.mean((sim - building.array(["T_zon"])[:, 0]) ** 2)
        np.testing.assert_allclose(cont.starts.cost[i], cost, rtol=1e-9)


def test_stages_count_in_the_steps_and_reach_the_optimum(fits):
    """Each start takes at least one step per stage; the continuation reaches the best cost of
    plain output error from at least as many starts, and its best is no worse."""
    cont, plain = fits
    assert np.all(cont.starts.steps >= len(DEFAULT_HOMOTOPY) + 1)
    best = min(cont.cost, plain.cost)
    assert cont.cost <= plain.cost * (1 + 1e-6)

    def at(r):
        return int(np.sum(r.starts.cost <= best * (1 + 1e-4)))

    assert at(cont) >= at(plain)
    assert at(cont) >= 6


@pytest.mark.parametrize(
    "homotopy, match",
    [
        ((1.5,), "in \\(0, 1\\]"),
        ((0.2, 0.5), "decrease"),
        ((0.5, 0.0), "in \\(0, 1\\]"),
        ("0.5", "sequence"),
    ],
)
def test_bad_homotopy_is_refused(building, homotopy, match):
    with pytest.raises(jaxbox.FitError, match=match):
        fit_model("Zon", building, homotopy=homotopy)


@pytest.fixture(scope="module")
def released(building):
    """Plain output error from the same 12 starts, without and with the release."""
    common = dict(starts=12, seed=2, max_steps=200, homotopy=())
    return (
        fit_model("ZonWalIntInf", building, release=False, **common),
        fit_model("ZonWalIntInf", building, release=True, **common),
    )


def _on_a_bound(result) -> np.ndarray:
    """Starts that ended with a two-sided parameter within 0.1 % of its bounds."""
    from jaxbox.fit._fit import EDGE
    from jaxbox.fit._transforms import position_in_bounds, two_sided

    tr = result.problem.transform
    z = tr.to_internal(result.starts.params)
    pos = np.asarray(position_in_bounds(tr.style, jnp.asarray(z)))
    return np.any(two_sided(tr.kinds) & ((pos < EDGE) | (pos > 1 - EDGE)), axis=1)


def test_release_frees_starts_trapped_on_a_bound(released):
    """Starts that end with a parameter frozen on its bound are solved again with it released
    and most reach the optimum (none of them had: 6 of 7 do); the other starts are untouched
    (the same steps, the same cost to rounding: the two fits are different programs)."""
    trapped_fit, freed = released
    on_bound = _on_a_bound(trapped_fit)
    assert on_bound.sum() >= 3
    best = min(trapped_fit.cost, freed.cost)
    before = trapped_fit.starts.cost <= best * (1 + 1e-4)
    at = freed.starts.cost <= best * (1 + 1e-4)
    assert not np.any(before[on_bound])
    assert at[on_bound].mean() >= 0.75
    assert np.sum(at) > np.sum(trapped_fit.starts.cost <= best * (1 + 1e-4))
    np.testing.assert_allclose(
        freed.starts.cost[~on_bound], trapped_fit.starts.cost[~on_bound], rtol=1e-12
    )
    np.testing.assert_array_equal(
        freed.starts.steps[~on_bound], trapped_fit.starts.steps[~on_bound]
    )
    assert np.all(freed.starts.steps[on_bound] > trapped_fit.starts.steps[on_bound])


def test_a_trapped_parameter_is_released_towards_the_guess(building):
    """The release moves a trapped coordinate towards the problem's guess, or towards the
    middle of its bounds where the guess itself lies on a bound; a caller's guess is the one
    used."""
    from jaxbox.fit import make_problem
    from jaxbox.fit._fit import _anchors

    problem = make_problem(get_model("ZonWal"), building)
    tr = problem.transform
    guess = np.asarray([problem.guess_dict[k] for k in problem.free])
    np.testing.assert_allclose(_anchors(problem), tr.to_internal(guess))
    k = problem.free.index("R_wal")
    lo = float(tr.lower[k])
    moved = make_problem(get_model("ZonWal"), building, guess={"R_wal": lo, "C_wal": 3e6})
    anchors = _anchors(moved)
    assert anchors[k] == 0.0  # the middle of the bounds
    j = problem.free.index("C_wal")
    expected = tr.to_internal(np.where(np.arange(len(guess)) == j, 3e6, guess))[j]
    assert anchors[j] == pytest.approx(expected)


def test_the_continuation_for_the_first_starts_only(building, fits):
    """``continued=k``: the first ``k`` starts of a request take both routes, the others the
    output-error route alone; each start's result is that of the call that gives it those
    routes, and the skipped routes cost no steps. The same compiled program serves any ``k``."""
    from jaxbox.fit import compile_cache_info, fit_batch

    cont, plain = fits
    common = dict(model="ZonWalIntInf", data=building, starts=12, seed=1, max_steps=200)
    before = compile_cache_info()["compiles"]
    part, none = (fit_batch([dict(common, continued=k)])[0] for k in (4, 0))
    assert compile_cache_info()["compiles"] == before
    assert part.settings["continued"] == 4
    np.testing.assert_array_equal(part.starts.cost[:4], cont.starts.cost[:4])
    np.testing.assert_array_equal(part.starts.steps[:4], cont.starts.steps[:4])
    # the others: the output-error route alone, whatever k (the same program)
    np.testing.assert_array_equal(part.starts.cost[4:], none.starts.cost[4:])
    np.testing.assert_array_equal(part.starts.steps[4:], none.starts.steps[4:])
    # … which is the plain fit's (another program: the same to rounding, but for a start that
    # ends in a flat valley, where rounding moves its end)
    same = np.abs(none.starts.cost / plain.starts.cost - 1) < 1e-9
    assert same.sum() >= 10
    np.testing.assert_array_equal(none.starts.steps[same], plain.starts.steps[same])
    assert none.starts.steps.sum() < part.starts.steps.sum() < cont.starts.steps.sum()


def test_polish_solves_the_best_starts_on(building, fits):
    """``polish=k``: every start is solved to :data:`POLISH_RTOL` (its result the one of a fit
    at that tolerance), then the ``k`` best on from where they ended; the best reaches the
    full fit's optimum (to 1e-8 of its cost: the polishing pass stops a hundred times tighter
    than ``rtol``), for fewer steps in all. One compiled program serves both passes, the full
    fit and the loose one (the tolerance is an argument)."""
    from jaxbox.fit import compile_cache_info, fit_batch
    from jaxbox.fit._fit import POLISH_RTOL

    cont, _ = fits
    common = dict(model="ZonWalIntInf", data=building, starts=12, seed=1, max_steps=200)
    before = compile_cache_info()["compiles"]
    polished = fit_batch([dict(common, polish=2)])[0]
    loose = fit_batch([dict(common, rtol=POLISH_RTOL)])[0]
    assert compile_cache_info()["compiles"] == before
    assert polished.settings["polish"] == 2 and cont.settings["polish"] is None
    # the two best of the loose fit went on; the other ten are the loose fit's starts
    on = np.argsort(loose.starts.cost, kind="stable")[:2]
    rest = np.setdiff1d(np.arange(12), on)
    np.testing.assert_array_equal(polished.starts.cost[rest], loose.starts.cost[rest])
    np.testing.assert_array_equal(polished.starts.steps[rest], loose.starts.steps[rest])
    assert np.all(polished.starts.cost[on] <= loose.starts.cost[on])
    assert np.all(polished.starts.steps[on] > loose.starts.steps[on])
    # the best: the full fit's optimum, to its tolerance, and its parameters with it
    assert polished.best in on
    assert polished.cost == pytest.approx(cont.cost, rel=1e-8)
    for name, value in cont.params.items():
        assert polished.params[name] == pytest.approx(value, rel=1e-3, abs=1e-9), name
    assert polished.starts.steps.sum() < cont.starts.steps.sum()


def test_polish_in_a_bucketed_batch_of_parts(building, monkeypatch):
    """A bucketed batch dealt to two parts, more starts in all than a part holds: the polishing
    pass takes each request's best start on wherever it ran, and each request's best is the
    one of its unpolished batch (to 1e-6: on this building the aperture's optimum lies on its
    bound, approached rather than reached by either)."""
    from jaxbox.fit import fit_batch

    monkeypatch.setenv("JAXBOX_THREADS", "2")
    reqs = [dict(model="Zon", data=building, starts=50, seed=s, max_steps=60) for s in range(3)]
    polished = fit_batch([dict(r, polish=1) for r in reqs], bucket=True)
    full = fit_batch(reqs, bucket=True)
    assert polished[0].timing["parts"] == 2
    for a, b in zip(polished, full, strict=True):
        assert a.cost == pytest.approx(b.cost, rel=1e-6)
        assert a.starts.steps.sum() < b.starts.steps.sum()


@pytest.mark.parametrize("value", [0, -1, 1.5, True, "2"])
def test_bad_polish_is_refused(building, value):
    from jaxbox.fit import fit_batch

    with pytest.raises(jaxbox.FitError, match="polish must be None or a whole number"):
        fit_batch([dict(model="Zon", data=building, polish=value)])


def test_polish_needs_jaxbox_solver(building):
    import optimistix as optx

    from jaxbox.fit import fit_batch

    solver = optx.Dogleg(rtol=1e-6, atol=1e-9)
    with pytest.raises(jaxbox.FitError, match="polish needs jaxbox.LevenbergMarquardt"):
        fit_batch([dict(model="Zon", data=building, solver=solver, polish=1)])


@pytest.mark.parametrize("value", [-1, 1.5, True, "2"])
def test_bad_continued_is_refused(building, value):
    from jaxbox.fit import fit_batch

    with pytest.raises(jaxbox.FitError, match="continued must be None or a whole number"):
        fit_batch([dict(model="Zon", data=building, continued=value)])


def test_continued_per_request_in_a_bucketed_batch(building):
    """Requests of other structures batched and bucketed (padding starts never solved), each
    with its own ``continued``: every start's result is the one of its request's batch with
    every start along both routes, or along the output error alone, as its place says."""
    from jaxbox.fit import fit_batch

    def batch(ks, **kw):
        reqs = [
            dict(model=m, data=building, starts=6, seed=4, max_steps=100, continued=k, **kw)
            for m, k in zip(("Zon+Wal", "ZonWalIntInf"), ks, strict=True)
        ]
        return fit_batch(reqs, bucket=True)

    mixed = batch((2, 0))
    both = batch((None, None))
    plain = batch((0, 0))
    np.testing.assert_array_equal(mixed[0].starts.cost[:2], both[0].starts.cost[:2])
    np.testing.assert_array_equal(mixed[0].starts.cost[2:], plain[0].starts.cost[2:])
    np.testing.assert_array_equal(mixed[1].starts.cost, plain[1].starts.cost)
    np.testing.assert_array_equal(mixed[1].starts.steps, plain[1].starts.steps)
    assert mixed[0].settings["continued"] == 2 and both[0].settings["continued"] is None
