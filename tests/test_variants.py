"""Model variants of different sizes fitted in one compiled call, and the array form of a network
that makes it possible (one program for every structure of the same padded size)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _reference import synthetic_building

import jaxbox
from jaxbox import _compiled
from jaxbox.fit import fit_batch
from jaxbox.fit._transforms import make_transform, to_physical_coded
from jaxbox.models import (
    Grammar,
    RCNetwork,
    get_model,
    library_models,
    parse_structure,
    random_structure,
)
from jaxbox.models import components as c

jaxbox.enable_x64()

TRUTH = {"C_zon": 2e6, "C_wal": 3e7, "C_int": 2e7, "R_wal": 0.01, "R_int": 0.002, "gA": 2.0}
TRUTH.update(T_zon0=19.0, T_wal0=16.0, T_int0=18.0)
VARIANTS = ["Zon", "Zon+Wal", "Zon+Wal+Int", "Zon+Hea"]


@pytest.fixture(scope="module")
def data():
    return synthetic_building(get_model("Zon+Wal+Int"), TRUTH, n=150, seed=5, noise=0.03)


@pytest.fixture(scope="module")
def together_and_alone(data):
    g = Grammar.from_columns(data.columns)
    models = [parse_structure(n).build(g) for n in VARIANTS]
    before = _compiled.info("fit")["entries"]
    together = fit_batch([dict(model=m, data=data, starts=4, seed=2) for m in models])
    compiled = _compiled.info("fit")["entries"] - before
    alone = [fit_batch([dict(model=m, data=data, starts=4, seed=2)])[0] for m in models]
    return together, alone, compiled


@pytest.mark.slow
def test_variants_of_different_sizes_share_one_compiled_solve(together_and_alone):
    together, _, compiled = together_and_alone
    assert compiled == 1  # four structures, 1 to 3 states, 4 to 9 parameters: one program
    assert {r.timing["batch"] for r in together} == {len(VARIANTS)}
    assert [len(r.problem.model.states) for r in together] == [1, 2, 3, 2]


def test_a_batch_of_variants_gives_each_fit_alone(together_and_alone):
    together, alone, _ = together_and_alone
    for a, b in zip(together, alone, strict=True):
        assert a.problem.free == b.problem.free
        assert a.starts.status == b.starts.status
        done = a.starts.converged  # (a start stopped by the step cap, in a flat valley, may
        assert done.sum() >= 1  # drift by rounding: its cost is compared loosely)
        # a converged start stops when a step gains less than 1e-6 of the cost: in a flat valley
        # two paths a rounding apart stop a few 1e-6 apart (Zon+Hea's local minimum at 0.155 K²)
        np.testing.assert_allclose(a.starts.cost[done], b.starts.cost[done], rtol=1e-5)
        np.testing.assert_allclose(a.starts.cost, b.starts.cost, rtol=1e-3)
        # the same path: a stage of a route may end a step or two apart by rounding (the padded
        # program sums in another order), out of some hundred steps over the stages
        np.testing.assert_allclose(a.starts.steps[done], b.starts.steps[done], rtol=0.02, atol=2)
        np.testing.assert_allclose(a.cost, b.cost, rtol=1e-5)
    # the true structure fits to the noise
    assert together[2].cost < 1.2 * 0.03**2


def _with_constant_ground(name):
    """A zone with a constant, estimated ground temperature (a constant node: no array form)."""
    net = c.zone(RCNetwork(name, "zone and a constant ground"))
    return c.window(c.heating(c.ground(net, to=None))).build()


@pytest.fixture(scope="module")
def bucketed(data):
    """The variants in three bucketed calls: two structures of 1 and 2 states, then one of 2
    states (``Zon+Hea``), then one of 3 (``Zon+Wal+Int``: the next bucket of states). Returns
    the fits in the order of ``VARIANTS`` and the programs compiled after each call."""
    g = Grammar.from_columns(data.columns)
    models = [parse_structure(n).build(g) for n in VARIANTS]
    widest = len({u for m in models for u in m.inputs})
    before = _compiled.info("fit")["entries"]
    out, compiled = {}, []
    for part in ((0, 1), (3,), (2,)):
        reqs = [dict(model=models[i], data=data, starts=4, seed=2) for i in part]
        out.update(zip(part, fit_batch(reqs, bucket={"inputs": widest}), strict=True))
        compiled.append(_compiled.info("fit")["entries"] - before)
    return [out[i] for i in range(len(VARIANTS))], compiled


def test_bucketed_calls_of_neighbouring_sizes_share_one_program(bucketed, together_and_alone):
    """A structure search's steps: calls with other structures, sizes and numbers of starts
    run one compiled program per bucket, and each fit is the one of the plain call."""
    out, compiled = bucketed
    assert compiled == [1, 1, 2]
    together, _, _ = together_and_alone
    for a, b in zip(out, together, strict=True):
        assert a.problem.free == b.problem.free
        done = a.starts.converged & b.starts.converged
        assert done.sum() >= 1
        np.testing.assert_allclose(a.starts.cost[done], b.starts.cost[done], rtol=1e-5)
        np.testing.assert_allclose(a.cost, b.cost, rtol=1e-5)
        np.testing.assert_allclose(a.starts.steps[done], b.starts.steps[done], rtol=0.02, atol=2)


def test_a_bucketed_batch_pads_to_the_sizes_asked_and_a_later_one_reuses_its_program(
    data, together_and_alone
):
    """``bucket={"free": …, "states": …}``: a batch padded to at least those sizes (a
    structure search's earlier, larger batch) reports the sizes it ran at, and a call of a
    larger structure within them runs the same compiled program; the fits are the plain
    call's, to rounding. A size that is no size of a batch, or not a whole number, is refused
    by name."""
    g = Grammar.from_columns(data.columns)
    models = [parse_structure(n).build(g) for n in VARIANTS]
    widest = len({u for m in models for u in m.inputs})
    small = fit_batch([dict(model=models[0], data=data, starts=4, seed=2)], bucket=True)[0]
    assert small.timing["sizes"]["free"] == 8 and small.timing["sizes"]["states"] == 2
    before = _compiled.info("fit")["entries"]
    wide = fit_batch(
        [dict(model=models[0], data=data, starts=4, seed=2)],
        bucket={"inputs": widest, "free": 12, "states": 3},
    )[0]
    sizes = wide.timing["sizes"]
    assert sizes["free"] == 16 and sizes["states"] == 4 and sizes["inputs"] >= widest
    assert set(sizes) == set(jaxbox.fit._fit.SIZES)
    after = _compiled.info("fit")["entries"]
    big = fit_batch([dict(model=models[2], data=data, starts=4, seed=2)], bucket=sizes)[0]
    assert _compiled.info("fit")["entries"] == after  # Zon+Wal+Int within the sizes: no compile
    assert after - before <= 1
    assert big.timing["sizes"] == sizes
    together, _, _ = together_and_alone
    for a, b in ((wide, together[0]), (big, together[2])):
        done = a.starts.converged & b.starts.converged
        assert done.sum() >= 1
        np.testing.assert_allclose(a.starts.cost[done], b.starts.cost[done], rtol=1e-5)
        np.testing.assert_allclose(a.cost, b.cost, rtol=1e-5)
    assert fit_batch([dict(model=models[0], data=data, starts=2)])[0].timing.get("sizes") is None
    req = [dict(model=models[0], data=data, starts=2)]
    with pytest.raises(jaxbox.FitError, match="'nodes'.*free, fixed, states"):
        fit_batch(req, bucket={"nodes": 4})
    for bad in (-1, 2.5, True):
        with pytest.raises(jaxbox.FitError, match="bucket size 'free'"):
            fit_batch(req, bucket={"free": bad})


def test_a_sequence_of_sizes_pads_to_the_first_that_holds_the_batch_and_compiled_ahead(data):
    """``bucket=[sizes, larger]``: a batch within ``sizes`` pads to them, one that outgrows
    them to ``larger``, one that outgrows both to its own sizes (at least the last's).
    :func:`~jaxbox.fit.compile_batch` builds a batch's program without solving, and the batch
    that then needs it compiles nothing."""
    from jaxbox.fit import compile_batch

    g = Grammar.from_columns(data.columns)
    small, mid = (parse_structure(n).build(g) for n in ("Zon", "Zon+Wal+Int"))
    widest = len({u for m in (small, mid) for u in m.inputs})
    sizes = [
        {"inputs": widest, "free": 8, "states": 2},
        {"inputs": widest, "free": 16, "states": 6},
    ]
    ahead = compile_batch([dict(model=mid, data=data, starts=1)], bucket=sizes[1])
    assert len(ahead) == 1 and ahead[0]["sizes"]["free"] == 16 and ahead[0]["sizes"]["states"] == 6
    again = compile_batch([dict(model=small, data=data, starts=3)], bucket=sizes[1])
    assert not again[0]["built"] and again[0]["compile_s"] == 0.0  # the same program
    before = _compiled.info("fit")["entries"]
    fits = {
        name: fit_batch([dict(model=m, data=data, starts=4, seed=2)], bucket=sizes)[0]
        for name, m in (("small", small), ("mid", mid))
    }
    assert (
        fits["small"].timing["sizes"]["free"] == 8 and fits["small"].timing["sizes"]["states"] == 2
    )
    assert fits["mid"].timing["sizes"] == ahead[0]["sizes"]  # Zon+Wal+Int: 3 states, 9 free
    assert fits["mid"].timing["compile_s"] == 0.0
    assert _compiled.info("fit")["entries"] - before <= 1  # at most Zon's (8, 2), if new
    beyond = fit_batch(
        [dict(model=mid, data=data, starts=2)], bucket=[{"free": 4, "states": 1}, {"free": 8}]
    )[0]
    assert beyond.timing["sizes"]["free"] == 16 and beyond.timing["sizes"]["states"] == 4
    for bad in ([], [{"free": 8}, 3], "free"):
        with pytest.raises(jaxbox.FitError, match="bucket must be"):
            fit_batch([dict(model=small, data=data, starts=2)], bucket=bad)


def test_parts_side_by_side_solve_each_start_as_alone(data, monkeypatch):
    """A bucketed batch dealt to three parts run by threads (and its padding starts, never
    solved) gives each start the result of one part alone."""
    from jaxbox.fit._fit import parallel_parts

    g = Grammar.from_columns(data.columns)
    reqs = [
        dict(model=parse_structure(n).build(g), data=data, starts=8, seed=3) for n in VARIANTS[1:]
    ]
    runs = {}
    for threads in ("1", "3"):
        monkeypatch.setenv("JAXBOX_THREADS", threads)
        runs[threads] = fit_batch(reqs, bucket=True)
    assert parallel_parts(24) == 3
    monkeypatch.setenv("JAXBOX_THREADS", "one")
    with pytest.raises(jaxbox.FitError, match="JAXBOX_THREADS"):
        parallel_parts(24)
    for a, b in zip(runs["1"], runs["3"], strict=True):
        np.testing.assert_allclose(a.starts.cost, b.starts.cost, rtol=1e-9)
        np.testing.assert_array_equal(a.starts.steps, b.starts.steps)
        assert a.starts.status == b.starts.status


def test_transform_in_numpy_equals_jax():
    tr = make_transform(
        ["R", "T", "lo", "free"],
        np.asarray([1e-5, -3.0, 0.5, -np.inf]),
        np.asarray([10.0, 37.0, np.inf, np.inf]),
        guess=np.asarray([0.01, 20.0, 2.0, 0.3]),
    )
    z = np.random.default_rng(1).normal(scale=3.0, size=(5, 4))
    got = tr.to_physical(z)
    assert isinstance(got, np.ndarray)
    np.testing.assert_allclose(got, np.asarray(tr.to_physical(jnp.asarray(z))), rtol=1e-14)


def test_the_cores_of_a_container_quota(tmp_path):
    """Parts per core: no more than a container's CPU quota (cgroup v2 cpu.max) allows."""
    import os

    from jaxbox.fit._fit import _usable_cores

    own = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cpu_max = tmp_path / "cpu.max"
    cpu_max.write_text("max 100000\n")
    assert _usable_cores(str(cpu_max)) == own
    cpu_max.write_text("150000 100000\n")  # one and a half cores: one part
    assert _usable_cores(str(cpu_max)) == 1
    cpu_max.write_text(f"{100000 * (own + 4)} 100000\n")  # a quota above the affinity set
    assert _usable_cores(str(cpu_max)) == own
    assert _usable_cores(str(tmp_path / "missing")) == own


def test_the_starts_of_one_model_in_parts_side_by_side(data, monkeypatch):
    """The starts of one fit dealt to parts run by threads (13 starts: parts of 5, 4 and 4,
    the short ones padded with starts never solved) give each start what it gets in one part."""
    import jax

    from jaxbox.fit import fit_model

    if jax.default_backend() != "cpu":
        pytest.skip("parts run side by side on a CPU only")
    runs = {}
    for threads in (1, 3):  # more parts than parallel_parts gives 13 starts (8 each at least)
        monkeypatch.setattr("jaxbox.fit._fit.parallel_parts", lambda n, t=threads: t)
        runs[threads] = fit_model(VARIANTS[1], data, starts=13, seed=5)
    a, b = runs[1], runs[3]
    assert len(b.starts.cost) == 13 and np.all(np.isfinite(b.starts.cost))
    np.testing.assert_allclose(a.starts.cost, b.starts.cost, rtol=1e-9)
    np.testing.assert_array_equal(a.starts.steps, b.starts.steps)
    np.testing.assert_allclose(a.cost, b.cost, rtol=1e-12)


def test_compiler_options_on_a_cpu(monkeypatch):
    import jax

    opts = _compiled.compiler_options()
    if jax.default_backend() == "cpu" and _compiled._supported():
        assert opts == {"xla_cpu_use_fusion_emitters": False}
    else:
        assert opts is None
    monkeypatch.setenv("JAXBOX_XLA_DEFAULTS", "1")
    assert _compiled.compiler_options() is None


def test_a_compiler_that_does_not_know_the_options(monkeypatch):
    """A jaxlib whose CPU compiler retired the option (jaxlib 0.11) compiles with XLA's own
    settings instead of failing every fit."""
    import jax

    monkeypatch.setattr(_compiled, "_SUPPORTED", [])
    monkeypatch.setattr(_compiled, "_CPU_OPTIONS", {"xla_no_such_option_anywhere": True})
    assert _compiled.compiler_options() is None
    f = _compiled.jit(lambda x: 2.0 * x)
    assert float(f(jax.numpy.asarray(1.5))) == 3.0


def test_a_constant_node_in_a_batch_of_variants(data):
    """A network with a constant node has no array form: the batch pads each variant's own
    matrices instead, with the same results."""
    g = Grammar.from_columns(data.columns)
    models = [_with_constant_ground("ZonGro"), parse_structure("Zon+Wal").build(g)]
    assert models[0].network._constant_nodes()
    # the starts of the fits alone above: Zon+Wal alone reuses their compiled solve
    together = fit_batch([dict(model=m, data=data, starts=4, seed=2) for m in models])
    for m, a in zip(models, together, strict=True):
        b = fit_batch([dict(model=m, data=data, starts=4, seed=2)])[0]
        np.testing.assert_allclose(a.starts.cost, b.starts.cost, rtol=1e-7)


def test_the_array_form_gives_the_state_space_of_every_model():
    g = Grammar.from_columns(
        ["T_zon", "T_amb", "T_bou", "T_cel", "Q_hea", "I_glo_hor", "I_s", "I_e", "I_w", "P_ele"]
    )
    rng = np.random.default_rng(4)
    models = [m for m in library_models() if not m.network._constant_nodes()]
    models += [random_structure(g, rng).build(g) for _ in range(40)]
    g2 = Grammar.from_columns(["T_zon1", "T_zon2", "T_amb", "Q_hea1", "Q_hea2", "I_glo_hor"])
    models += [random_structure(g2, rng).build(g2) for _ in range(20)]
    thetas = [{p.name: float(rng.uniform(0.05, 2.0)) for p in m.parameters} for m in models]
    # the JAX assembly of every model in one compiled program (op by op, each model's shapes
    # dispatch their own small programs)
    wants = jax.jit(lambda ths: [m.state_space(th) for m, th in zip(models, ths, strict=True)])(
        thetas
    )
    for m, theta, want in zip(models, thetas, wants, strict=True):
        got = m.state_space_numpy(theta)
        for x, y in zip(got, want, strict=True):
            np.testing.assert_allclose(x, np.asarray(y), rtol=1e-13, atol=1e-300, err_msg=m.name)


def test_padding_states_decay_apart_from_the_network():
    """A padding state has no input, starts at 0 and decays faster than every mode of the
    network, each at its own rate: the spectrum stays simple."""
    from jaxbox.models._network import rc_from_arrays

    m = get_model("Zon+Wal+Int")
    names = [p.name for p in m.parameters]
    arrays = m.rc_arrays(
        names + ["1", "0"], states=5, inputs=m.inputs + ("T_x",), edges=4, sources=3, factors=2
    )
    theta = {**TRUTH, "R_wal": 0.01}
    v = np.asarray([theta[n] for n in names] + [1.0, 0.0])
    A, B, caps, x0 = rc_from_arrays(v, arrays, xp=np)
    A0, B0, _, _ = m.state_space_numpy(theta)
    np.testing.assert_allclose(A[:3, :3], A0, rtol=1e-14)
    np.testing.assert_allclose(B[:3, : len(m.inputs)], B0, rtol=1e-14)
    assert np.all(A[3:, :3] == 0) and np.all(A[:3, 3:] == 0) and np.all(B[3:] == 0)
    assert np.all(x0[3:] == 0)
    real = np.linalg.eigvals(A0).real
    pad = np.diag(A)[3:]
    assert np.all(pad < 2.5 * real.min()) and len(set(pad)) == 2


def test_coded_transform_equals_the_static_one():
    names = ["R", "T", "lo", "free"]
    lower = np.asarray([1e-5, -3.0, 0.5, -np.inf])
    upper = np.asarray([10.0, 37.0, np.inf, np.inf])
    tr = make_transform(names, lower, upper, guess=np.asarray([0.01, 20.0, 2.0, 0.3]))
    z = np.random.default_rng(0).normal(size=(7, 4))
    want = np.asarray(tr.to_physical(jnp.asarray(z)))
    got = to_physical_coded(
        jnp.asarray(z), tr.lower, tr.upper, tr.scale, jnp.asarray(tr.kinds), tr.style
    )
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-14)
