"""The component grammar's rules (jaxbox.models.grammar) and the physical bounds of parameter
specs: every name the project uses still reads, every library model builds as before, and each
ill-formed name, structure or spec is refused by name with the fix."""

import dataclasses
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from jaxbox.models import (
    Grammar,
    ModelError,
    Parameter,
    RCNetwork,
    Structure,
    extensions,
    families,
    get_model,
    list_models,
    parse_structure,
    random_structure,
    reductions,
    roots,
)
from jaxbox.models import components as c

# ---- what exists keeps working ------------------------------------------------------------------

#: every library model's parameters, in order, as they were before the grammar's rules (a model
#: that changes here changes every saved fit and every reference table)
LIBRARY = {
    "Zon": "C_zon R_wal gA T_zon0",
    "ZonWal": "C_zon C_wal R_wal gA T_zon0 T_wal0",
    "ZonWalIntInf": "C_zon C_wal C_int R_wal R_int R_inf gA T_zon0 T_wal0 T_int0",
    "ZonWalIntInfWin": "C_zon C_wal C_int R_wal R_int R_inf gA_e gA_w T_zon0 T_wal0 T_int0",
    "ZonWalIntInfWinBou": (
        "C_zon C_wal C_int R_wal R_int R_inf R_bou gA_e gA_w T_zon0 T_wal0 T_int0"
    ),
    "ZonWalIntInfWinBouC": (
        "C_zon C_wal C_int C_bou R_wal R_int R_inf R_bou gA_e gA_w T_zon0 T_wal0 T_int0 T_bou0"
    ),
    "ZonIntBou": "C_zon C_int R_wal R_int R_bou gA T_zon0 T_int0",
    "Zon2IntBou": (
        "C_zon1 C_int1 C_zon2 C_int2 R_wal1 R_int1 R_wal2 R_int2 R_bou gA1 gA2 T_zon10 "
        "T_int10 T_zon20 T_int20"
    ),
    "Zon2IntBouC": (
        "C_zon1 C_int1 C_zon2 C_int2 C_bou R_wal1 R_int1 R_wal2 R_int2 R_bou gA1 gA2 "
        "T_zon10 T_int10 T_zon20 T_int20 T_bou0"
    ),
    "BM_Ti": "C_zon R_wal gA T_zon0",
    "BM_TiTe": "C_zon C_wal R_wal fra_wal gA T_zon0 T_wal0",
    "BM_TiTh": "C_zon C_hea R_wal R_hea gA T_zon0 T_hea0",
    "BM_TiTeTh": "C_zon C_wal C_hea R_wal fra_wal R_hea gA T_zon0 T_wal0 T_hea0",
    "BM_TiTmTe": "C_zon C_wal C_int R_wal fra_wal R_int gA T_zon0 T_wal0 T_int0",
    "BM_TiTeThRia": "C_zon C_wal C_hea R_wal fra_wal R_inf R_hea gA T_zon0 T_wal0 T_hea0",
    "BM_TiTmTeTh": (
        "C_zon C_wal C_int C_hea R_wal fra_wal R_int R_hea gA T_zon0 T_wal0 T_int0 T_hea0"
    ),
    "BM_TiTeThTs": (
        "C_zon C_wal C_hea C_sen R_wal fra_wal R_hea R_sen gA T_zon0 T_wal0 T_hea0 T_sen0"
    ),
    "BM_TiTmTeThTs": (
        "C_zon C_wal C_int C_hea C_sen R_wal fra_wal R_int R_hea R_sen gA T_zon0 T_wal0 "
        "T_int0 T_hea0 T_sen0"
    ),
    "BM_TiTeAe": "C_zon C_wal R_wal fra_wal gA gA_wal T_zon0 T_wal0",
    "BM_TiTeThAe": "C_zon C_wal C_hea R_wal fra_wal R_hea gA gA_wal T_zon0 T_wal0 T_hea0",
    "BM_TiTmTeAe": "C_zon C_wal C_int R_wal fra_wal R_int gA gA_wal T_zon0 T_wal0 T_int0",
    "BM_TiTeThRiaAe": "C_zon C_wal C_hea R_wal fra_wal R_inf R_hea gA gA_wal T_zon0 T_wal0 T_hea0",
    "BM_TiTmTeThAe": (
        "C_zon C_wal C_int C_hea R_wal fra_wal R_int R_hea gA gA_wal T_zon0 T_wal0 T_int0 T_hea0"
    ),
    "BM_TiTeThTsAe": (
        "C_zon C_wal C_hea C_sen R_wal fra_wal R_hea R_sen gA gA_wal T_zon0 T_wal0 T_hea0 T_sen0"
    ),
    "BM_TiTmTeThTsAe": (
        "C_zon C_wal C_int C_hea C_sen R_wal fra_wal R_int R_hea R_sen gA gA_wal T_zon0 "
        "T_wal0 T_int0 T_hea0 T_sen0"
    ),
}

