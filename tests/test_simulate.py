"""Simulation: exact first-order hold vs diffrax vs analytic solutions."""

import jax
import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.models import get_model
from jaxbox.simulate import simulate_arrays, simulate_model

DT = 3600.0


@pytest.fixture(scope="module")
def inputs():
    n = 200
    t = np.arange(n) * DT
    rng = np.random.default_rng(1)
    day = 2 * np.pi * t / 86400
    u = {
        "T_amb": 10 + 6 * np.sin(day) + rng.normal(0, 0.5, n),
        "Q_hea": 500.0 * (rng.random(n) > 0.6),
        "I_glo_hor": np.maximum(0, 500 * np.sin(day)),
    }
    return t, u


def _u(model, u):
    return np.stack([u[name] for name in model.inputs], axis=1)


def test_one_state_matches_analytic_ramp_response():
    """T_amb = a + b t (linear, so first-order hold is exact), constant Q and I."""
    m = get_model("Zon")
    th = {"C_zon": 3e6, "R_wal": 0.01, "gA": 2.0, "T_zon0": 25.0}
    tau = th["C_zon"] * th["R_wal"]
    n = 100
    t = np.arange(n) * DT
    a, b, q, irr = 5.0, 2e-5, 800.0, 150.0
    u = {"T_amb": a + b * t, "Q_hea": np.full(n, q), "I_glo_hor": np.full(n, irr)}
    extra = th["R_wal"] * (q + th["gA"] * irr)
    particular = a + b * t - b * tau + extra
    analytic = particular + (th["T_zon0"] - (a - b * tau + extra)) * np.exp(-t / tau)
    for method, opts in (("exact", {}), ("diffrax", {"rtol": 1e-11, "atol": 1e-11})):
        y, _ = simulate_arrays(m, th, t, _u(m, u), method=method, **opts)
        np.testing.assert_allclose(np.asarray(y[:, 0]), analytic, atol=1e-8, rtol=0)


def test_exact_and_diffrax_agree_at_tight_tolerance(inputs):
    """Two states under switching heating (kinks the step control must land on); the one-state
    model's diffrax route is held to its analytic solution above."""
    t, u = inputs
    m = get_model("ZonWal")
    th = m.defaults() | {"T_zon0": 24.0}
    y1, x1 = simulate_arrays(m, th, t, _u(m, u), method="exact")
    y2, x2 = simulate_arrays(m, th, t, _u(m, u), method="diffrax", rtol=1e-10, atol=1e-10)
    assert np.max(np.abs(np.asarray(x1) - np.asarray(x2))) <= 1e-6
    assert np.max(np.abs(np.asarray(y1) - np.asarray(y2))) <= 1e-6


@pytest.mark.slow
def test_fixed_step_diffrax_converges_to_exact(inputs):
    """Fixed steps on the sample grid converge to the exact solution.

    Kvaerno5 (an ESDIRK of stage order 2) shows order reduction under the sampled, piecewise
    linear forcing at these step sizes (|hλ| ≈ 0.4): the observed order is 2, not 5.
    """
    t, u = inputs
    m = get_model("ZonWal")
    th = m.defaults()
    y_ex, _ = simulate_arrays(m, th, t, _u(m, u))
    errs = []
    for k in (1, 2, 4):
        y, _ = simulate_arrays(m, th, t, _u(m, u), method="diffrax", adaptive=False, substeps=k)
        errs.append(float(np.max(np.abs(np.asarray(y) - np.asarray(y_ex)))))
    orders = np.log2(np.asarray(errs[:-1]) / np.asarray(errs[1:]))
    assert np.all(orders > 1.8), orders
    assert errs[0] < 0.05


