"""Estimation: parameter recovery, batched multistart, failing starts, problem checks."""

import subprocess
import sys

import numpy as np
import pytest
from _reference import synthetic_building

from jaxbox.data import Dataset
from jaxbox.fit import FitError, compile_cache_info, fit_model, make_problem
from jaxbox.models import get_model

TRUTH = {
    "C_zon": 3.0e6,
    "C_wal": 4.0e7,
    "R_wal": 0.012,
    "gA": 2.5,
    "T_zon0": 26.0,
    "T_wal0": 19.0,
}


@pytest.fixture(scope="module")
def zonwal_data():
    return synthetic_building(get_model("ZonWal"), TRUTH)


@pytest.fixture(scope="module")
def zonwal_fit(zonwal_data):
    return fit_model("ZonWal", zonwal_data, starts=8, seed=3)


def test_recovers_known_parameters_from_default_guess(zonwal_fit):
    r = zonwal_fit
    guess = r.problem.guess_dict
    # the default guess is far from the truth
    assert abs(guess["C_wal"] / TRUTH["C_wal"] - 1) > 0.4
    assert r.converged
    for name, true in TRUTH.items():
        assert r.params[name] == pytest.approx(true, rel=1e-5), name
    assert r.cost < 1e-12
    assert not any(r.at_bound().values())


def test_multistart_compiles_once_and_reports_a_failing_start(zonwal_data, zonwal_fit):
    r0 = zonwal_fit
    before = compile_cache_info()
    starts = np.array(r0.starts.initial)
    starts[1] = np.nan  # a start that cannot be evaluated
    r = fit_model("ZonWal", zonwal_data, starts=starts)
    after = compile_cache_info()
    assert after["compiles"] == before["compiles"], "same shapes must reuse the compiled solve"
    assert r.timing["compile_s"] == 0.0
    assert r.starts.status[1] == "nonfinite"
    assert r.best != 1
    assert np.isfinite(r.cost)
    # another dataset of the same shape: no recompilation either
    other = synthetic_building(get_model("ZonWal"), TRUTH | {"R_wal": 0.02}, seed=5)
    r2 = fit_model("ZonWal", other, starts=starts)
    assert compile_cache_info()["compiles"] == before["compiles"]
    assert r2.params["R_wal"] == pytest.approx(0.02, rel=1e-5)


def test_all_starts_failing_is_an_error(zonwal_data):
    # four starts: the shape of the one-state fit below (one compiled solve for both)
    with pytest.raises(FitError, match="all 4 starts failed"):
        fit_model("Zon", zonwal_data, starts=np.full((4, 4), np.nan))


def test_fixed_parameters_and_bounds(zonwal_data):
    r = fit_model(
        "ZonWal", zonwal_data, starts=1, fixed={"gA": 2.5}, bounds={"R_wal": (0.001, 0.1)}
    )
    assert "gA" not in r.free and r.params["gA"] == 2.5
    assert r.bounds["R_wal"] == (0.001, 0.1)
    assert r.params["R_wal"] == pytest.approx(TRUTH["R_wal"], rel=1e-5)
    # a bound that excludes the truth: the estimate ends on it and is flagged
    r = fit_model("ZonWal", zonwal_data, bounds={"R_wal": (0.001, 0.008)}, starts=1)
    assert r.at_bound()["R_wal"]


def test_noisy_fit_is_close(zonwal_data):
    noisy = synthetic_building(
        get_model("Zon"),
        {"C_zon": 8e6, "R_wal": 0.01, "gA": 3.0, "T_zon0": 25.0},
        noise=0.05,
        seed=2,
    )
    r = fit_model("Zon", noisy, starts=4)
    assert r.params["R_wal"] == pytest.approx(0.01, rel=0.02)
    assert r.params["C_zon"] == pytest.approx(8e6, rel=0.05)
    assert np.sqrt(r.cost) == pytest.approx(0.05, rel=0.2)


