"""jaxbox.LevenbergMarquardt as an optimistix solver, other optimistix solvers plugged into the
fit, and the batched slot-refilling multistart against one start at a time."""

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
from _reference import ZONWALINTINF_TRUTH, synthetic_building

import jaxbox
from jaxbox.fit import LevenbergMarquardt, LMState, fit_model
from jaxbox.models import get_model

TRUTH = ZONWALINTINF_TRUTH


def _rosenbrock(y, args):
    a, b = args
    return jnp.stack([a - y["x"], jnp.sqrt(b) * (y["y"] - y["x"] ** 2)])


def test_solves_any_residual_function_through_optx_least_squares():
    """A pytree ``y``, any residual function: the minimum of Rosenbrock's function at (a, a²)."""
    solver = LevenbergMarquardt(rtol=1e-12, atol=1e-20)
    y0 = {"x": jnp.asarray(-1.2), "y": jnp.asarray(1.0)}
    sol = optx.least_squares(_rosenbrock, solver, y0, args=(1.5, 100.0), max_steps=500)
    assert sol.result == optx.RESULTS.successful
    np.testing.assert_allclose(sol.value["x"], 1.5, rtol=1e-8)
    np.testing.assert_allclose(sol.value["y"], 2.25, rtol=1e-8)
    # the same optimum as optimistix's own Levenberg–Marquardt
    stock = optx.least_squares(
        _rosenbrock,
        optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12),
        y0,
        args=(1.5, 100.0),
        max_steps=500,
    )
    np.testing.assert_allclose(sol.value["x"], stock.value["x"], rtol=1e-8)


def test_it_is_an_optimistix_solver_with_an_equinox_state():
    solver = jaxbox.LevenbergMarquardt()
    assert isinstance(solver, optx.AbstractLeastSquaresSolver)
    assert isinstance(solver.descent, optx.AbstractDescent)
    assert isinstance(solver.search, optx.AbstractSearch)
    y0 = jnp.asarray([0.0, 0.0])
    fn = lambda y, args: (_rosenbrock({"x": y[0], "y": y[1]}, (1.0, 10.0)), None)  # noqa: E731
    f_struct = jax.eval_shape(lambda: fn(y0, None)[0])
    state = solver.init(fn, y0, None, {}, f_struct, None, frozenset())
    assert isinstance(state, LMState)
    y, state, _ = solver.step(fn, y0, None, {}, state, frozenset())
    done, result = solver.terminate(fn, y, None, {}, state, frozenset())
    assert not bool(done) and result == optx.RESULTS.successful
    # a first point that cannot be evaluated ends the solve as a divergence
    bad = jnp.asarray([jnp.nan, 0.0])
    state = solver.init(fn, bad, None, {}, f_struct, None, frozenset())
    _, state, _ = solver.step(fn, bad, None, {}, state, frozenset())
    done, result = solver.terminate(fn, bad, None, {}, state, frozenset())
    assert bool(done) and result == optx.RESULTS.nonlinear_divergence


def test_vmap_over_starts_with_throw_false():
    solver = LevenbergMarquardt(rtol=1e-10, atol=1e-20)
    fn = lambda y, args: _rosenbrock({"x": y[0], "y": y[1]}, args)  # noqa: E731
    y0s = jnp.asarray([[-1.2, 1.0], [2.0, 2.0], [0.0, -3.0]])
    sols = jax.vmap(lambda y0: optx.least_squares(fn, solver, y0, args=(1.0, 10.0), throw=False))(
        y0s
    )
    np.testing.assert_allclose(sols.value, np.ones((3, 2)), rtol=1e-7)


@pytest.fixture(scope="module")
def building():
    return synthetic_building(get_model("ZonWalIntInf"), TRUTH, n=120, noise=0.05)


