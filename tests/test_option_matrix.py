"""Every pair of options of every command, each with a valid and an invalid value.

The options are read from the command line's own parser (:func:`jaxbox.cli.build_parser`), so a
new command or option is in the matrix the day it is added: the values of each option come from
the table below where it names the option, else from its kind (a flag; a choice; an integer; a
number; text, of which only an invalid value, the empty string, is known).

Each option is a factor whose levels are *left out* (where it may be), its *valid* value(s) and
its *invalid* value. Two sets of rows per command (:func:`_pairs.all_pairs`):

* ``valid``: every pair of left-out and valid levels. These runs fit models (tiny data, one
  start, two iterations) and must end with exit 0, 1 (``no valid model``) or 2 (a combination
  refused with one ``error:`` line).
* ``invalid``: every pair in which at least one option is invalid. These must end with exit 2,
  one ``error:`` line last on stderr, nothing on stdout and nothing written.

Never an internal error, never a traceback. The values keep the compiled programs few (the same
lengths, one start, the base ``--starts``/``--max-steps`` given again), so the whole matrix stays
cheap: a few valid values that compile or draw much (:data:`COSTLY`) are run in one row each
instead of with every other option, and ``demo`` runs only its invalid rows (its valid ones
would identify the bundled twin house). The valid rows of ``fit`` and ``select``
(:data:`SLOW_VALID`), which identify models with every option combination, are in the long
tier (``-m slow``, CI's second step).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from _pairs import all_pairs, pairs_of
from test_hostile import frame

from jaxbox.cli._main import build_parser, main

N = 48  # hourly samples: a 24-h identification and a 24-h validation period

#: option -> (valid value, …, invalid value); None as the invalid value: the option has none
#: (a flag); an empty tuple of valid values: no valid value known. Placeholders: {csv} the
#: data, {missing} a path that does not exist, {out} a folder not yet made, {here} the run's own
#: (empty) folder, {file} an existing file where a folder is expected, and the prepared files
#: {params_ml} (a stochastic fit), {params_fit} (a fit document), {fleet}, {config}.
VALUES: dict[str, tuple] = {
    # DATA and the options that read and split it
    "data": ("{csv}", "{missing}"),
    "--map": ("T_zon=T_zon", "T_zon=no_such_column"),
    "--time": ("time", "no_such_column"),
    "--time-unit": ("s", "fortnights"),
    "--epoch": ("1970-01-01", "not a stamp"),
    "--tz": ("UTC", "Mars/Olympus_Mons"),
    "--sep": (",", ";"),
    "--decimal": (".", ","),
    "--thousands": ("'", "x"),
    "--scale": ("T_amb=1", "Q_hea=0"),
    "--counter": ("P_ele=kWh", "P_ele=furlongs"),
    "--range": ("T_zon=-10:60", "T_zon=60:-10"),
    "--stuck-hours": ("none", "-3"),
    "--resample": ("1h", "fortnightly"),
    "--train": ("2024-01-01..2024-01-02 00:00", "2030-01-01..2030-01-02"),
    "--validate": ("none", "2024-01-02..2023-01-01"),
    "--max-gap": ("2h", "-1h"),
    # models and fits
    "--model": ("Zon", "NoSuchModel"),
    "--models": ("Zon,ZonWal", "NoSuchModel"),
    "--starts": ("1", "0"),
    "--seed": ("7", "-1"),
    "--fix": ("gA=2", "no_such_parameter=1"),
    "--bounds": ("gA=0:50", "gA=5:1"),  # the default bounds: no new program to compile
    "--simulator": ("diffrax", "rk4"),
    "--method": ("ml", "ls"),
    "--max-steps": ("2", "0"),
    "--homotopy": ("none", "2,x"),
    "--criterion": ("aic", "r2"),
    "--beam": ("2", "0"),
    "--continued": ("1", "-1"),
    "--polish": ("1", "-1"),
    "--margin": ("0.05", "-1"),
    "--patience": ("0", "-1"),
    "--plots": ("{out}/plots", "{file}"),
    "--out": ("{out}", "{file}"),
    "--params": ("{params_fit}", "{missing}"),
    # estimate
    "--hold": ("zoh", "cubic"),
    # fleet
    "source": ("{fleet}", "{missing}"),
    "dir": ((), "extra"),
    "--config": ("{config}", "{missing}.toml"),
    "--partition-size": ("1", "0"),
    "--scheduler": ((), "localhost:8786"),
    "--workers": ("0", "-2"),
    "--n": ("2", "0"),
    "--days": ("1", "-1"),
    "--noise": ("0.1", "-1"),
    # design
    "--step": ("1h", "0"),
    "--sigma": ("0.1", "-1"),
    "--power": ("0:2000", "5:1"),
    "--comfort": ("10:40", "40:10"),
    "--max-energy": ("50kWh", "-5"),
    "--weather": ("{csv}", "{missing}"),
    "--start-temperature": ("18", "nan"),
    "--robust": ("0", "-1"),
    "--spread": ("0.1", "-1"),
    # demo
    "--house": ("O5", "Z9"),
    "--allow": ("jump", "wobble"),
    "--trim": ("none", "middle"),
    # forecast
    "--at": ("2024-01-02 12:00", "2030-01-01"),
    "--horizon": ("6h", "-1h"),
}

#: per command: values that differ from :data:`VALUES`
COMMAND_VALUES: dict[str, dict[str, tuple]] = {
    "estimate": {"--params": ("{params_ml}", "{csv}"), "--out": ("{here}/states.csv", "{out}/s")},
    "design": {"--out": ("{here}/design.csv", "{out}/design.csv")},
    "forecast": {
        "--params": ("{params_fit}", "{csv}"),
        "--out": ("{here}/forecast.csv", "{out}/forecast.csv"),
        "--plot": ("{here}/forecast.png", "{out}/forecast.png"),
        "--inputs": ("{csv}", "{missing}"),
    },
    "export": {
        "fit": ("{params_fit}", "{csv}"),
        "--out": ("{here}/model.json", "{out}/model.json"),
        "--format": ("json", "mat"),
        "--data": ("{csv}", "{missing}"),
    },
    "fleet": {"--out": ("{out}", "{file}"), "--models": ("Zon", "NoSuchModel")},
    "fleet make": {"--models": ("Zon", "NoSuchModel")},
}

#: per command: positional arguments given as they are (not factors) and options always given
#: first (a factor's value, given later, replaces them)
FIXED: dict[str, tuple[list[str], list[str]]] = {
    "fit": ([], ["--starts", "1", "--max-steps", "2"]),
    "select": ([], ["--models", "Zon", "--starts", "1", "--max-steps", "2"]),
    "fleet": ([], ["--out", "{out}", "--models", "Zon", "--starts", "1", "--workers", "0"]),
    "fleet make": (["make", "{out}"], ["--n", "2", "--days", "1"]),
    "design": ([], ["--model", "Zon", "--days", "1", "--starts", "1"]),
}

#: commands whose valid rows are too costly for the suite
INVALID_ONLY = {"demo"}
#: valid values that compile or draw much (the adaptive solver, plots, another set of free
#: parameters, a fit without continuation): each is run once, in a row of its own, not paired
#: with every other option
COSTLY = {
    ("--simulator", "diffrax"),
    ("--plots", None),
    ("--plot", None),
    ("--fix", None),
    ("--homotopy", "none"),
}


@dataclass(frozen=True)
class Factor:
    """One option (or positional argument) of a command and its levels, each an argv
    fragment: ``levels[k]`` is ``None`` for "left out"; ``invalid`` is the index of the invalid
    level (or ``None``)."""

    name: str
    positional: bool
    levels: tuple[tuple[str, ...] | None, ...]
    invalid: int | None


@functools.cache
def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    commands = dict(sub.choices)
    if "fleet" in commands:
        commands["fleet make"] = commands["fleet"]
    return commands


def _name(action: argparse.Action) -> str:
    if not action.option_strings:
        return action.dest
    return next((s for s in action.option_strings if s.startswith("--")), action.option_strings[0])


def _values(command: str, action: argparse.Action) -> tuple[tuple[str, ...], str | None]:
    """(valid values, invalid value) of an option: the table's, else by the option's kind."""
    name = _name(action)
    given = COMMAND_VALUES.get(command, {}).get(name, VALUES.get(name))
    if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
        return ((),), None  # present (an empty value) or left out
    if given is not None:
        *valid, invalid = given
        valid = [v for v in valid if v != ()]
        return tuple((v,) for v in valid), invalid
    if action.choices:
        return ((str(list(action.choices)[-1]),),), "no-such-choice"
    kind = getattr(action.type, "__name__", "")
    if kind in ("int", "integer"):
        return (("1",),), "-1"
    if kind in ("float", "number"):
        return (("1",),), "nan"
    return (), ""


@functools.cache
def factors(command: str) -> tuple[Factor, ...]:
    """The factors of ``command``, from its parser (the fixed positionals of FIXED excluded)."""
    parser = _subparsers()[command]
    fixed_positionals = bool(FIXED.get(command, ([], []))[0])
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._VersionAction):
            continue
        positional = not action.option_strings
        if positional and fixed_positionals:
            continue
        name = _name(action)
        valid, invalid = _values(command, action)
        fragments = [v if positional else (name, *v) for v in valid]
        optional = not action.required and not (positional and action.nargs in (None, "+"))
        levels: list[tuple[str, ...] | None] = [None] if optional else []
        levels += fragments
        bad = None
        if invalid is not None:
            bad = len(levels)
            levels.append((invalid,) if positional else (name, invalid))
        if not levels:
            levels = [None]
        out.append(Factor(name, positional, tuple(levels), bad))
    return tuple(out)


def rows(command: str, phase: str) -> list[tuple[int, ...]]:
    fs = factors(command)
    if phase == "valid":
        counts = [len(f.levels) - (f.invalid is not None) for f in fs]
        if min(counts, default=1) == 0:  # a required argument without a known valid value
            return []
        costly = [(k, a) for k, f in enumerate(fs) for a in range(counts[k]) if _costly(f, a)]
        out = all_pairs(counts, lambda i, a, j, b: (i, a) not in costly and (j, b) not in costly)
        lone = [tuple(a if m == k else 0 for m in range(len(fs))) for k, a in costly]
        return out + [r for r in lone if r not in out]
    bad = [
        r
        for r in all_pairs(
            [len(f.levels) for f in fs],
            lambda i, a, j, b: a == fs[i].invalid or b == fs[j].invalid,
        )
    ]
    return [r for r in bad if any(level == f.invalid for f, level in zip(fs, r, strict=True))]


def _costly(f: Factor, level: int) -> bool:
    fragment = f.levels[level]
    if fragment is None or f.positional:
        return False
    value = fragment[1] if len(fragment) > 1 else None
    return (f.name, value) in COSTLY or (f.name, None) in COSTLY


def argv(command: str, row: tuple[int, ...]) -> list[str]:
    fs = factors(command)
    positionals, first = FIXED.get(command, ([], []))
    args = [*command.split()[:1], *positionals]
    options: list[str] = []
    for f, level in zip(fs, row, strict=True):
        fragment = f.levels[level]
        if fragment is None:
            continue
        (args if f.positional else options).extend(fragment)
    return [*args, *first, *options]


#: commands whose valid rows identify models end to end (a fit, a structure search) with every
#: option combination: the long tier (``-m slow``, the second step of CI); their invalid rows,
#: refused before anything is fitted, stay in the first
SLOW_VALID = ("fit", "select")


def _cases():
    for command in _subparsers():
        for phase in ("valid", "invalid"):
            if phase == "valid" and command in INVALID_ONLY:
                continue
            slow = phase == "valid" and command in SLOW_VALID
            for k, row in enumerate(rows(command, phase)):
                yield pytest.param(
                    command,
                    phase,
                    row,
                    id=f"{command.replace(' ', '-')}-{phase}-{k}",
                    marks=(pytest.mark.slow,) if slow else (),
                )


# ---- the files the values name -----------------------------------------------------------------


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    """The data (a tiny building, with an energy meter in kWh as P_ele), the fit documents, a
    fleet of two buildings and its configuration, made once."""
    from jaxbox.datasets import make_fleet

    root = tmp_path_factory.mktemp("matrix")
    f = frame(N)
    f["P_ele"] = 1000.0 + np.cumsum(np.full(N, 0.3))  # a meter: kWh since it was installed
    f.to_csv(root / "data.csv", index=False)
    for name, method in (("fit.json", "oe"), ("ml.json", "ml")):
        code, out, err = run(
            ["fit", str(root / "data.csv"), "--model", "Zon", "--method", method, "--json"]
            + FIXED["fit"][1]
        )
        assert code == 0, err
        (root / name).write_text(out)
    make_fleet(2, root / "fleet", model="Zon", days=2, seed=0)
    (root / "fleet.toml").write_text(
        '[identify]\nmodels = "Zon"\nstarts = 1\nmax_steps = 2\n[run]\npartition_size = 1\n'
    )
    (root / "a_file").write_text("a file, not a folder")
    return {
        "csv": str(root / "data.csv"),
        "missing": str(root / "no_such_file"),
        "file": str(root / "a_file"),
        "params_ml": str(root / "ml.json"),
        "params_fit": str(root / "fit.json"),
        "fleet": str(root / "fleet"),
        "config": str(root / "fleet.toml"),
    }


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def run(argv: list[str]) -> tuple[int, str, str]:
    """``jaxbox ARGV`` in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("command, phase, row", list(_cases()))
