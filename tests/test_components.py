"""Components: what each one adds, multi-zone numbering, parameter specs, declaration errors, and
a model declared from components in a few lines, registered, and recovered from its own data."""

import numpy as np
import pytest

from jaxbox.data import DataError, Dataset
from jaxbox.fit import fit_model
from jaxbox.models import (
    ModelError,
    RCNetwork,
    get_model,
    list_models,
    parameter_for,
    register,
)
from jaxbox.models import components as c
from jaxbox.simulate import simulate_arrays, simulate_model


def _net(name="t"):
    return c.zone(RCNetwork(name))


def _matrices(model, **theta):
    th = model.defaults() | theta
    return tuple(np.asarray(x) for x in model.state_space(th)), th


def _col(model, name):
    return model.inputs.index(name)


# ---- what each component adds --------------------------------------------------------------------


def test_zone_is_a_measured_capacity():
    m = c.wall(_net(), capacity=False).add(c.heating).build()
    assert m.states == ("T_zon",) and m.outputs == ("T_zon",)
    assert m.param_names == ("C_zon", "R_wal", "T_zon0")
    assert "air" in m.parameter("C_zon").description
    assert m.parameter("C_zon").default == parameter_for("C_zon").default


@pytest.mark.parametrize("position", [0.5, 0.2])
def test_wall_split_position(position):
    m = c.wall(_net(), position=position).build()
    (A, B, _, _), th = _matrices(m)
    R, Cz, Cw = th["R_wal"], th["C_zon"], th["C_wal"]
    assert A[0, 1] == pytest.approx(1 / (position * R * Cz))
    assert B[1, _col(m, "T_amb")] == pytest.approx(1 / ((1 - position) * R * Cw))
    assert m.param_names == ("C_zon", "C_wal", "R_wal", "T_zon0", "T_wal0")


def test_wall_position_can_be_estimated():
    m = c.wall(_net(), position="fra_wal").build()
    spec = m.parameter("fra_wal")
    assert (spec.lower, spec.upper, spec.default) == (0.01, 0.99, 0.5)
    (A, B, _, _), th = _matrices(m, fra_wal=0.3, R_wal=0.01)
    assert A[0, 1] == pytest.approx(1 / (0.3 * 0.01 * th["C_zon"]))
    assert B[1, 0] == pytest.approx(1 / (0.7 * 0.01 * th["C_wal"]))
    assert "(fra_wal*R_wal)" in m.equations()[0]
    assert "((1-fra_wal)*R_wal)" in m.equations()[1]


@pytest.mark.parametrize("position", [0.0, 1.0, -0.1, 1.5])
def test_wall_position_out_of_range(position):
    with pytest.raises(ModelError, match="strictly between 0 and 1"):
        c.wall(_net(), position=position)


def test_internal_mass_infiltration_boundary():
    net = c.infiltration(c.internal_mass(c.wall(_net(), capacity=False)))
    net = c.boundary(net, to="T_bou")
    m = net.build()
    assert m.param_names == (
        "C_zon",
        "C_int",
        "R_wal",
        "R_int",
        "R_inf",
        "R_bou",
        "T_zon0",
        "T_int0",
    )
    assert set(m.inputs) == {"T_amb", "T_bou"}
    (A, B, _, _), th = _matrices(m)
    g = 1 / th["R_wal"] + 1 / th["R_int"] + 1 / th["R_inf"] + 1 / th["R_bou"]
    assert A[0, 0] == pytest.approx(-g / th["C_zon"])
    assert B[0, _col(m, "T_amb")] == pytest.approx(
        (1 / th["R_wal"] + 1 / th["R_inf"]) / th["C_zon"]
    )


def test_boundary_with_capacity_and_other_names():
    m = c.boundary(c.wall(_net(), capacity=False), to="T_cel", name="cel", capacity=True).build()
    assert m.states == ("T_zon", "T_celwal")
    assert {"C_cel", "R_cel", "T_cel0"} <= set(m.param_names)
    assert "T_cel" in m.inputs
    m = c.boundary(c.wall(_net(), capacity=False), capacity=True, position=0.25).build()
    (A, _, _, _), th = _matrices(m)
    assert A[0, 1] == pytest.approx(1 / (0.25 * th["R_bou"] * th["C_zon"]))