FAMILIES = {
    "exp1": [
        "Zon",
        "ZonWal",
        "ZonWalIntInf",
        "ZonWalIntInfWin",
        "ZonWalIntInfWinBou",
        "ZonWalIntInfWinBouC",
    ],
    "exp2": ["ZonIntBou", "Zon2IntBou", "Zon2IntBouC"],
    "multizone": ["Zon2IntBou", "Zon2IntBouC"],
    "bacher-madsen": [
        "BM_Ti",
        "BM_TiTe",
        "BM_TiTh",
        "BM_TiTeTh",
        "BM_TiTmTe",
        "BM_TiTeThRia",
        "BM_TiTmTeTh",
        "BM_TiTeThTs",
        "BM_TiTmTeThTs",
        "BM_TiTeAe",
        "BM_TiTeThAe",
        "BM_TiTmTeAe",
        "BM_TiTeThRiaAe",
        "BM_TiTmTeThAe",
        "BM_TiTeThTsAe",
        "BM_TiTmTeThTsAe",
    ],
}

#: every structure name used in the tests, the README and the benchmark notes
USED = (
    "Zon",
    "Zon+Bou",
    "Zon+Bou+WinSEW",
    "Zon+Bou+WinSEW+Off",
    "Zon+BouC",
    "Zon+BouC+Hea",
    "Zon+Cel",
    "Zon+Hea",
    "Zon+Hea+Off",
    "Zon+Hea+WinSEW",
    "Zon+Hea+WinSEW+Off",
    "Zon+Int",
    "Zon+Int+Bou+Hea",
    "Zon+Int+Bou+Sol",
    "Zon+Int+Bou+Sup+WinSEW+Off",
    "Zon+Int+Bou+WinSW",
    "Zon+Int+BouC",
    "Zon+Int+Hea",
    "Zon+Int+Hea+Off",
    "Zon+Int+Hea+Sol",
    "Zon+Int+Hea+WinSEW",
    "Zon+Int+Off",
    "Zon+Int+Rad",
    "Zon+Int+Sol",
    "Zon+Int+WinE",
    "Zon+Int+WinSE+Sol",
    "Zon+Int+WinSEW",
    "Zon+Int+WinSEW+Sol",
    "Zon+Off",
    "Zon+Wal",
    "Zon+Wal+Ae",
    "Zon+Wal+Bou",
    "Zon+Wal+Bou+Ae",
    "Zon+Wal+Bou+Sol",
    "Zon+Wal+BouC",
    "Zon+Wal+GroC",
    "Zon+Wal+Hea",
    "Zon+Wal+Hea+Ae",
    "Zon+Wal+Hea+Sol",
    "Zon+Wal+Hea+Sol+Off",
    "Zon+Wal+Hea+WinSEW",
    "Zon+Wal+Inf",
    "Zon+Wal+Inf+Ae",
    "Zon+Wal+Inf+Bou",
    "Zon+Wal+Inf+Bou+Off",
    "Zon+Wal+Inf+Hea",
    "Zon+Wal+Inf+Hea+Off",
    "Zon+Wal+Inf+Hea+Sol",
    "Zon+Wal+Inf+Hea+WinSE",
    "Zon+Wal+Inf+Sol",
    "Zon+Wal+Int",
    "Zon+Wal+Int+Ae",
    "Zon+Wal+Int+Bou",
    "Zon+Wal+Int+BouC+CelC+GroC",
    "Zon+Wal+Int+Hea",
    "Zon+Wal+Int+Inf",
    "Zon+Wal+Int+Inf+Bou",
    "Zon+Wal+Int+Off",
    "Zon+Wal+Int+Rad",
    "Zon+Wal+Int+Sol",
    "Zon+Wal+Int+SupC+Hea+WinEW+Off",
    "Zon+Wal+Int+WinE",
    "Zon+Wal+Int+WinSEW",
    "Zon+Wal+Off",
    "Zon+Wal+Sol",
    "Zon+Wal+WinE",
    "Zon+Wal+WinEW",
    "Zon+Wal+WinSEW",
    "Zon+Wal+WinSEW+Ae",
    "Zon+Wal+WinSEW+Sol",
    "Zon+WinS",
    "Zon+WinSEW",
    "Zon1+Bz2",
    "Zon1+Hea1+Bz2",
    "Zon1+Int1+Hea1+Bz2",
    "Zon1+Wal1+Bz2",
    "Zon1+Zon2+Cpl",
    "Zon1+Zon2+CplC",
    "Zon1+Zon2+Hea2+Cpl",
    "Zon1+Zon2+Int2+Cpl",
    "Zon1+Zon2+Off1+Int2+Cpl",
    "Zon1+Zon2+Off1+Off2+Cpl",
    "Zon1+Zon2+Off2+Cpl",
    "Zon1+Zon2+Wal1+Cpl",
    "Zon1+Zon2+Wal1+Wal2+CplC",
    "Zon1+Zon2+Wal2+WinSE2+Cpl",
    "Zon1+Zon2+WinE2+Cpl",
    "Zon1+Zon2+WinSE2+Cpl",
    "Zon1+Zon2+WinSEW2+Cpl",
    "Zon2+Bz1",
    "Zon2+Hea2+WinSEW2+Bz1",
    "Zon2+Hea2+WinSEW2+Off2+Bz1",
    "Zon2+Int2+Bz1",
    "Zon2+Wal2+Bz1",
    "Zon2+Wal2+Int2+Bz1",
)


