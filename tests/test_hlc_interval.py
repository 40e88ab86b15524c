"""HLC intervals that carry the model's error: the HAC covariance for coloured residuals and
the spread over near-best structures.

References: simulated data of known truth with AR(1) output noise (the white delta interval
misses the true HLC often, the HAC one seldom); white noise (HAC ≈ white); a stand-in selection
of two candidates that disagree.
"""

import dataclasses
import math
import types

import numpy as np
import pytest

from jaxbox.data import Dataset
from jaxbox.fit import fit_batch, fit_many, fit_model
from jaxbox.models import get_model
from jaxbox.simulate import simulate_model
from jaxbox.validate import (
    fit_report,
    hlc_interval,
    kpis,
    near_best,
    record_conductance,
    robust_covariance,
    uncertainty,
)
from jaxbox.validate._hlc_hac import HAC, WHITE

STEP = 3600.0
N = 168
ZONWAL = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.008, "gA": 3.0, "T_zon0": 20.0, "T_wal0": 15.0}
TRUE_HLC = 1 / ZONWAL["R_wal"]


def _inputs(rng, n):
    """Hourly times [s] and inputs: weather with a daily cycle, random heating, the sun."""
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    u = {
        "T_amb": 8.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "Q_hea": 1500.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
    }
    return t, u


def _data(seed, rho, sd, n=N):
    """ZonWal's response to random heating, weather and sun, plus AR(1) noise of standard
    deviation ``sd`` [K] and lag-1 correlation ``rho``."""
    rng = np.random.default_rng(seed)
    t, u = _inputs(rng, n)
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model("ZonWal", ZONWAL, clean).y[:, 0]
    w = rng.normal(0.0, sd * np.sqrt(1 - rho**2), n)
    e = np.empty(n)
    e[0] = rng.normal(0.0, sd)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + w[i]
    return clean.with_columns(T_zon=y + e)


def _start():
    return np.asarray([[ZONWAL[n] * 1.1 for n in ZONWAL]])


@pytest.fixture(scope="module")
def coloured_fits():
    """20 replicates with AR(1) noise (ρ = 0.9, 0.3 K), fitted in one batched call."""
    datasets = [_data(seed, 0.9, 0.3) for seed in range(20)]
    return fit_many("ZonWal", datasets, starts=_start())


@pytest.fixture(scope="module")
def white_fit():
    return fit_model("ZonWal", _data(7, 0.0, 0.1), starts=_start())


def _covers(k) -> bool:
    lo, hi = k.hlc.ci95
    return lo <= TRUE_HLC <= hi


def test_hac_covers_the_true_hlc_where_the_white_interval_does_not(coloured_fits):
    white = [_covers(kpis(r, interval="white")) for r in coloured_fits]
    hac = [_covers(kpis(r, interval="hac")) for r in coloured_fits]
    assert np.mean(hac) >= 0.8, np.mean(hac)
    assert np.mean(white) <= 0.65, np.mean(white)
    assert np.mean(hac) - np.mean(white) >= 0.25


def test_hac_is_the_white_covariance_on_white_residuals(white_fit):
    unc = uncertainty(white_fit)
    rc = robust_covariance(white_fit, unc)
    assert rc.white
    assert 0.75 < rc.inflation < 1.3, rc.inflation
    w, h = kpis(white_fit, unc, interval="white"), kpis(white_fit, unc, interval="hac")
    assert h.hlc.value == w.hlc.value
    assert 0.7 < h.hlc.std / w.hlc.std < 1.35, (h.hlc.std, w.hlc.std)
    assert w.warnings == ()
    # deterministic: the same numbers again
    again = robust_covariance(white_fit, unc)
    np.testing.assert_array_equal(again.cov_free, rc.cov_free)
    assert again.bandwidth == rc.bandwidth