def test_ground_to_an_input():
    m = c.ground(c.wall(_net(), capacity=False)).build()
    assert "T_gro" in m.inputs and "R_gro" in m.param_names
    with pytest.raises(ModelError, match="to=None"):
        c.ground(_net(), temperature=10.0)


def test_ground_at_a_constant_temperature():
    m = c.ground(c.wall(_net(), capacity=False), to=None, temperature=9.5).build()
    assert m.states == ("T_zon", "T_gro") and "T_gro" not in m.inputs
    assert m.parameter("T_gro0").default == 9.5
    assert m.equations()[1] == "T_gro = T_gro0 (constant)"
    (A, B, C, _), th = _matrices(m, T_gro0=9.5)
    assert np.all(A[1] == 0) and np.all(B[1] == 0)
    # steady state of the zone: between T_amb and the constant ground, by their conductances
    u = np.zeros(len(m.inputs))
    u[_col(m, "T_amb")] = 2.0
    x_zon = np.linalg.solve(A[:1, :1], -(B[:1] @ u + A[:1, 1] * 9.5))[0]
    g_wal, g_gro = 1 / th["R_wal"], 1 / th["R_gro"]
    assert x_zon == pytest.approx((2.0 * g_wal + 9.5 * g_gro) / (g_wal + g_gro))
    # and the simulation keeps the ground at T_gro0
    t = np.arange(50) * 3600.0
    U = np.stack([np.full(50, 2.0) if i == "T_amb" else np.zeros(50) for i in m.inputs], 1)
    _, x = simulate_arrays(m, th, t, U)
    np.testing.assert_allclose(np.asarray(x)[:, 1], 9.5, rtol=0, atol=1e-12)


def test_embedded_system_takes_the_heating():
    m = c.embedded(c.wall(_net(), capacity=False)).build()
    assert m.states == ("T_zon", "T_emb")
    assert {"C_emb", "R_emb", "T_emb0"} <= set(m.param_names)
    (_, B, _, _), th = _matrices(m)
    q = _col(m, "Q_hea")
    assert B[0, q] == 0 and B[1, q] == pytest.approx(1 / th["C_emb"])


def test_windows_any_number_and_split():
    net = c.internal_mass(c.wall(_net(), capacity=False))
    for name, inp in (("e", "I_e"), ("s", "I_s"), ("w", "I_w")):
        net = c.window(net, inp, name=name, fra=True)
    net = c.window(net, "I_glo_hor", fra=0.25)
    m = net.build()
    assert {"gA_e", "gA_s", "gA_w", "gA", "fra_sol"} <= set(m.param_names)
    assert m.parameter("gA_e").unit == "m²"
    (_, B, _, _), th = _matrices(m, gA_s=3.0, fra_sol=0.4)
    s, g = _col(m, "I_s"), _col(m, "I_glo_hor")
    assert B[0, s] == pytest.approx(0.6 * 3.0 / th["C_zon"])
    assert B[1, s] == pytest.approx(0.4 * 3.0 / th["C_int"])
    assert B[0, g] == pytest.approx(0.75 * th["gA"] / th["C_zon"])
    assert B[1, g] == pytest.approx(0.25 * th["gA"] / th["C_int"])
    with pytest.raises(ModelError, match="duplicate window 'gA_e'"):
        c.window(net, "I_e", name="e")
    with pytest.raises(ModelError, match="no node receives the share"):
        c.window(_net(), "I_s", fra=True)


def test_heating_radiative_fraction():
    m = c.heating(c.internal_mass(c.wall(_net(), capacity=False)), fra_rad=True).build()
    (_, B, _, _), th = _matrices(m, fra_rad=0.3)
    q = _col(m, "Q_hea")
    assert B[0, q] == pytest.approx(0.7 / th["C_zon"])
    assert B[1, q] == pytest.approx(0.3 / th["C_int"])
    # without internal mass the radiative share goes to the wall
    m = c.heating(c.wall(_net()), fra_rad=0.4).build()
    (_, B, _, _), th = _matrices(m)
    assert B[1, _col(m, "Q_hea")] == pytest.approx(0.4 / th["C_wal"])
    assert "fra_rad" not in m.param_names
    with pytest.raises(ModelError, match="fraction"):
        c.heating(c.wall(_net()), fra_rad=1.5)