def test_library_models_and_families_build_as_before():
    assert families() == FAMILIES
    assert list_models() == list(LIBRARY)
    for name, params in LIBRARY.items():
        assert " ".join(get_model(name).param_names) == params, name


#: the parameters of some of them, as they were before the grammar's rules
STRUCTURE_PARAMS = {
    "Zon+Wal+Int+Inf+Bou": "C_zon C_wal C_int R_wal R_int R_inf R_bou gA T_zon0 T_wal0 T_int0",
    "Zon+Wal+Int+BouC+CelC+GroC": (
        "C_zon C_wal C_int C_bou C_cel C_gro R_wal R_int R_bou R_cel R_gro gA T_zon0 "
        "T_wal0 T_int0 T_bou0 T_cel0 T_gro0"
    ),
    "Zon1+Zon2+CplC": "C_zon1 C_zon2 C_bou R_wal1 R_wal2 R_bou gA1 gA2 T_zon10 T_zon20 T_bou0",
    "Zon1+Zon2+Wal1+Wal2+CplC": (
        "C_zon1 C_wal1 C_zon2 C_wal2 C_bou R_wal1 R_wal2 R_bou gA1 gA2 T_zon10 T_wal10 "
        "T_zon20 T_wal20 T_bou0"
    ),
    "Zon+Wal+Int+SupC+Hea+WinEW+Off": (
        "C_zon C_wal C_int C_sup C_hea R_wal R_int R_sup R_hea gA_e gA_w Q_off T_zon0 "
        "T_wal0 T_int0 T_sup0 T_hea0"
    ),
    "Zon+Int+WinSEW+Sol": "C_zon C_int R_wal R_int gA_s fra_sol gA_e gA_w T_zon0 T_int0",
    "Zon+Wal+Inf+Hea+Sol": "C_zon C_wal C_hea R_wal R_inf R_hea gA fra_sol T_zon0 T_wal0 T_hea0",
    "Zon+Int+Rad": "C_zon C_int R_wal R_int fra_rad gA T_zon0 T_int0",
    "Zon1+Zon2+Off1+Int2+Cpl": (
        "C_zon1 C_zon2 C_int2 R_wal1 R_wal2 R_int2 R_bou gA1 Q_off1 gA2 T_zon10 T_zon20 T_int20"
    ),
    "Zon1+Int1+Hea1+Bz2": (
        "C_zon1 C_int1 C_hea1 R_wal1 R_int1 R_hea1 R_bou gA1 T_zon10 T_int10 T_hea10"
    ),
    "Zon+Wal+Hea+Ae": "C_zon C_wal C_hea R_wal R_hea gA gA_wal T_zon0 T_wal0 T_hea0",
}


