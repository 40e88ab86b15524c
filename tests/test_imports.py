"""No import cycles inside jaxbox, not even through imports inside function bodies."""

import ast
from pathlib import Path

import jaxbox

ROOT = Path(jaxbox.__file__).parent


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package)."""
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        package = parts[-1] == "__init__"
        if package:
            parts = parts[:-1]
        out[".".join(parts)] = (path, package)
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the jaxbox modules it imports anywhere in its body (``from .x import y``
    resolved; ``y`` itself when it is a submodule). Importing a submodule also runs its
    package's ``__init__``, but that is the package's own business, not an edge."""
    modules = _modules()
    graph = {}
    for name, (path, package) in modules.items():
        here = name if package else name.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here.split(".")[: len(here.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    if f"{target}.{alias.name}" in modules:
                        edges.add(f"{target}.{alias.name}")
                    elif target in modules:
                        edges.add(target)
            elif isinstance(node, ast.Import):
                edges |= {a.name for a in node.names if a.name in modules}
        edges.discard(name)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_sees_imports_in_function_bodies():
    graph = import_graph()
    assert "jaxbox.select._persist" in graph["jaxbox.select._greybox"]
    assert "jaxbox.fit" in graph["jaxbox.select._cases"]  # imported inside run_cases
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_the_exact_route_does_not_load_diffrax():
    """diffrax (0.2 s of every process's start) is imported where a model is integrated with
    it, not by importing jaxbox's fit, select and validate modules (the route itself is tested
    in test_simulate)."""
    import subprocess
    import sys

    code = (
        "import sys, jaxbox, jaxbox.fit, jaxbox.select, jaxbox.validate, jaxbox.simulate; "
        "print('diffrax' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_help_and_a_malformed_command_line_load_no_jax():
    """``jaxbox --help``, ``jaxbox select --help`` and a mistyped command line answer at once:
    building the parser reads the fit's defaults from :mod:`jaxbox._defaults` and imports
    neither JAX nor pandas (about 3 s of a process's start), nor does the error of a
    malformed command line."""
    import subprocess
    import sys

    code = (
        "import contextlib, io, sys\n"
        "from jaxbox.cli import main\n"
        "codes = []\n"
        "for argv in (['--help'], ['select', '--help'], ['select'], ['fit', 'x.csv']):\n"
        "    with contextlib.redirect_stdout(io.StringIO()), "
        "contextlib.redirect_stderr(io.StringIO()):\n"
        "        try:\n"
        "            codes.append(main(argv))\n"
        "        except SystemExit as e:\n"
        "            codes.append(e.code)\n"
        "print(codes, sorted(m for m in ('jax', 'pandas', 'scipy') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[0, 0, 2, 2] []"


def test_the_export_formats_of_the_command_line_are_the_library_s():
    from jaxbox.cli._export import _SUFFIX
    from jaxbox.control import FORMATS

    assert tuple(dict.fromkeys(_SUFFIX.values())) == FORMATS