def test_simulate_on_a_dataset_and_vmap_over_parameters(inputs):
    t, u = inputs
    m = get_model("Zon")
    ds = Dataset.from_arrays(t, u)
    sim = simulate_model(m, None, ds)
    assert sim.y.shape == (len(t), 1) and sim.x.shape == (len(t), 1)
    th = {k: np.full(5, v) for k, v in m.defaults().items()}
    th["R_wal"] = np.linspace(0.005, 0.02, 5)
    ys, _ = jax.jit(jax.vmap(lambda p: simulate_arrays(m, p, t, _u(m, u))))(th)
    assert ys.shape == (5, len(t), 1)
    y2, _ = simulate_arrays(m, {k: v[2] for k, v in th.items()}, t, _u(m, u))
    np.testing.assert_allclose(np.asarray(ys[2]), np.asarray(y2), rtol=1e-12)


def test_simulate_errors(inputs):
    from jaxbox.data import DataError
    from jaxbox.models import ModelError

    t, u = inputs
    m = get_model("Zon")
    ds = Dataset.from_arrays(t, {"T_amb": u["T_amb"], "Q_hea": u["Q_hea"]})
    with pytest.raises(DataError, match="I_glo_hor"):
        simulate_model(m, None, ds)
    ds = Dataset.from_arrays(t, u)
    with pytest.raises(ModelError, match="no value for parameter"):
        simulate_model(m, {"C_zon": 1e6}, ds)
    with pytest.raises(ModelError, match="no parameter"):
        simulate_model(m, m.defaults() | {"R_x": 1.0}, ds)
    with pytest.raises(ValueError, match="unknown simulation method"):
        simulate_model(m, None, ds, method="euler")
    # a non-physical value is refused by name, before anything runs
    for method in ("exact", "diffrax"):
        with pytest.raises(ModelError, match="C_zon = -1e\\+06 is not positive; a capacity"):
            simulate_model(m, m.defaults() | {"C_zon": -1e6}, ds, method=method)
    with pytest.raises(ModelError, match="R_wal = 0 is not positive; a resistance"):
        simulate_model(m, m.defaults() | {"R_wal": 0.0}, ds)
    with pytest.raises(ModelError, match="gA is nan; give a finite value"):
        simulate_model(m, m.defaults() | {"gA": float("nan")}, ds)
    # a traced value (under jit) is left to the computation that uses it
    from jaxbox.simulate._simulate import check_theta

    th = m.defaults()
    assert jax.jit(lambda c: check_theta(m, th | {"C_zon": c})["C_zon"])(-1.0) == -1.0


def test_hostile_parameters_are_refused_by_name(inputs):
    from jaxbox.models import ModelError

    t, u = inputs
    ds = Dataset.from_arrays(t, u)
    m = get_model("Zon")
    th = m.defaults()
    for bad in ("2e6", None, True, 1 + 2j):
        with pytest.raises(TypeError, match="parameter C_zon is .*; give a number in J/K"):
            simulate_model(m, th | {"C_zon": bad}, ds)
    with pytest.raises(ModelError, match="C_zon has shape \\(2,\\); give one number"):
        simulate_model(m, th | {"C_zon": np.array([2e6, 3e6])}, ds)
    ok = simulate_model(m, th | {"C_zon": np.array([th["C_zon"]])}, ds)  # one value, any shape
    np.testing.assert_array_equal(ok.y, simulate_model(m, th, ds).y)
    with pytest.raises(TypeError, match="must be a mapping"):
        simulate_model(m, list(th.values()), ds)
    with pytest.raises(ModelError, match="T_zon0 = 293.15 looks like kelvin"):
        simulate_model(m, th | {"T_zon0": 293.15}, ds)
    bm = get_model("BM_TiTe")  # fra_wal splits R_wal: fra_wal·R_wal and (1 − fra_wal)·R_wal
    for fra in (0.0, 1.0, 1.5):
        with pytest.raises(ModelError, match="fra_wal = .* strictly between 0 and 1"):
            simulate_model(bm, bm.defaults() | {"fra_wal": fra}, ds)
    rad = get_model("Zon+Int+Rad")  # fra_rad and 1 − fra_rad share Q_hea
    with pytest.raises(ModelError, match="fra_rad = 1.2 lies outside \\[0, 1\\]"):
        simulate_model(rad, rad.defaults() | {"fra_rad": 1.2}, ds)
    simulate_model(rad, rad.defaults() | {"fra_rad": 1.0}, ds)  # all of it to the mass: fine