@pytest.mark.parametrize("name", USED)
def test_every_structure_the_project_uses_still_reads(name):
    s = parse_structure(name)
    assert s.name == name and parse_structure(s.name) == s
    model = get_model(name)
    assert model.param_names == s.build().param_names
    if name in STRUCTURE_PARAMS:
        assert " ".join(model.param_names) == STRUCTURE_PARAMS[name]


GRAMMARS = [
    ["T_zon", "T_amb", "T_bou", "T_cel", "Q_hea", "I_glo_hor", "I_s", "I_e", "I_w", "P_ele"],
    ["T_zon", "T_amb", "T_gro", "Q_hea"],
    ["T_zon1", "T_zon2", "T_amb", "T_bou", "Q_hea1", "Q_hea2", "I_glo_hor", "I_s", "I_e"],
    ["T_zon1", "T_zon2", "T_amb", "Q_hea2"],
]


@pytest.mark.parametrize("columns", GRAMMARS)
def test_what_the_grammar_grows_reads_back_and_builds(columns):
    """Roots, extensions, reductions and random draws are all structures of the rules."""
    g = Grammar.from_columns(columns)
    rng = np.random.default_rng(7)
    grown = list(roots(g))
    for _ in range(60):
        grown.append(random_structure(g, rng))
    for s in list(grown):
        grown += [x for _, x in extensions(s, g)] + [x for _, x in reductions(s, g)]
    for s in grown:
        assert parse_structure(s.name) == s
        s.build(g)


# ---- 1. the coupling: CplC replaces Cpl ----------------------------------------------------------


def test_coupling_with_and_without_capacity_are_one_each():
    plain = get_model("Zon1+Zon2+Cpl").param_names
    split = get_model("Zon1+Zon2+CplC").param_names
    assert "R_bou" in plain and "C_bou" not in plain
    assert "R_bou" in split and "C_bou" in split and "T_bou0" in split


def test_cpl_and_cplc_together_are_refused_whatever_the_hash_seed():
    """Both tokens used to be kept: which coupling was built followed the set's iteration
    order, i.e. the process's hash seed. Now the name is refused, in every process."""
    with pytest.raises(ModelError, match=r"CplC .*replaces Cpl.*'Zon1\+Zon2\+CplC'"):
        parse_structure("Zon1+Zon2+Cpl+CplC")
    with pytest.raises(ModelError, match="replaces Cpl"):
        Structure((1, 2), frozenset({(-1, "Cpl"), (-1, "CplC")}))
    code = (
        "from jaxbox.models import parse_structure, ModelError\n"
        "try:\n"
        "    print(parse_structure('Zon1+Zon2+Cpl+CplC').build().param_names)\n"
        "except ModelError as e:\n"
        "    print('refused', 'replaces Cpl' in str(e))\n"
    )
    seen = set()
    for seed in ("1", "2"):
        env = {**os.environ, "PYTHONHASHSEED": seed, "JAX_PLATFORMS": "cpu"}
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
        seen.add(out.stdout.strip().splitlines()[-1])
    assert seen == {"refused True"}


# ---- 2. a boundary with its capacity variant -----------------------------------------------------


@pytest.mark.parametrize(
    "name, fixed",
    [
        ("Zon+Bou+BouC", "Zon+BouC"),
        ("Zon+Wal+Cel+CelC+Hea", "Zon+Wal+CelC+Hea"),
        ("Zon1+Zon2+Bou1+BouC1+Cpl", "Zon1+Zon2+BouC1+Cpl"),
    ],
)
def test_a_boundary_and_its_capacity_variant_are_refused(name, fixed):
    """Both used to build the boundary twice: R_bou on two branches, one with C_bou."""
    with pytest.raises(ModelError, match="replaces .*write " + re.escape(repr(fixed))):
        parse_structure(name)
    parse_structure(fixed)