def test_electric_gains_may_exceed_one():
    m = c.electric_gains(c.wall(_net(), capacity=False)).build()
    spec = m.parameter("fra_ele")
    assert spec.upper == 3.0 and spec.lower == 0.0
    (_, B, _, _), th = _matrices(m, fra_ele=1.4)
    assert B[0, _col(m, "P_ele")] == pytest.approx(1.4 / th["C_zon"])


def test_sensor_is_measured_instead_of_the_air():
    m = c.sensor(c.wall(_net(), capacity=False)).build()
    assert m.states == ("T_zon", "T_sen") and m.outputs == ("T_zon",)
    (_, _, C, _), _ = _matrices(m)
    np.testing.assert_array_equal(C, [[0.0, 1.0]])
    with pytest.raises(ModelError, match="not measured"):
        c.sensor(c.sensor(c.wall(_net(), capacity=False)))


def test_sensor_offset_is_a_constant_offset_of_the_outputs():
    """A constant heat input Q_off into the zone, with the initial states shifted by its
    steady-state response s = (−A)⁻¹ b, gives the outputs of the model without it plus the
    constant s_zone: a sensor offset of s_zone kelvin (s_zone = Q_off / UA for one state)."""
    base = c.heating(c.wall(_net())).build()
    shifted = c.sensor_offset(c.heating(c.wall(_net()))).build()
    assert shifted.inputs == (*base.inputs, "one") and "Q_off" in shifted.param_names
    theta = base.defaults() | {"T_zon0": 19.0, "T_wal0": 14.0}
    (A, B, _, _), _ = _matrices(shifted, **theta, Q_off=120.0)
    s = np.linalg.solve(-A, B[:, _col(shifted, "one")])
    rng = np.random.default_rng(0)
    n = 200
    t = np.arange(n) * 900.0
    u = np.column_stack([10 + rng.normal(0, 2, n), 500.0 * (rng.random(n) > 0.5)])
    y0 = np.asarray(simulate_arrays(base, theta, t, u)[0])
    moved = theta | {"Q_off": 120.0, "T_zon0": 19.0 + s[0], "T_wal0": 14.0 + s[1]}
    y1 = np.asarray(simulate_arrays(shifted, moved, t, np.column_stack([u, np.ones(n)]))[0])
    np.testing.assert_allclose(y1, y0 + s[0], rtol=0, atol=1e-10)
    # one state: the offset is Q_off / UA
    one = c.sensor_offset(c.wall(_net(), capacity=False)).build()
    (A1, B1, _, _), th = _matrices(one, Q_off=50.0)
    off = np.linalg.solve(-A1, B1[:, _col(one, "one")])[0]
    np.testing.assert_allclose(off, 50.0 * th["R_wal"], rtol=1e-12)
    from jaxbox.validate import sensor_offsets

    assert sensor_offsets(base, theta) == {}
    np.testing.assert_allclose(sensor_offsets(one, th)["T_zon"], off, rtol=1e-12)
    np.testing.assert_allclose(sensor_offsets(shifted, moved)["T_zon"], s[0], rtol=1e-12)
    with pytest.raises(ModelError, match="unknown node"):
        c.sensor_offset(_net(), zone="zon2")


def test_multizone_numbering_and_coupling():
    net = RCNetwork("two")
    for z in ("zon1", "zon2"):
        net = c.wall(c.zone(net, z), z)
        net = c.window(c.heating(net, zone=z), "I_glo_hor", z)
    for capacity in (False, True):
        m = c.zone_coupling(net, "zon1", "zon2", capacity=capacity).build()
        assert m.outputs == ("T_zon1", "T_zon2")
        assert {"Q_hea1", "Q_hea2"} <= set(m.inputs)
        assert {"C_zon1", "R_wal1", "C_wal2", "gA1", "gA2", "T_zon20", "R_bou"} <= set(
            m.param_names
        )
        assert ("C_bou" in m.param_names) == capacity
        assert m.parameter("C_zon1").default == parameter_for("C_zon").default
        assert m.parameter("gA2").upper == 50.0
    with pytest.raises(ModelError, match="unknown node 'zon3'"):
        c.zone_coupling(net, "zon1", "zon3")