@pytest.mark.parametrize("name", ["ZonWal", "ZonWalIntInf", "BM_TiTe"])
@pytest.mark.slow
def test_stock_optimistix_lm_reaches_the_same_optimum(building, name):
    """From the same start, jaxbox's solver and optimistix's own reach the same cost (the
    solver alone: no continuation route, no release from the bounds)."""
    ours = fit_model(
        name,
        building,
        starts=1,
        max_steps=500,
        rtol=1e-12,
        atol=1e-20,
        homotopy=(),
        release=False,
    )
    stock = fit_model(
        name,
        building,
        starts=1,
        max_steps=500,
        solver=optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10),
    )
    assert ours.starts.status[0] == "converged"
    assert stock.starts.status[0] == "converged"
    np.testing.assert_allclose(stock.cost, ours.cost, rtol=1e-6)


#: jaxbox's solver, tight: the reference fit and the single starts below share one compiled solve
TIGHT = dict(rtol=1e-12, atol=1e-20, max_steps=500)


@pytest.fixture(scope="module")
def reference(building):
    """ZonWal from one start with jaxbox's solver at tight tolerances."""
    return fit_model("ZonWal", building, starts=1, **TIGHT)


@pytest.mark.slow
def test_other_optimistix_solvers_plug_in(building, reference):
    tight = dict(rtol=1e-10, atol=1e-12)
    ref = reference
    for solver in (optx.Dogleg(**tight), optx.GaussNewton(**tight)):
        r = fit_model("ZonWal", building, starts=1, max_steps=500, solver=solver)
        assert r.cost <= ref.cost * (1 + 1e-5), type(solver).__name__


def test_a_solver_that_is_not_one_is_refused(building):
    with pytest.raises(jaxbox.FitError, match="optimistix"):
        fit_model("Zon", building, solver="lm")


@pytest.mark.slow
def test_slot_refilling_batch_equals_one_start_at_a_time(building, reference):
    """The batched multistart, with few slots that refill, gives each start the result it gets
    when solved alone (the program of the reference fit: one start, the same settings)."""
    tight = TIGHT
    batched = fit_model("ZonWal", building, starts=6, seed=2, slots=2, **tight)
    wide = fit_model("ZonWal", building, starts=6, seed=2, slots=6, **tight)
    x0 = batched.starts.initial
    assert list(batched.starts.status) == list(wide.starts.status)
    np.testing.assert_allclose(batched.starts.cost, wide.starts.cost, rtol=1e-10)
    np.testing.assert_allclose(batched.starts.params, wide.starts.params, rtol=1e-6)
    for i in range(len(x0)):
        alone = fit_model("ZonWal", building, starts=x0[i : i + 1], **tight)
        assert alone.starts.status[0] == batched.starts.status[i]
        np.testing.assert_allclose(alone.starts.cost[0], batched.starts.cost[i], rtol=1e-10)
        np.testing.assert_allclose(alone.starts.params[0], batched.starts.params[i], rtol=1e-6)


def test_default_slots_fill_a_cpu_in_groups_and_an_accelerator_at_once():
    from jaxbox.fit._fit import default_slots

    assert [default_slots(n, "cpu") for n in (1, 8, 64, 1024, 8192)] == [1, 8, 8, 8, 8]
    assert [default_slots(n, "gpu") for n in (1, 64, 8192)] == [1, 64, 8192]
    assert default_slots(10**6, "gpu") == 16384  # bounded by memory
    # where a narrow batch runs parallel in time, up to 1024 starts share 256 refilling slots
    assert [default_slots(n, "gpu", parallel=True) for n in (64, 300, 1024, 1025)] == [
        64,
        256,
        256,
        1025,
    ]
    assert default_slots(1024, "cpu", parallel=True) == 8  # never on a CPU
    assert default_slots(64) == default_slots(64, jax.default_backend())


def test_fit_and_a_selection_case_draw_the_same_starts(building):
    """One start sampler: fit_model(starts=8) and a selection case with 8 starts."""
    from jaxbox.select import lhs_starts, naming_guess

    model = get_model("ZonWalIntInf")
    guess = naming_guess(model, building).values
    names, case_starts = lhs_starts(model, building, guess, 8, seed=5)
    result = fit_model(model, building, starts=8, seed=5, max_steps=1)
    assert names == result.problem.free
    np.testing.assert_array_equal(case_starts, result.starts.initial)