# ---- 3. a coupling needs two zone states ---------------------------------------------------------


@pytest.mark.parametrize("name", ["Zon+Cpl", "Zon+CplC", "Zon1+Cpl", "Zon1+Cpl+Bz2"])
def test_a_coupling_without_two_zone_states_is_refused(name):
    """The coupling used to be dropped in silence: 'Zon+Cpl' built the model 'Zon'."""
    with pytest.raises(ModelError, match="couples two zones modelled as states"):
        parse_structure(name)


# ---- 4. the needs among a zone's components ------------------------------------------------------


@pytest.mark.parametrize(
    "name, words",
    [
        ("Zon+Inf", r"Inf \(infiltration.*needs Wal; write 'Zon\+Wal\+Inf'"),
        ("Zon+Ae", r"Ae \(solar gains on the envelope.*needs Wal; write 'Zon\+Wal\+Ae'"),
        ("Zon+Wal+Rad", r"Rad .*needs Int, .*write 'Zon\+Wal\+Int\+Rad'"),
        ("Zon+Int+Hea+Rad", r"two accounts .*'Zon\+Int\+Rad' or 'Zon\+Int\+Hea'"),
        ("Zon+Sol", r"Sol .*needs a mass .*'Zon\+Int\+Sol' or 'Zon\+Wal\+Sol'"),
        ("Zon1+Zon2+Inf2+Cpl", r"Inf2 .*needs Wal2; write 'Zon1\+Zon2\+Wal2\+Inf2\+Cpl'"),
    ],
)
def test_a_component_without_what_it_needs_is_refused(name, words):
    """The table of needs was declared (and used to grow structures) but a name could break
    it: 'Zon+Inf' built R_inf parallel to R_wal, which the data cannot tell apart."""
    with pytest.raises(ModelError, match=words):
        parse_structure(name)


def test_the_needs_agree_with_growth():
    """A structure refused for a need is one that no extension of a valid structure grows."""
    g = Grammar.from_columns(GRAMMARS[0])
    rng = np.random.default_rng(11)
    for _ in range(40):
        s = random_structure(g, rng, size=5)
        for _, grown in extensions(s, g):
            assert parse_structure(grown.name) == grown


# ---- 5. unknown words ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, words",
    [
        ("Zon+Amb", r"'Amb' is not a grammar token \(the ambient T_amb is in every structure"),
        ("Zon+Ambient", "the ambient T_amb"),
        ("Zon1+Bz0", r"'Bz0' .*numbered from 1.*did you mean 'Bz1'"),
        ("Zon+Wall", r"'Wall' .*typo of Wal.*did you mean 'Wal'"),
        ("Zon+Zone", "did you mean 'Zon'"),
        ("Zon+Wal+Heat", "did you mean 'Hea'"),
        ("Zon+Wal+Bouc", "did you mean 'BouC'"),
        ("Zon1+Zon2+Cplc", "did you mean 'CplC'"),
        ("Zon+WalC", r"capacity variant.*did you mean 'Wal'"),
        ("Zon1+Zon2+Wal1+Cpl1", "did you mean 'Cpl'"),
        ("Zon+WinES", r"order S, E, W, N.*did you mean 'WinSE'"),
        ("Zon1+Zon2+WinES2+Cpl", "did you mean 'WinSE2'"),
        ("Zon+wal", r"not a grammar token.*did you mean 'Wal'"),
        ("Zon+WalInt", r"joined by '\+'.*did you mean 'Wal\+Int'"),
        ("Zon+Bz", "did you mean 'Bz1'"),
    ],
)
def test_unknown_words_are_refused_with_the_word_meant(name, words):
    """Every capitalised word used to be taken for a boundary to a column of that name
    ('Zon+Wall' needed T_wall, 'Zon+Amb' added a second path to T_amb), and 'Bz0' a zone."""
    with pytest.raises(ModelError, match=words) as err:
        parse_structure(name)
    assert "Bou for T_bou" in str(err.value)  # the words there are