def test_fluent_and_functional_styles_agree():
    a = (
        RCNetwork("M")
        .add(c.zone)
        .add(c.wall, position=0.4)
        .add(c.heating)
        .add(c.window, "I_s", name="s")
        .build()
    )
    b = c.window(c.heating(c.wall(c.zone(RCNetwork("M")), position=0.4)), "I_s", name="s").build()
    assert a == b
    with pytest.raises(ModelError, match="must return an RCNetwork"):
        RCNetwork("M").add(lambda net: None)


def test_components_reproduce_the_foundation_models():
    zon = c.window(c.heating(c.wall(c.zone(RCNetwork("Zon")), capacity=False)), "I_glo_hor")
    assert zon.build().structure == get_model("Zon").structure
    zw = c.window(c.heating(c.wall(c.zone(RCNetwork("ZonWal")))), "I_glo_hor")
    assert zw.build().structure == get_model("ZonWal").structure


# ---- parameter specs -----------------------------------------------------------------------------


def test_parameter_specs_in_the_declaration():
    net = c.wall(_net(), capacity=False).parameter("R_wal", default=0.02, upper=1.0)
    m = net.build()
    assert (m.parameter("R_wal").default, m.parameter("R_wal").upper) == (0.02, 1.0)
    assert m.with_parameters({"R_wal": {"default": 0.03}}).parameter("R_wal").default == 0.03
    assert net.build({"R_wal": {"default": 0.05}}).parameter("R_wal").default == 0.05
    with pytest.raises(ModelError, match="no field"):
        net.parameter("R_wal", minimum=0.0)
    with pytest.raises(ModelError, match="no element of the network uses"):
        net.parameter("R_int").build()
    with pytest.raises(ModelError, match="naming convention"):
        net.parameter("wal_R")


def test_parametric_share_of_a_resistance():
    m = (
        RCNetwork("s")
        .node("zon", output=True)
        .resistance("zon", "T_amb", "R_wal", scale="2*fra_a")
        .resistance("zon", "T_bou", "R_wal", scale="1-fra_a")
        .build()
    )
    assert m.param_names == ("C_zon", "R_wal", "fra_a", "T_zon0")
    (A, _, _, _), th = _matrices(m, fra_a=0.2, R_wal=0.01)
    g = 1 / (2 * 0.2 * 0.01) + 1 / (0.8 * 0.01)
    assert A[0, 0] == pytest.approx(-g / th["C_zon"])


# ---- declaration errors --------------------------------------------------------------------------


def test_declaration_errors_are_clear():
    with pytest.raises(ModelError, match="unknown node 'zon'"):
        c.wall(RCNetwork("x"))
    with pytest.raises(ModelError, match="unknown node 'zon1'"):
        c.internal_mass(_net(), "zon1")
    with pytest.raises(ModelError, match="duplicate node 'zon'"):
        c.zone(_net())
    with pytest.raises(ModelError, match="duplicate node 'int'"):
        c.internal_mass(c.internal_mass(_net()))
    with pytest.raises(ModelError, match="no capacity"):
        _net().node("wal", C="")
    with pytest.raises(ModelError, match="no resistance path"):
        c.wall(_net()).node("int").build()
    with pytest.raises(ModelError, match="no resistance path"):
        c.internal_mass(_net()).build()  # zone and mass float: nothing links them to a boundary
    with pytest.raises(ModelError, match="held at a constant temperature"):
        _net().constant("gro").heat("gro", "Q_hea")
    with pytest.raises(ModelError, match="linked to nothing"):
        c.wall(_net()).constant("gro").build()
    with pytest.raises(ModelError, match="another boundary"):
        _net().constant("gro").resistance("gro", "T_amb", "R_gro")


def test_registration_checks_the_declaration():
    with pytest.raises(ModelError, match="no resistance path"):
        register("BrokenForTest", lambda: _net("BrokenForTest"))
    assert "BrokenForTest" not in list_models()
    with pytest.raises(ModelError, match="exists already"):
        register("Zon", lambda: get_model("Zon"))