def test_the_blocking_finds_a_slow_error_under_fast_noise():
    """Scores of white noise over a slow AR(1) part (ρ = 0.99, long-run variance 26 times the
    white one's): the kernel at the samples' scale sees a twentieth of it, the blocking level
    about all of it; on white scores the blocking adds at most its sampling error."""
    from jaxbox.validate._hlc_hac import _blocked_sandwich, _sandwich

    n, rho, sd = 4000, 0.99, 0.05
    truth = n * (1 + sd**2 / (1 - rho) ** 2)
    ones, blocked = [], []
    for seed in range(5):
        rng = np.random.default_rng(seed)
        slow, shocks = np.zeros(n), rng.normal(0, sd, n)
        for t in range(1, n):
            slow[t] = rho * slow[t - 1] + shocks[t]
        s = (rng.normal(0, 1, n) + slow)[:, None]
        ones.append(_sandwich(s, np.eye(1), 0.97)[0][0, 0] / truth)
        cov, _, _, block = _blocked_sandwich(s, np.eye(1), 0.97)
        blocked.append(cov[0, 0] / truth)
        assert block > 1
        white = rng.normal(0, 1, (n, 3))
        se1 = np.sqrt(np.diag(_sandwich(white, np.eye(3), 0.97)[0]))
        seb = np.sqrt(np.diag(_blocked_sandwich(white, np.eye(3), 0.97)[0]))
        assert 1 - 1e-12 <= np.median(seb / se1) < 1.3  # the largest median level
    assert max(ones) < 0.1, ones
    assert 0.6 < np.median(blocked) < 2.0 and 0.4 < min(blocked) and max(blocked) < 3.5, blocked