def test_boundaries_named_after_their_column_still_read():
    for name, column in [
        ("Zon+Bou", "T_bou"),
        ("Zon+Cel", "T_cel"),
        ("Zon+Wal+Int+BouC+CelC+GroC", "T_gro"),
        ("Zon+Att", "T_att"),
        ("Zon+Int+Bou+Sup+WinSEW+Off", "T_sup"),
        ("Zon1+Zon2+Office1+Cpl", "T_office"),
    ]:
        assert column in get_model(name).inputs


def test_boundary_columns_are_the_words_the_names_read():
    cols = ["T_zon", "T_amb", "T_bou", "T_att", "T_x", "T_off", "T_ambient", "Q_hea"]
    g = Grammar.from_columns(cols)
    assert g.boundaries == ("T_bou", "T_att")  # T_x: no word; T_off: the sensor offset Off
    for _, s in extensions(roots(g)[0], g):
        assert parse_structure(s.name) == s
    with pytest.raises(ModelError, match=r"column T_wall .*typo of the token 'Wal'.*rename"):
        Grammar.from_columns(["T_zon", "T_amb", "T_wall"])


def test_names_that_are_not_names_say_what_was_meant():
    with pytest.raises(ModelError, match=r"did you mean 'Zon\+Wal'"):
        parse_structure("Zon + Wal")
    with pytest.raises(ModelError, match=r"did you mean 'Zon\+Wal\+Int'"):
        parse_structure("ZonWalInt")
    with pytest.raises(ModelError, match="is text"):
        parse_structure(3)
    with pytest.raises(ModelError, match="did you mean 'ZonWal'"):
        get_model("ZonWall")


@pytest.mark.parametrize(
    "name, words",
    [
        ("Zon+Zon1", "do not mix"),
        ("Zon+Bz2", "goes with numbered zones"),
        ("Zon1+Bz1", "both a state .* and a measured boundary"),
        ("Zon1+Bz2+Bz3", "one or two zones"),
        ("Zon1+Zon2+Zon3", "one or two zones"),
        ("Zon+WinS+WinE", "one window token per zone.*WinSE"),
        ("Zon1+Wal", "Wal belongs to zone Zon, which is not a state"),
        ("Zon+Wal+Wal", "'Wal' appears twice"),
    ],
)
def test_zones_and_windows_follow_the_rules(name, words):
    with pytest.raises(ModelError, match=words):
        parse_structure(name)


def test_a_structure_built_by_hand_is_checked_too():
    with pytest.raises(ModelError, match="Inf .*needs Wal"):
        Structure((0,), frozenset({(0, "Inf")}))
    with pytest.raises(ModelError, match="zone numbers"):
        Structure("12")
    with pytest.raises(ModelError, match=r"\(zone, token\) pairs"):
        Structure((0,), frozenset({"Wal"}))
    s = Structure([2, 1], {(-1, "Cpl"), (1, "Wal")})
    assert s.states == (1, 2) and s.tokens == frozenset({(-1, "Cpl"), (1, "Wal")})
    assert s == parse_structure("Zon1+Zon2+Wal1+Cpl") and hash(s) == hash(s)
    with pytest.raises(ModelError, match="Wal"):
        dataclasses.replace(s, tokens=frozenset({(1, "Wall")}))


def test_a_grammar_builds_only_what_its_data_drive():
    """A heater capacity without a heating column used to vanish in silence (and so did the
    heating of a zone the data do not have)."""
    no_heat = Grammar.from_columns(["T_zon", "T_amb", "I_glo_hor"])
    with pytest.raises(ModelError, match="Hea .*needs the heating column Q_hea"):
        parse_structure("Zon+Hea").build(no_heat)
    with pytest.raises(ModelError, match="Rad .*needs the heating column"):
        parse_structure("Zon+Int+Rad").build(no_heat)
    dark = Grammar.from_columns(["T_zon", "T_amb", "Q_hea"])
    with pytest.raises(ModelError, match="Sol .*needs solar gains"):
        parse_structure("Zon+Wal+Sol").build(dark)
    two = Grammar.from_columns(["T_zon1", "T_zon2", "T_amb", "Q_hea1", "Q_hea2"])
    with pytest.raises(ModelError, match="not a zone of the grammar's data"):
        parse_structure("Zon+Wal").build(two)
    assert "Q_hea" in parse_structure("Zon+Hea").build().inputs  # without a grammar: Q_hea