@pytest.mark.slow
def test_hostile_data_options_and_x0_are_refused_early(inputs):
    from jaxbox.data import DataError, prepare_window
    from jaxbox.models import ModelError

    t, u = inputs
    ds = Dataset.from_arrays(t, u)
    m = get_model("Zon")
    with pytest.raises(TypeError, match="must be a jaxbox.data.Dataset, got DataFrame"):
        simulate_model(m, None, ds.frame)
    gap = dict(u, T_amb=np.where((t > 5 * DT) & (t < 9 * DT), np.nan, u["T_amb"]), T_zon=20.0)
    with pytest.raises(DataError, match="input 'T_amb' of model Zon is NaN .* at 3 sample"):
        simulate_model(m, None, Dataset.from_arrays(t, gap))
    with pytest.warns(Warning):
        cut = prepare_window(Dataset.from_arrays(t, gap), m.inputs, m.outputs, max_gap=0)
    with pytest.raises(ModelError, match="2 segments .* simulate model.segmented\\(2\\)"):
        simulate_model(m, None, cut)
    two = m.segmented(2)
    exact = simulate_model(two, None, cut).y
    np.testing.assert_allclose(simulate_model(two, None, cut, method="diffrax").y, exact, atol=1e-4)
    with pytest.raises(TypeError, match="rtol apply to method='diffrax' only"):
        simulate_model(m, None, ds, rtol=1e-3)
    with pytest.raises(TypeError, match="no option\\(s\\) step; its options are adaptive"):
        simulate_model(m, None, ds, method="diffrax", step=1)
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="rtol = .* finite number above zero"):
            simulate_model(m, None, ds, method="diffrax", rtol=bad)
    with pytest.raises(ValueError, match="substeps = 0 must be a whole number"):
        simulate_model(m, None, ds, method="diffrax", adaptive=False, substeps=0)
    with pytest.raises(FloatingPointError, match="max_steps=2 steps .* raise max_steps"):
        simulate_model(m, None, ds, method="diffrax", max_steps=2)
    for method in ("exact", "diffrax"):
        with pytest.raises(ModelError, match="x0 has shape \\(2,\\) but model Zon has 1 state"):
            simulate_model(m, None, ds, method=method, x0=[20.0, 21.0])
    with pytest.raises(ModelError, match="x0 = \\[nan\\] is not finite"):
        simulate_model(m, None, ds, x0=[float("nan")])


def test_simulate_arrays_checks_shapes_and_times(inputs):
    from jaxbox.models import ModelError

    t, u = inputs
    m = get_model("Zon")
    th, U = m.defaults(), _u(m, u)
    with pytest.raises(ModelError, match="u has shape \\(199, 3\\) but model Zon needs"):
        simulate_arrays(m, th, t, U[:-1])
    with pytest.raises(ModelError, match="u has shape \\(200, 2\\)"):
        simulate_arrays(m, th, t, U[:, :2])
    with pytest.raises(ModelError, match="finite and increasing"):
        simulate_arrays(m, th, np.zeros_like(t), U)  # a time step of zero
    with pytest.raises(ModelError, match="finite and increasing"):
        simulate_arrays(m, th, t[::-1], U, method="diffrax")
    irregular = t.copy()
    irregular[1] = 10.0
    with pytest.raises(ModelError, match="needs a regular time step"):
        simulate_arrays(m, th, irregular, U)
    with pytest.raises(ModelError, match="input 'T_amb' of model Zon is nan at sample 4"):
        simulate_arrays(m, th, t, np.where(np.arange(len(t))[:, None] == 4, np.nan, U))
    with pytest.raises(ModelError, match="at least two samples"):
        simulate_arrays(m, th, t[:1], U[:1])
    # traced times and inputs: the shapes are checked, the values left to the computation
    y = jax.jit(lambda t, U: simulate_arrays(m, th, t, U)[0])(t, U)
    np.testing.assert_allclose(y, simulate_arrays(m, th, t, U)[0], rtol=1e-12)