@pytest.mark.slow
def test_diffrax_simulator_fits_too(zonwal_data):
    r = fit_model("Zon", zonwal_data, simulator="diffrax", starts=1, max_steps=60)
    r_ex = fit_model("Zon", zonwal_data, starts=1, max_steps=60)
    assert r.problem.simulator == "diffrax"
    # both fit the same (misspecified) problem; the fixed-step error is small against the misfit
    assert r.params["R_wal"] == pytest.approx(r_ex.params["R_wal"], rel=0.05)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"fixed": {"R_nope": 1.0}}, "no parameter"),
        ({"bounds": {"R_wal": (0.1, 0.01)}}, "must be below"),
        ({"guess": {"R_wal": 50.0}}, "outside its bounds"),
        ({"free": ["R_wal"], "fixed": {"R_wal": 0.01}}, "both free and fixed"),
        ({"weights": [1.0, 2.0]}, "2 weights for 1 outputs"),
        ({"simulator": "euler"}, "unknown simulator"),
        ({"starts": 0}, "at least 1"),
        ({"starts": np.ones((2, 3))}, "one column per free parameter"),
    ],
)
def test_problem_errors(zonwal_data, kwargs, match):
    with pytest.raises(FitError, match=match):
        fit_model("Zon", zonwal_data, **kwargs)


def test_missing_column_is_named(zonwal_data):
    from jaxbox.data import DataError

    data = Dataset.from_arrays(zonwal_data.t, {"T_amb": zonwal_data["T_amb"]})
    with pytest.raises(DataError, match="Q_hea"):
        fit_model("Zon", data)


def test_float32_is_refused_with_a_clear_message():
    code = (
        "import jaxbox, numpy as np\n"
        "d = jaxbox.Dataset.from_arrays(np.arange(10)*3600., {k: np.ones(10) for k in "
        "['T_amb','Q_hea','I_glo_hor','T_zon']})\n"
        "jaxbox.fit_model('Zon', d)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={"JAX_PLATFORMS": "cpu", "PATH": ""},
    )
    assert proc.returncode != 0
    assert "enable_x64" in proc.stderr


def test_subpackages_are_not_shadowed_by_verbs():
    import importlib
    import types

    import jaxbox

    for name in ("fit", "simulate", "validate", "select", "models", "data", "report"):
        module = importlib.import_module(f"jaxbox.{name}")
        assert isinstance(getattr(jaxbox, name), types.ModuleType), name
        assert getattr(jaxbox, name) is module
    assert callable(jaxbox.fit_model) and callable(jaxbox.simulate_model)
    assert jaxbox.fit.fit_model is jaxbox.fit_model


def test_guess_on_its_bound_up_to_rounding_is_clipped(zonwal_data):
    """An estimate on its bound handed back as a guess (a parent's optimum, a retry's start)
    comes out of the transform a rounding off the bound; it is clipped onto it, while a guess
    truly outside is refused by name."""
    lo, hi = get_model("ZonWal").parameter("R_wal").lower, 0.1
    for g, want in ((lo * (1 - 4e-16), lo), (hi * (1 + 4e-16), hi), (lo, lo)):
        p = make_problem("ZonWal", zonwal_data, bounds={"R_wal": (lo, hi)}, guess={"R_wal": g})
        assert p.guess_dict["R_wal"] == want
    with pytest.raises(FitError, match=r"guess of R_wal = .* outside its bounds.*widen"):
        make_problem("ZonWal", zonwal_data, bounds={"R_wal": (lo, hi)}, guess={"R_wal": lo * 0.9})
    with pytest.raises(FitError, match="guess of R_wal.*outside its bounds"):
        make_problem("ZonWal", zonwal_data, bounds={"R_wal": (lo, hi)}, guess={"R_wal": hi * 1.01})


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"bounds": {"R_wal": (-1.0, 1.0)}}, "R_wal.*> 0"),
        ({"bounds": {"C_wal": (0.0, 1e9)}}, "C_wal.*> 0"),
        ({"fixed": {"R_wal": -0.01}}, "R_wal.*> 0"),
        ({"fixed": {"C_zon": 0.0}}, "C_zon.*> 0"),
    ],
)
def test_resistances_and_capacities_must_be_positive(zonwal_data, kwargs, match):
    with pytest.raises(FitError, match=match):
        make_problem(get_model("ZonWal"), zonwal_data, **kwargs)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"fixed": {"R_wal": "abc"}}, FitError, "fixed value of R_wal must be a number"),
        ({"fixed": {"R_wal": None}}, FitError, "fixed value of R_wal must be a number"),
        ({"fixed": {"R_wal": True}}, FitError, "fixed value of R_wal must be a number"),
        ({"fixed": {"R_wal": np.ones(2)}}, FitError, "fixed value of R_wal must be a number"),
        ({"guess": {"C_zon": [1e6, 2e6]}}, FitError, "guess of C_zon must be a number"),
        ({"bounds": {"R_wal": (1e-3, 1.0, 3.0)}}, FitError, "R_wal must be a pair.*3 values"),
        ({"bounds": {"R_wal": (1e-3, "high")}}, FitError, "upper bound of R_wal must be"),
        ({"free": 5}, FitError, "free must be a parameter name"),
        ({"free": ["R_wal", 5]}, FitError, "free must hold parameter names"),
        ({"fixed": "R_wal"}, TypeError, "fixed must be a mapping"),
        ({"bounds": [1e-3, 1.0]}, TypeError, "bounds must be a mapping"),
        ({"weights": {"T_zon": "high"}}, FitError, "weight of T_zon must be a number"),
        ({"weights": 2.0}, FitError, "weights must map outputs to numbers"),
    ],
)
def test_parameter_settings_are_checked_and_named(zonwal_data, kwargs, error, match):
    with pytest.raises(error, match=match):
        make_problem("ZonWal", zonwal_data, **kwargs)