# ---- 6. physical bounds of parameter specs -------------------------------------------------------


@pytest.mark.parametrize(
    "spec, words",
    [
        (("R_wal", "K/W", 0.01, 0.0, 1.0), r"'R_wal': lower bound 0 must be > 0, a resistance"),
        (("R_x", "K/W", 0.01, -1.0, 1.0), r"'R_x': lower bound -1 must be > 0"),
        (("C_zon", "J/K", 1e6, 0.0, 1e8), r"'C_zon': lower bound 0 must be > 0, a capacity"),
        (("C_wal1", "J/K", 1e6, -np.inf, 1e8), "'C_wal1': lower bound -inf"),
        (("fra_rad", "-", 0.5, 0.0, 1.5), r"'fra_rad': bounds \[0, 1.5\] leave \[0, 1\]"),
        (("fra_sol1", "-", 0.0, -0.5, 1.0), r"'fra_sol1': bounds \[-0.5, 1\] leave \[0, 1\]"),
        (("fra_ele", "-", 1.0, -1.0, 3.0), r"'fra_ele': .*leave \[0, ∞\)"),
        (("R_wal", "K/W", "0.01", 1e-5, 1.0), "default must be a number"),
        ((3, "K/W", 0.01, 1e-5, 1.0), "a parameter name is text"),
    ],
)
def test_non_physical_bounds_are_refused_by_name(spec, words):
    with pytest.raises(ModelError, match=words):
        Parameter(*spec)


def test_the_bounds_stay_physical_wherever_they_are_given():
    assert Parameter("fra_ele", "-", 1.0, 0.0, 3.0).upper == 3.0  # a share that may exceed 1
    assert Parameter("R_wal", "K/W", 0.01, 1e-6, np.inf).upper == np.inf
    zon = get_model("Zon")
    with pytest.raises(ModelError, match="'R_wal': lower bound 0"):
        zon.with_parameters({"R_wal": {"lower": 0.0}})
    with pytest.raises(ModelError, match="'C_zon': lower bound -1e"):
        zon.network.build({"C_zon": {"lower": -1e6}})
    with pytest.raises(ModelError, match="'C_zon': lower bound 0"):
        zon.network.parameter("C_zon", lower=0.0)
    rad = get_model("Zon+Int+Rad")
    with pytest.raises(ModelError, match=r"'fra_rad': bounds \[0, 2\]"):
        rad.with_parameters({"fra_rad": {"upper": 2.0}})


def test_a_share_of_a_resistance_stays_inside_zero_and_one():
    """A fraction that places a capacity inside a resistance (``wall(position="fra_wal")``) at
    0 or 1 removes one side of the resistance: the zone joined to the wall or to T_amb."""
    net = c.wall(c.zone(RCNetwork("M")), position="fra_wal")
    net = c.heating(net)
    assert net.build().parameter("fra_wal").lower == 0.01
    for field, value in (("lower", 0.0), ("upper", 1.0)):
        with pytest.raises(ModelError, match=r"fra_wal sets a share of the resistance R_wal"):
            net.parameter("fra_wal", **{field: value}).build()
        with pytest.raises(ModelError, match="strictly inside"):
            net.build({"fra_wal": {field: value}})
    raw = RCNetwork("s").node("zon", output=True).resistance("zon", "T_amb", "R_wal", "2*fra_a")
    raw = raw.resistance("zon", "T_bou", "R_wal", scale="1-fra_a")
    a = raw.build().parameter("fra_a")  # undeclared: not the [0, 1] of other fractions
    assert (a.lower, a.default, a.upper) == (0.01, 0.5, 0.99)
    assert raw.parameter("fra_a", lower=0.05, upper=0.9).build().parameter("fra_a").lower == 0.05
    with pytest.raises(ModelError, match="fra_a sets a share of the resistance R_wal"):
        raw.parameter("fra_a", lower=0.0, upper=1.0).build()
    for name in list_models("bacher-madsen"):
        get_model(name)