def test_the_interval_from_10_minute_data_is_that_of_their_hourly_means(monkeypatch):
    """A slow AR(1) error (0.3 K, ρ = 0.9 an hour) under fast white noise (0.15 K): the HAC
    interval of the HLC from 10-minute samples is about that from their hourly means (the
    same information on a steady state), and holds the truth; at the samples' scale alone it
    was half as wide as the hourly one and missed the truth."""
    import jaxbox.validate._hlc_hac as hac

    step, n = 600.0, 1008
    fine = []
    for seed in range(3):
        rng = np.random.default_rng(seed)
        t = np.arange(n) * step
        day = 2 * np.pi * t / 86400.0
        on = np.random.default_rng(seed + 100).random(n // 6) > 0.5
        u = {
            "T_amb": 8.0 + 5.0 * np.sin(day - 2.0),
            "Q_hea": 1500.0 * np.repeat(on, 6),
            "I_glo_hor": np.maximum(0.0, 600.0 * np.sin(day - 1.5)),
        }
        clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
        y = simulate_model("ZonWal", ZONWAL, clean).y[:, 0]
        rho = 0.9 ** (step / STEP)
        e, w = np.empty(n), rng.normal(0.0, 0.3 * np.sqrt(1 - rho**2), n)
        e[0] = rng.normal(0.0, 0.3)
        for i in range(1, n):
            e[i] = rho * e[i - 1] + w[i]
        fine.append(clean.with_columns(T_zon=y + e + rng.normal(0.0, 0.15, n)))
    hourly = [d.resample("1h") for d in fine]
    fits = fit_many("ZonWal", fine, starts=_start()), fit_many("ZonWal", hourly, starts=_start())
    for a, b in zip(*fits, strict=True):
        ka, kb = kpis(a, interval="hac"), kpis(b, interval="hac")
        assert ka.residuals["block"] > 1
        block = ka.to_dict()["residuals"]["block"]  # samples per block: an integer in JSON
        assert isinstance(block, int) and block == ka.residuals["block"]
        assert 1 / 1.6 < ka.hlc.std / kb.hlc.std < 1.6, (ka.hlc.std, kb.hlc.std)
        assert ka.hlc.ci95[0] <= TRUE_HLC <= ka.hlc.ci95[1], ka.hlc.ci95
    monkeypatch.setattr(hac, "MIN_BLOCKS", 10**9)  # the samples' scale alone
    alone = [kpis(a, interval="hac") for a in fits[0]]
    hours = [kpis(b, interval="hac") for b in fits[1]]
    assert all(a.hlc.std < 0.8 * b.hlc.std for a, b in zip(alone, hours, strict=True))
    assert not all(a.hlc.ci95[0] <= TRUE_HLC <= a.hlc.ci95[1] for a in alone)


def test_the_method_and_a_warning_are_reported(coloured_fits):
    r = coloured_fits[0]
    w = kpis(r)
    assert w.hlc.method == WHITE and w.method == WHITE
    assert not w.residuals["white"]
    assert len(w.warnings) == 1 and "white residuals" in w.warnings[0]
    assert "interval" in w.summary() and "warning" in w.summary()
    doc = fit_report(r)["kpis"]
    assert doc["method"] == HAC and doc["hlc"]["method"] == HAC
    assert doc["residuals"]["lag1"] > 0.5
    h = kpis(r, interval="hac")
    assert doc["hlc"]["ci95"] == pytest.approx(list(h.hlc.ci95))
    assert h.hlc.ci95[1] - h.hlc.ci95[0] > 2 * (w.hlc.ci95[1] - w.hlc.ci95[0])
    with pytest.raises(ValueError, match="interval must be"):
        kpis(r, interval="bootstrap")


def test_a_record_shorter_than_the_slowest_time_constant_is_named():
    """36 h of data for a slowest time constant of 36 h: the HLC extrapolates."""
    r = fit_model("ZonWal", _data(3, 0.0, 0.05, n=30), starts=_start())
    k = kpis(r, interval="hac")
    assert max(t.value for t in k.time_constants) > 30
    assert any("longer than the identification record" in w for w in k.warnings), k.warnings


# ---- structure spread: a stand-in selection ----------------------------------------------------


@dataclasses.dataclass(eq=False)
class _Case:
    name: str
    result: object
    score: float
    is_valid: bool = True
    done: bool = True

    @property
    def model(self):
        return self.result.model


def _selection(cases, accepted="a"):
    by_name = {c.name: c for c in cases}
    tree = tuple(types.SimpleNamespace(case=c.name, criterion=c.score) for c in cases)
    return types.SimpleNamespace(
        greybox=types.SimpleNamespace(cases=by_name),
        case=by_name[accepted],
        accepted=accepted,
        order=tuple(by_name),
        tree=tree,
        criterion="cv",
    )


def test_near_best_models_widen_the_interval(coloured_fits):
    """Two near-best models that disagree (the same structure fitted to two replicates, HLCs
    apart): the interval is the union of theirs; one outside the margin, not valid, or with
    the accepted one's criterion (the same model) counts not."""
    ks = [kpis(r, interval="hac") for r in coloured_fits[:6]]
    order = np.argsort([k.hlc.value for k in ks])
    lo_i, hi_i = int(order[0]), int(order[-1])
    a = _Case("a", coloured_fits[lo_i], 0.100)
    b = _Case("b", coloured_fits[hi_i], 0.101)  # within 2 %
    far = _Case("far", coloured_fits[int(order[2])], 0.2)
    bad = _Case("bad", coloured_fits[int(order[3])], 0.1005, is_valid=False)
    alone = hlc_interval(_selection([a, far, bad]))
    assert alone.method == HAC and len(alone.models) == 1
    assert alone.ci95 == pytest.approx(ks[lo_i].hlc.ci95)
    same = _Case("same", coloured_fits[hi_i], 0.1000001)  # a's criterion: a vanished component
    sel = _selection([a, b, far, bad, same])
    assert [c.name for c in near_best(sel)] == ["a", "b"]
    both = hlc_interval(sel)
    assert "structure spread over 2 near-best models" in both.method
    assert both.value == pytest.approx(ks[lo_i].hlc.value)
    assert both.ci95[0] == pytest.approx(min(ks[lo_i].hlc.ci95[0], ks[hi_i].hlc.ci95[0]))
    assert both.ci95[1] == pytest.approx(max(ks[lo_i].hlc.ci95[1], ks[hi_i].hlc.ci95[1]))
    assert both.ci95[1] > alone.ci95[1]
    doc = both.to_dict()
    assert doc["method"] == both.method and doc["unit"] == "W/K"
    assert [m["model"] for m in doc["models"]] == ["a", "b"]
    assert "heat-loss coefficient" in both.text() and both.method in both.text()


def test_an_interval_below_zero_is_reported_from_zero_with_a_warning(coloured_fits, monkeypatch):
    """A heat-loss coefficient is not negative: where the delta interval reaches below 0 W/K
    (the data do not bound it from below), the reported one starts at 0 and says why."""
    import jaxbox.validate._kpi as kpi_module

    real = kpi_module.kpis

    def wide(*args, **kwargs):  # the accepted model's interval 3 times its value wide
        k = real(*args, **kwargs)
        v = k.hlc.value
        hlc = dataclasses.replace(k.hlc, std=1.5 * v, ci95=(v - 3 * v, v + 3 * v))
        return dataclasses.replace(k, hlc=hlc)

    sel = _selection([_Case("a", coloured_fits[0], 0.1)])
    plain = hlc_interval(sel)
    assert plain.ci95[0] > 0 and not any("below 0" in w for w in plain.warnings)
    monkeypatch.setattr(kpi_module, "kpis", wide)
    got = hlc_interval(sel)
    v = got.value
    assert got.ci95 == pytest.approx((0.0, 4 * v))
    (why,) = [w for w in got.warnings if "below 0" in w]
    assert f"{-2 * v:.3g} W/K" in why and "do not bound the HLC from below" in why
    assert got.to_dict()["ci95"] == pytest.approx([0.0, 4 * v])
    assert "below 0" in got.text()


def test_the_select_outputs_carry_the_method(coloured_fits):
    from jaxbox.cli._select import _hlc, _hlc_text
    from jaxbox.report._html import _hlc_section

    sel = _selection([_Case("a", coloured_fits[0], 0.1), _Case("b", coloured_fits[1], 0.1005)])
    doc = _hlc(sel)
    assert doc["method"].startswith(HAC) and doc["ci95"][0] < doc["value"] < doc["ci95"][1]
    assert doc["method"] in _hlc_text(doc)
    # no measured boundary but the outdoor air: the outdoor-referenced HLC is the accepted
    # model's own, with its own HAC interval
    out = doc["outdoor"]
    assert out["value"] == pytest.approx(doc["models"][0]["value"], rel=1e-9)
    assert out["ci95"] == pytest.approx(doc["models"][0]["ci95"], rel=1e-9)
    assert out["boundaries"] == {} and "referenced to the outdoor air" in _hlc_text(doc)
    html = "".join(_hlc_section(sel))
    assert "Heat-loss coefficient" in html and "near-best" in html


def test_an_offset_beside_an_unused_boundary_is_named():
    """A zone losing 40 W/K through a heavy floor (5e7 J/K) to a cellar near 12 °C: a model
    without the cellar (``Zon+Int+Off``, the floor as its mass) puts that loss into a negative
    offset, and the warning names the cellar's column and the conductance the offset would be
    (the HLC's missing part, within a fifth); a model with the cellar (``Zon+BouC``) gets no
    such warning, nor does an offset that points the other way (``Zon+Off``: the cellar's
    conductance taken as the outdoor air's, the offset positive). Without the cellar's column
    the loss is named as one to an unmeasured boundary, at the outdoor air's mean. Either way
    the HLC's interval reaches up by that conductance."""
    rng = np.random.default_rng(11)
    n = 240
    t = np.arange(n) * STEP
    day = 2 * np.pi * t / 86400.0
    u = {
        "T_amb": 6.0 + 5.0 * np.sin(day - 2.0) + rng.normal(0, 0.5, n),
        "T_bou": 12.0 + 0.3 * np.sin(day / 7.0),
        "Q_hea": 2500.0 * (rng.random(n) > 0.4),
        "I_glo_hor": np.maximum(0.0, 500.0 * np.sin(day - 1.5)),
    }
    truth = {"C_zon": 3e6, "C_bou": 5e7, "R_wal": 0.01, "R_bou": 0.025, "gA": 2.0}
    truth |= {"T_zon0": 20.0, "T_bou0": 16.0}
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    y = simulate_model("Zon+BouC", truth, clean).y[:, 0]
    data = clean.with_columns(T_zon=y + rng.normal(0, 0.05, n))
    names = ("Zon+Int+Off", "Zon+BouC", "Zon+Off")  # one batch, as a search fits them
    batch = fit_batch([{"model": m, "data": data, "starts": 4} for m in names])
    fits = dict(zip(names, batch, strict=True))
    assert fits["Zon+Int+Off"].params["Q_off"] < 0 < fits["Zon+Off"].params["Q_off"]
    (w,) = _offset_warnings(fits["Zon+Int+Off"], data)
    assert "T_bou" in w and "lost to" in w
    added = float(w.split("add ")[1].split(" W/K")[0])
    assert added == pytest.approx(1 / truth["R_bou"], rel=0.2)
    assert not _offset_warnings(fits["Zon+BouC"], data)
    assert not _offset_warnings(fits["Zon+Off"], data)
    # without the cellar's column: a loss to an unmeasured boundary, at the outdoor mean
    frame = data.frame
    cols = {c: frame[c].to_numpy() for c in frame.columns if c != "T_bou"}
    unmeasured = Dataset.from_arrays(t, cols)
    (w,) = _offset_warnings(fits["Zon+Int+Off"], unmeasured)
    assert "unmeasured boundary" in w
    q = fits["Zon+Int+Off"].params["Q_off"]
    at_outdoor = -q / float((frame["T_zon"] - frame["T_amb"]).mean())
    assert float(w.split("add about ")[1].split(" W/K")[0]) == pytest.approx(at_outdoor, rel=1e-3)
    assert not _offset_warnings(fits["Zon+Off"], unmeasured)
    # the interval carries that reading: the model's own interval moved up by the conductance
    # joins it, and only there. With the cellar measured it holds the truth (140 W/K; the
    # model's own interval, about 100 W/K, misses it); with the loss read at the outdoor air's
    # mean (6 °C, the cellar near 12 °C) it reaches up by less: a lower bound of that loss
    own = kpis(fits["Zon+Int+Off"], interval="hac").hlc
    true_hlc = 1 / truth["R_wal"] + 1 / truth["R_bou"]
    record, _ = record_conductance(types.SimpleNamespace(result=fits["Zon+Int+Off"]))
    for d, h in ((data, added), (unmeasured, at_outdoor)):
        got = _interval(fits["Zon+Int+Off"], d)
        assert got.value == pytest.approx(own.value, rel=1e-9)
        assert got.ci95[0] == pytest.approx(own.ci95[0], rel=1e-9)
        # up by the offset's conductance, or to the conductance the record shows if higher
        assert got.ci95[1] == pytest.approx(max(own.ci95[1] + h, record), rel=1e-3)
        assert "offset read as a conductance" in got.method and got.method in got.text()
    assert own.ci95[1] < true_hlc <= _interval(fits["Zon+Int+Off"], data).ci95[1]
    assert own.ci95[1] + 10.0 < _interval(fits["Zon+Int+Off"], unmeasured).ci95[1] < true_hlc
    for name in ("Zon+BouC", "Zon+Off"):
        own = kpis(fits[name], interval="hac").hlc
        got = _interval(fits[name], data)
        up = max(own.ci95[1], record_conductance(types.SimpleNamespace(result=fits[name]))[0])
        assert got.ci95 == pytest.approx((own.ci95[0], up), rel=1e-9)
        assert "offset" not in got.method
    # an offset takes a constant unmeasured input itself: no line per 100 W of it
    assert _interval(fits["Zon+Int+Off"], data).per_100_w is None
    assert _interval(fits["Zon+BouC"], data).per_100_w is not None


def test_unmeasured_heat_lowers_the_hlc_by_its_mean_over_the_zones_excess():
    """ZonWal (125 W/K) heated by 300 W more than its data say (occupants, appliances): the
    model fitted to them takes that warmth for a lower HLC (about a fifth lower, its interval
    far from the truth), and the reported ``per_100_w``, ``100 / mean(T_zon − T_amb)``, moves it
    back to the truth within 5 % once the 300 W are known; every output says so."""
    from jaxbox.cli._select import _hlc, _hlc_text
    from jaxbox.report._html import _hlc_section

    rng = np.random.default_rng(3)
    t, u = _inputs(rng, N)
    hidden = 300.0
    heated = Dataset.from_arrays(t, {**u, "Q_hea": u["Q_hea"] + hidden, "T_zon": np.zeros(N)})
    y = simulate_model("ZonWal", ZONWAL, heated).y[:, 0] + rng.normal(0, 0.05, N)
    data = Dataset.from_arrays(t, {**u, "T_zon": y})
    sel = _selection([_Case("a", fit_model("ZonWal", data, starts=_start()), 0.1)])
    got = hlc_interval(sel)
    excess = float(np.mean(y - u["T_amb"]))
    assert got.zone_excess == pytest.approx(excess, rel=1e-12)
    assert got.per_100_w == pytest.approx(100.0 / excess, rel=1e-12)
    assert got.value < 0.85 * TRUE_HLC and got.ci95[1] < TRUE_HLC
    assert got.value + hidden / 100.0 * got.per_100_w == pytest.approx(TRUE_HLC, rel=0.05)
    line = (
        "every 100 W of heat the data do not measure (occupants, appliances) would add "
        f"{got.per_100_w:.3g} W/K"
    )
    doc = _hlc(sel)
    assert doc["per_100_w"] == pytest.approx(got.per_100_w)
    assert doc["zone_excess"] == got.zone_excess
    assert line in got.text() and line in _hlc_text(doc)
    assert line[1:] in "".join(_hlc_section(sel))


def test_the_interval_reaches_up_to_the_conductance_the_record_shows():
    """The data show the response over the record only: the interval's upper end is at least
    H(T), the conductance the accepted model shows after the record's length T (a step of
    heat, every other input held), which bounds the steady state from above. Checked
    against the analytic step response of one node, R (1 − e^(−T/RC)), and against the
    exact simulation of a two-node model; a model that settles well within its record keeps
    its own interval."""
    rng = np.random.default_rng(5)
    n = 120
    t, u = _inputs(rng, n)
    clean = Dataset.from_arrays(t, {**u, "T_zon": np.zeros(n)})
    truth = {"C_zon": 4e7, "R_wal": 0.01, "gA": 2.0, "T_zon0": 20.0}  # τ = 111 h, T = 119 h
    y = simulate_model("Zon", truth, clean).y[:, 0]
    slow = fit_model("Zon", clean.with_columns(T_zon=y + rng.normal(0, 0.05, n)), starts=2)
    h, span = record_conductance(types.SimpleNamespace(result=slow))
    r, c = slow.params["R_wal"], slow.params["C_zon"]
    assert span == (n - 1) * STEP
    assert h == pytest.approx(1 / (r * (1 - math.exp(-span / (r * c)))), rel=1e-9)
    got = _interval(slow, slow.data)
    own = kpis(slow, interval="hac").hlc
    assert own.ci95[1] < h and got.ci95 == pytest.approx((own.ci95[0], h), rel=1e-9)
    assert "conductance the record shows" in got.method
    # two nodes: the zone's rise after T under a step of 1 W, simulated exactly
    theta = {"C_zon": 2e6, "C_wal": 3e7, "R_wal": 0.01, "R_int": 0.002, "C_int": 5e7}
    theta |= {"gA": 1.0, "T_zon0": 0.0, "T_wal0": 0.0, "T_int0": 0.0}
    model = "Zon+Wal+Int"
    fit = types.SimpleNamespace(model=get_model(model), params=theta, data=clean)
    step = clean.with_columns(
        T_amb=np.zeros(n), Q_hea=np.ones(n), I_glo_hor=np.zeros(n), T_zon=np.zeros(n)
    )
    rise = simulate_model(model, theta, step).y[-1, 0]
    h2, _ = record_conductance(types.SimpleNamespace(result=fit))
    assert h2 == pytest.approx(1 / rise, rel=1e-6)
    # a model that settles within hours: its own interval stands
    fast = dict(truth, C_zon=2e6)  # τ = 5.6 h
    y = simulate_model("Zon", fast, clean).y[:, 0]
    quick = fit_model("Zon", clean.with_columns(T_zon=y + rng.normal(0, 0.05, n)), starts=2)
    got = _interval(quick, quick.data)
    assert got.ci95 == pytest.approx(kpis(quick, interval="hac").hlc.ci95, rel=1e-9)
    assert "record shows" not in got.method


def _interval(result, data):
    sel = _selection([_Case("a", result, 0.1)])
    sel.greybox.data = data
    return hlc_interval(sel)


def _offset_warnings(result, data):
    return [w for w in _interval(result, data).warnings if "offset" in w]


def test_an_interval_wider_than_the_value_says_the_data_hardly_determine_the_hlc(
    coloured_fits, monkeypatch
):
    """The rule every parameter's verdict applies (an interval beyond ±100 % of the value):
    the HLC is then reported as not determined, in the JSON, the text and a warning."""
    import jaxbox.validate._verdict as verdict
    from jaxbox.cli._select import _hlc_text
    from jaxbox.validate import HlcInterval

    wide = HlcInterval(value=100.0, ci95=(0.0, 350.0), level=0.95, method=HAC, models=())
    assert wide.half_width == pytest.approx(1.75) and not wide.determined
    assert wide.to_dict()["determined"] is False
    assert (
        wide.text()
        .split("\n")[0]
        .endswith("; not determined by these data: quote the interval, not the value")
    )
    narrow = dataclasses.replace(wide, ci95=(50.0, 150.0))
    assert narrow.determined and narrow.to_dict()["determined"] is True
    assert "not determined" not in narrow.text()
    assert not dataclasses.replace(wide, ci95=(0.0, math.inf)).determined
    sel = _selection([_Case("a", coloured_fits[0], 0.1)])
    got = hlc_interval(sel)
    assert got.determined and not any("hardly determine" in w for w in got.warnings)
    monkeypatch.setattr(verdict, "MAX_REL_CI", 0.25 * got.half_width)
    got = hlc_interval(sel)
    assert not got.determined
    (why,) = [w for w in got.warnings if "hardly determine" in w]
    assert why.startswith(f"the interval is ±{100 * got.half_width:.0f} % of the HLC")
    assert "not determined by these data" in _hlc_text(got.to_dict())