def test_one_free_name_a_model_name_and_the_start_sampling_settings(zonwal_data):
    p = make_problem("ZonWal", zonwal_data, free="C_zon")  # one name, not its letters
    assert p.free == ("C_zon",) and p.model.name == "ZonWal"
    with pytest.raises(TypeError, match="model must be an RCModel"):
        make_problem(3, zonwal_data)
    for kwargs, match in [
        ({"seed": -1}, "seed must be an integer"),
        ({"seed": "x"}, "seed must be an integer"),
        ({"seed": 1.5}, "seed must be an integer"),
        ({"concentration": -1.0}, "concentration must be a finite number"),
        ({"concentration": float("nan")}, "concentration must be a finite number"),
        ({"max_steps": 0}, "max_steps must be an integer ≥ 1"),
        ({"max_steps": 2.5}, "max_steps must be an integer ≥ 1"),
        ({"rtol": "a"}, "rtol must be a number"),
        ({"atol": -1.0}, "atol must be a finite number ≥ 0"),
    ]:
        with pytest.raises(FitError, match=match):
            fit_model("ZonWal", zonwal_data, starts=3, **kwargs)


def test_one_set_of_defaults_in_python_the_selection_and_the_command_line():
    import inspect

    from jaxbox.cli import build_parser
    from jaxbox.fit import DEFAULT_MAX_STEPS, DEFAULT_STARTS, fit_batch, fit_many
    from jaxbox.select import GreyBox, forward_selection

    for fn in (fit_model, fit_many):
        params = inspect.signature(fn).parameters
        assert params["starts"].default == DEFAULT_STARTS
        assert params["max_steps"].default == DEFAULT_MAX_STEPS
    assert inspect.signature(forward_selection).parameters["starts"].default == DEFAULT_STARTS
    assert inspect.signature(GreyBox.add_case).parameters["starts"].default == DEFAULT_STARTS
    assert fit_batch  # requests take fit_model's defaults (tested in test_library)
    parser = build_parser()
    for command in ("fit", "select"):
        args = parser.parse_args(
            [command, "x.csv"] + (["--model", "Zon"] if command == "fit" else [])
        )
        assert args.starts == DEFAULT_STARTS, command
        assert args.max_steps in (None, DEFAULT_MAX_STEPS), command
    # the experiment design's optimiser: the command line takes jaxbox.design.plan's default
    from jaxbox.design import plan

    args = parser.parse_args(["design", "--model", "Zon", "--out", "x.csv"])
    assert args.starts is None
    assert inspect.signature(plan).parameters["starts"].default >= 1


def test_fraction_bounds_and_fixed_fractions_stay_physical():
    """A fraction fra_* given bounds or a fixed value outside [0, 1] is refused by name, as a
    model's own parameter specs are (resistances and capacities > 0 are refused already)."""
    from jaxbox.datasets import twinhouse_exp1

    ident, _ = twinhouse_exp1("N2").split()
    model = get_model("BM_TiTe")
    for kw in ({"bounds": {"fra_wal": (0.0, 1.5)}}, {"bounds": {"fra_wal": (-0.1, 0.5)}}):
        with pytest.raises(FitError, match=r"bounds of fra_wal: .*within \[0, 1\]"):
            make_problem(model, ident, **kw)
    with pytest.raises(FitError, match=r"fixed value of fra_wal is 1.2; a fraction"):
        make_problem(model, ident, fixed={"fra_wal": 1.2})
    make_problem(model, ident, fixed={"fra_wal": 1.0})
    assert make_problem(model, ident, bounds={"fra_wal": (0.0, 1.0)}).transform is not None
