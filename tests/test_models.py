"""The declarative RC network: structure, matrices, parameters and declaration errors."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbox.models import ModelError, Parameter, RCNetwork, get_model, list_models, parameter_for


def test_library_has_foundation_models():
    assert {"Zon", "ZonWal"} <= set(list_models())
    zon = get_model("Zon")
    assert zon.param_names == ("C_zon", "R_wal", "gA", "T_zon0")
    assert set(zon.inputs) == {"T_amb", "I_glo_hor", "Q_hea"}
    assert zon.outputs == ("T_zon",)
    zw = get_model("ZonWal")
    assert set(zw.param_names) == {"C_zon", "C_wal", "R_wal", "gA", "T_zon0", "T_wal0"}


def test_one_state_matrices_match_the_energy_balance():
    m = get_model("Zon")
    th = {"C_zon": 2e6, "R_wal": 0.01, "gA": 3.0, "T_zon0": 20.0}
    A, B, C, D = m.state_space(th)
    u = {name: i for i, name in enumerate(m.inputs)}
    assert float(A[0, 0]) == pytest.approx(-1 / (0.01 * 2e6))
    assert float(B[0, u["T_amb"]]) == pytest.approx(1 / (0.01 * 2e6))
    assert float(B[0, u["Q_hea"]]) == pytest.approx(1 / 2e6)
    assert float(B[0, u["I_glo_hor"]]) == pytest.approx(3.0 / 2e6)
    np.testing.assert_array_equal(C, [[1.0]])
    np.testing.assert_array_equal(D, np.zeros((1, 3)))


def test_two_state_split_wall_steady_state():
    m = get_model("ZonWal")
    th = m.defaults()
    A, B, _, _ = m.state_space(th)
    # all temperatures equal → no flow; a heat input Q raises the zone by R_wal·Q
    u = np.zeros(len(m.inputs))
    u[m.inputs.index("T_amb")] = 5.0
    u[m.inputs.index("Q_hea")] = 1000.0
    x = np.linalg.solve(np.asarray(A), -np.asarray(B) @ u)
    assert x[0] == pytest.approx(5.0 + th["R_wal"] * 1000.0)
    assert x[1] == pytest.approx(5.0 + 0.5 * th["R_wal"] * 1000.0)
    assert np.all(np.linalg.eigvals(np.asarray(A)).real < 0)


def test_naming_convention():
    assert parameter_for("R_wal").unit == "K/W"
    assert parameter_for("C_int").unit == "J/K"
    assert parameter_for("gA_e").lower == 0.0
    assert parameter_for("fra_rad").upper == 1.0
    assert parameter_for("fra_ele").upper > 1.0
    t0 = parameter_for("T_zon0")
    assert (t0.unit, t0.lower, t0.upper) == ("°C", -3.0, 37.0)
    assert t0.is_initial_state
    with pytest.raises(ModelError, match="naming convention"):
        parameter_for("foo")


def test_parameter_override_and_bad_override():
    m = get_model("Zon").with_parameters({"R_wal": {"default": 0.02, "upper": 1.0}})
    assert m.parameter("R_wal").default == 0.02
    with pytest.raises(ModelError, match="outside its bounds"):
        Parameter("R_x", "K/W", 5.0, 0.0, 1.0)
    with pytest.raises(ModelError, match="unknown parameter 'R_nope'"):
        get_model("Zon").network.build({"R_nope": {"default": 1.0}})


def test_declaration_errors_are_clear():
    net = RCNetwork("t").node("zon", output=True)
    with pytest.raises(ModelError, match="unknown node 'wal'"):
        net.resistance("wal", "T_amb", "R_wal")
    with pytest.raises(ModelError, match="duplicate node 'zon'"):
        net.node("zon")
    with pytest.raises(ModelError, match="no capacity"):
        net.node("wal", C="")
    with pytest.raises(ModelError, match="neither a declared node nor a temperature input"):
        net.resistance("zon", "amb", "R_wal")
    with pytest.raises(ModelError, match="named R_"):
        net.resistance("zon", "T_amb", "K_wal")
    with pytest.raises(ModelError, match="temperature"):
        net.heat("zon", "T_amb")
    with pytest.raises(ModelError, match="no resistance path"):
        net.resistance("zon", "T_amb", "R_wal").node("int").build()
    with pytest.raises(ModelError, match="no node is measured"):
        RCNetwork("x").node("zon").resistance("zon", "T_amb", "R_wal").build()
    with pytest.raises(ModelError, match="no library model named 'Nope'"):
        get_model("Nope")


def test_gain_expressions():
    m = (
        RCNetwork("g")
        .node("zon", output=True)
        .node("int")
        .resistance("zon", "T_amb", "R_wal")
        .resistance("zon", "int", "R_int")
        .heat("zon", "Q_hea", gain="1-fra_rad")
        .heat("int", "Q_hea", gain="fra_rad")
        .heat("zon", "I_e", gain="0.5*gA_e")
        .build()
    )
    th = m.defaults() | {"fra_rad": 0.3, "gA_e": 4.0}
    _, B, _, _ = m.state_space(th)
    q, ie = m.inputs.index("Q_hea"), m.inputs.index("I_e")
    assert float(B[0, q]) == pytest.approx(0.7 / th["C_zon"])
    assert float(B[1, q]) == pytest.approx(0.3 / th["C_int"])
    assert float(B[0, ie]) == pytest.approx(2.0 / th["C_zon"])
    assert "fra_rad" in m.param_names and "gA_e" in m.param_names


def test_models_are_hashable_values():
    assert get_model("Zon") == get_model("Zon")
    assert hash(get_model("Zon")) == hash(get_model("Zon"))
    assert get_model("Zon").structure != get_model("ZonWal").structure
    A, *_ = get_model("Zon").state_space(
        {k: jnp.asarray(v) for k, v in get_model("Zon").defaults().items()}
    )
    assert A.dtype == jnp.float64


def test_hostile_declarations_are_refused_by_name():
    """Names that are not text, shares that are not fractions, gains naming capacities or
    resistances, infinite scales and gains, duplicated elements, an output that is an input."""
    from jaxbox.models import components as c

    net = RCNetwork("M").node("zon", output=True)
    cases = [
        (lambda: RCNetwork("M").node("zon", C=5), "capacity parameter of node 'zon' is 5"),
        (lambda: RCNetwork("M").node("zon", C="C_ zon"), "capacity parameter .* 'C_ zon'"),
        (lambda: RCNetwork("M").node("zon", output="T zon"), "output of node 'zon' is 'T zon'"),
        (lambda: net.resistance("zon", 3, "R_w"), "links 'zon' to 3; give a node name"),
        (lambda: net.resistance("zon", "T_amb", "R_ w"), "'R_ w' must be named R_\\*"),
        (lambda: net.resistance("zon", "T_amb", "R_w", scale=np.inf), "finite scale > 0"),
        (lambda: net.resistance("zon", "T_amb", "R_w", scale="C_zon"), "a fraction fra_\\*"),
        (lambda: net.heat("zon", 3), "heat input 3 of node 'zon' must be a column name"),
        (lambda: net.heat("zon", "Q_hea", gain=float("nan")), "give a finite number"),
        (lambda: net.heat("zon", "Q_hea", gain="C_zon"), "names 'C_zon'; a gain names"),
        (lambda: net.heat("zon", "Q_hea", gain="1-gA"), "only a fraction fra_\\* has"),
        (lambda: c.infiltration(c.infiltration(c.wall(net))), "'R_inf' .* declared twice"),
        (lambda: net.heat("zon", "Q_hea").heat("zon", "Q_hea"), "'Q_hea' .* declared twice"),
        (
            lambda: RCNetwork("M").node("zon", output="T_amb").resistance("zon", "T_amb", "R_w"),
            "output 'T_amb' is also an input",
        ),
    ]
    for make, message in cases:
        with pytest.raises(ModelError, match=message):
            make().build()