def test_an_input_the_data_lacks():
    m = c.window(c.heating(c.wall(_net("W"), capacity=False)), "I_e", name="e").build()
    t = np.arange(10) * 3600.0
    data = Dataset.from_arrays(t, {"T_amb": np.zeros(10), "Q_hea": np.zeros(10), "T_zon": t * 0})
    with pytest.raises(DataError, match="'I_e' required by model W"):
        m.check_data(data)
    with pytest.raises(DataError, match="'I_e'"):
        fit_model(m, data)
    with pytest.raises(DataError, match="'I_e'"):
        simulate_model(m, None, data)
    m.check_data(data.with_columns(I_e=np.zeros(10)))


# ---- a user model in a few lines, registered and recovered ---------------------------------------


def _user_model():
    """Zone, envelope, internal mass, constant ground, floor heating, a split south window and
    electric gains."""
    net = c.internal_mass(c.wall(c.zone(RCNetwork("UserZonWalIntGroEmb"))))
    net = c.embedded(c.ground(net, to=None, temperature=10.0))
    return c.electric_gains(c.window(net, "I_s", name="s", fra=True))


TRUTH = {
    "C_zon": 4e6,
    "C_wal": 3e7,
    "C_int": 1.5e7,
    "C_emb": 6e6,
    "R_wal": 1e-2,
    "R_int": 2.5e-3,
    "R_gro": 3e-2,
    "R_emb": 2e-3,
    "gA_s": 3.5,
    "fra_sol": 0.4,
    "fra_ele": 1.3,
    "T_zon0": 21.0,
    "T_wal0": 14.0,
    "T_int0": 20.0,
    "T_gro0": 11.0,
    "T_emb0": 26.0,
}


def _user_data(model, n=240, seed=4):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 3600.0
    h = (t / 3600) % 24
    day = (t // 86400).astype(int)
    hold = np.repeat(rng.integers(0, 2, n // 6 + 1), 6)[:n]
    u = {
        "T_amb": 9 + 5 * np.sin(2 * np.pi * (h - 9) / 24) + np.cumsum(rng.normal(0, 0.3, n)),
        "I_s": 500
        * rng.uniform(0.2, 1, day.max() + 1)[day]
        * np.maximum(0, np.sin(np.pi * (h - 6) / 12)),
        "Q_hea": 2000.0 * hold,
        "P_ele": 300 + 400 * (rng.random(n) > 0.7),
    }
    U = np.stack([u[k] for k in model.inputs], axis=1)
    y = np.asarray(simulate_arrays(model, TRUTH, t, U)[0][:, 0])
    return Dataset.from_arrays(t, {**u, "T_zon": y})


def test_user_model_registered_in_a_family():
    from jaxbox.models import _library

    try:
        register("UserZonWalIntGroEmb", _user_model, family="user")
        assert list_models(family="user") == ["UserZonWalIntGroEmb"]
        m = get_model("UserZonWalIntGroEmb")
        assert set(m.param_names) == set(TRUTH)
        assert set(m.inputs) == {"T_amb", "I_s", "Q_hea", "P_ele"}
    finally:
        _library._REGISTRY.pop("UserZonWalIntGroEmb", None)
    assert "UserZonWalIntGroEmb" not in list_models()


def test_user_model_recovers_its_parameters():
    model = _user_model().build()
    data = _user_data(model)
    names = model.param_names
    rng = np.random.default_rng(2)
    starts = []
    for _ in range(3):
        row = []
        for n in names:
            v = TRUTH[n]
            if n.startswith(("R_", "C_")):
                v *= np.exp(rng.choice([-1, 1]) * rng.uniform(0.3, 0.6))
            elif n.startswith(("gA", "fra")):
                v *= rng.uniform(0.7, 1.3)
            else:
                v += rng.uniform(-2, 2)
            row.append(v)
        starts.append(row)
    result = fit_model(model, data, starts=np.asarray(starts))
    assert result.converged and np.sqrt(result.cost) < 1e-7
    for n in names:
        assert result.params[n] == pytest.approx(TRUTH[n], rel=1e-4), n