def test_option_pairs(command, phase, row, files, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    here = tmp_path / "run"
    here.mkdir()
    places = {**files, "out": str(here / "out"), "here": str(here)}
    args = [a.format(**places) for a in argv(command, row)]
    code, out, err = run(args)
    lines = err.strip().splitlines()
    shown = f"jaxbox {' '.join(args)}\n-> exit {code}\n{err}"
    assert "Traceback" not in err and "internal error" not in err, shown
    assert code in (0, 1, 2), shown
    errors = [line for line in lines if line.startswith("error: ")]
    if code == 2:
        assert len(errors) == 1 and lines[-1] == errors[0], shown
        assert out == "", shown
        assert _tree(here) == set(), shown  # nothing written, no folder made
    else:
        assert errors == [], shown
    if code == 1:
        assert lines and lines[-1].startswith("no valid model"), shown
    invalid = [f.name for f, level in zip(factors(command), row, strict=True) if level == f.invalid]
    if phase == "invalid":
        assert invalid and code == 2, f"invalid {invalid} accepted\n{shown}"


# ---- the generator and the matrix themselves ----------------------------------------------------


@pytest.mark.parametrize("levels", [[2, 2, 2], [3, 2, 4, 2, 2], [1, 3], [4], [3] * 12])
def test_all_pairs_covers_every_pair(levels):
    import itertools

    got = all_pairs(levels)
    covered = set().union(*(pairs_of(r) for r in got))
    every = {
        (i, a, j, b)
        for i, j in itertools.combinations(range(len(levels)), 2)
        for a in range(levels[i])
        for b in range(levels[j])
    }
    assert every <= covered
    assert all(0 <= x < levels[k] for r in got for k, x in enumerate(r))
    assert len(got) <= int(np.prod(levels))
    if len(levels) > 2:
        assert len(got) < int(np.prod(levels))


def test_all_pairs_covers_only_what_is_wanted_and_is_the_same_every_time():
    levels = [3] * 10
    wanted = lambda i, a, j, b: a == 2 or b == 2  # noqa: E731
    got = all_pairs(levels, wanted)
    covered = set().union(*(pairs_of(r) for r in got))
    assert all(p in covered for p in pairs_of((2,) * 10))
    assert all((i, 2, j, b) in covered for i in range(10) for j in range(i + 1, 10) for b in (0, 1))
    assert got == all_pairs(levels, wanted)
    assert len(got) < 3**10 // 100


def test_every_command_and_option_is_in_the_matrix():
    """A command added to the parser is in the matrix with every option it declares, and
    every level of every option is in some row."""
    commands = {c.values[0] for c in _cases()}
    assert commands == set(_subparsers())
    for command, parser in _subparsers().items():
        fs = factors(command)
        fixed = bool(FIXED.get(command, ([], []))[0])
        declared = {
            _name(a)
            for a in parser._actions
            if not isinstance(a, argparse._HelpAction | argparse._VersionAction)
            and not (fixed and not a.option_strings)
        }
        assert {f.name for f in fs} == declared
        phases = ("invalid",) if command in INVALID_ONLY else ("valid", "invalid")
        used = {(k, r[k]) for phase in phases for r in rows(command, phase) for k in range(len(fs))}
        for k, f in enumerate(fs):
            levels = range(len(f.levels))
            if command in INVALID_ONLY:
                levels = [f.invalid] if f.invalid is not None else []
            assert all((k, level) in used for level in levels), (command, f.name)