@pytest.mark.parametrize("name", ["Zon", "ZonWalIntInfWinBouC"])
def test_numpy_post_simulation_equals_the_jax_exact_route(inputs, name):
    """The compilation-free NumPy route of the post-simulation (``method="exact"`` of
    ``validate``) equals :func:`simulate_arrays` (JAX, exact) for several runs at once."""
    from jaxbox.validate._postsim import exact_runs_numpy

    t, u = inputs
    m = get_model(name)
    u = dict(u, T_bou=8 + 0.5 * u["T_amb"], I_e=0.5 * u["I_glo_hor"], I_w=0.3 * u["I_glo_hor"])
    th = m.defaults() | {"T_zon0": 24.0}
    U = _u(m, u)
    A, B, C, D = m.state_space_numpy(th)
    x0 = np.stack([np.asarray(m.initial_state(th)), np.asarray(m.initial_state(th)) + 1.5])
    runs = np.stack([U, U[::-1]])
    y, x = exact_runs_numpy(A, B, C, D, DT, runs, x0)
    for k in range(2):
        yj, xj = simulate_arrays(m, th, t, runs[k], method="exact", x0=x0[k])
        np.testing.assert_allclose(x[k], np.asarray(xj), rtol=0, atol=1e-9)
        np.testing.assert_allclose(y[k], np.asarray(yj), rtol=0, atol=1e-9)


@pytest.mark.slow
def test_diffrax_post_simulation_shares_one_program_and_keeps_its_tolerance(inputs):
    """The diffrax route of the post-simulation integrates the state-space matrices padded to
    the next multiple of 4 states and inputs: models of different structures share one
    compiled program, the padded states stay zero, and the step control keeps the tolerance of
    the unpadded system (its norm runs over the real states only), held against the exact
    first-order-hold route."""
    from jaxbox import _compiled
    from jaxbox.simulate import RMSOver, integrate_diffrax
    from jaxbox.validate._postsim import _simulate, exact_runs_numpy

    t, u = inputs
    u = dict(u, T_bou=8 + 0.5 * u["T_amb"], I_e=0.5 * u["I_glo_hor"], I_w=0.3 * u["I_glo_hor"])
    opts = (("atol", 1e-8), ("rtol", 1e-8))
    compiles = []
    for name in ("Zon", "ZonWal", "ZonWalIntInf"):  # 1, 2 and 3 states, 3 or 4 inputs
        m = get_model(name)
        th = m.defaults() | {"T_zon0": 24.0}
        U = _u(m, u)[None]
        x0 = np.asarray(m.initial_state(th))[None]
        y, x = _simulate(m, th, t, U, x0, "diffrax", opts)
        compiles.append(_compiled.info()["compiles"])
        A, B, C, D = m.state_space_numpy(th)
        ye, xe = exact_runs_numpy(A, B, C, D, DT, U, x0)
        assert x.shape == xe.shape and y.shape == ye.shape
        np.testing.assert_allclose(x, xe, rtol=0, atol=2e-5)
        np.testing.assert_allclose(y, ye, rtol=0, atol=2e-5)
    # the first may compile (or find the program another test compiled); the others reuse it
    assert compiles[1] == compiles[0] == compiles[2], compiles

    # padded with zero states and inputs: those states stay zero, and the error of the real
    # ones is that of the unpadded system (2.8e-4 K at this tolerance), not the looser one of an
    # RMS over every state (RMSOver(32) is that RMS: one compiled solve for both)
    m = get_model("ZonWal")
    th = m.defaults() | {"T_zon0": 24.0}
    A, B, C, D = m.state_space_numpy(th)
    U = _u(m, u)
    x0 = np.asarray(m.initial_state(th))
    _, xe = exact_runs_numpy(A, B, C, D, DT, U[None], x0[None])
    Ap, Bp, Up, x0p = np.zeros((32, 32)), np.zeros((32, 4)), np.zeros((len(t), 4)), np.zeros(32)
    Ap[:2, :2], Bp[:2, :3], Up[:, :3], x0p[:2] = A, B, U, x0
    run = jax.jit(
        lambda count: integrate_diffrax(
            Ap, Bp, x0p, t, Up, rtol=1e-6, atol=1e-6, norm=RMSOver(count)
        )
    )
    err = {}
    for count in (2.0, 32.0):
        xs = np.asarray(run(np.float64(count)))
        assert np.all(xs[:, 2:] == 0.0)
        err[count] = np.abs(xs[:, :2] - xe[0]).max()
    # an RMS over 32 states, 30 of them zero, is a quarter of the RMS over the 2 real ones
    assert err[2.0] < 3.5e-4 and err[32.0] > 3 * err[2.0], err


def test_diffrax_post_simulation_of_neighbouring_lengths_shares_one_program(inputs):
    """Records of neighbouring lengths run in one compiled diffrax program: the record is
    extended to its run length (the times at the last step, the inputs held) and the extra
    samples dropped; the states at the real samples are those of the program compiled for the
    record's own length, to rounding, and those of the exact route to the tolerance."""
    import functools

    from jaxbox import _compiled
    from jaxbox.simulate import diffrax_runs_numpy
    from jaxbox.simulate._diffrax import _runs, run_length
    from jaxbox.validate._postsim import exact_runs_numpy

    lengths = (1, 24, 33, 150, 200, 256, 257, 1024)
    assert [run_length(n) for n in lengths] == [32, 32, 64, 256, 256, 256, 512, 1024]
    # above 1024 samples an eighth of an octave: at most 12.5 % more
    for n in (1025, 1500, 5000, 52560):
        assert n <= run_length(n) <= 1.125 * n and run_length(run_length(n)) == run_length(n)
    t, u = inputs
    m = get_model("ZonWal")
    th = m.defaults() | {"T_zon0": 24.0}
    A, B, C, D = m.state_space_numpy(th)
    U = _u(m, u)[None]
    x0 = np.asarray(m.initial_state(th))[None]
    compiles = []
    for n in (130, 200, 161):  # all in the bucket of 256 samples
        xs = diffrax_runs_numpy(A, B, t[:n], U[:, :n], x0)
        compiles.append(_compiled.info()["compiles"])
        assert xs.shape == (1, n, 2)
        _, xe = exact_runs_numpy(A, B, C, D, DT, U[:, :n], x0)
        np.testing.assert_allclose(xs, xe, rtol=0, atol=2e-3)
    # the first may compile (or find the program another test compiled); the others reuse it
    assert compiles[0] == compiles[1] == compiles[2], compiles
    # the last against the program of its own length, unpadded in time
    Ap, Bp, Up, X0 = np.zeros((4, 4)), np.zeros((4, 4)), np.zeros((1, n, 4)), np.zeros((1, 4))
    Ap[:2, :2], Bp[:2, :3], Up[..., :3], X0[:, :2] = A, B, U[:, :n], x0
    own = jax.jit(functools.partial(_runs, atol=1e-6, rtol=1e-6))
    alone = np.asarray(own(Ap, Bp, t[:n], Up, X0, np.float64(2)))[..., :2]
    np.testing.assert_allclose(xs, alone, rtol=0, atol=1e-12)
