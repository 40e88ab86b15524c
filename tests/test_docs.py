"""The documentation: the README as a landing page, the site's configuration and its helpers.

The site itself is built by CI after the tests (``.ci/run``: ``mkdocs build --strict`` with every
notebook executed, then screenshots); these checks are cheap and need no build. Those that need
the ``docs`` extra (mkdocs, griffe) are skipped without it.
"""

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
TOOLS = ROOT / "tools"
DOCS = {"docs_dir": str(ROOT / "docs")}


def _readme() -> str:
    return README.read_text(encoding="utf-8")


def test_readme_is_a_landing_page():
    text = _readme()
    assert len(text.splitlines()) <= 150
    python = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(python) == 1 and len(python[0].splitlines()) <= 15
    cli = re.search(r"## Command line\n\n```bash\n(.*?)```", text, flags=re.S)
    assert cli and len(cli.group(1).splitlines()) <= 5
    assert "](docs/assets/fit-n2.png)" in text and (ROOT / "docs/assets/fit-n2.png").exists()
    assert "mkdocs serve" in text


def test_readme_set_up_commands_are_those_ci_runs():
    blocks = re.findall(r"```bash\n(.*?)```", _readme(), flags=re.S)
    commands = [line for block in blocks for line in block.splitlines()]
    assert (
        "python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/jaxbox demo"
        in commands
    )
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    tests = next(line for line in ci if "pytest" in line)
    assert tests in commands, "the README's test command is not the one .ci/run runs"


def test_readme_links_into_the_site_exist():
    links = re.findall(r"\]\(((?:docs)/[^)#]+)", _readme())
    assert links, "the README links into docs/"
    missing = [link for link in links if not (ROOT / link).exists()]
    assert not missing, missing


def test_readme_keeps_the_data_credits():
    text = _readme()
    assert "## Data credits" in text and "LICENSE_IDEAS.txt" in text
    assert (ROOT / "jaxbox" / "datasets" / "LICENSE_IDEAS.txt").exists()


def test_nav_files_exist():
    """Every page named in mkdocs.yml exists (a missing one fails ``mkdocs build --strict``)."""
    pages = re.findall(
        r":\s*([\w./-]+\.md)\s*$|^\s*-\s*([\w./-]+\.md)\s*(?:#.*)?$",
        (ROOT / "mkdocs.yml").read_text(encoding="utf-8"),
        flags=re.M,
    )
    names = [a or b for a, b in pages]
    assert "index.md" in names
    generated = {"api/jaxbox.md"}  # written by tools/docs_hooks.py
    missing = [n for n in names if n not in generated and not (ROOT / "docs" / n).exists()]
    assert not missing, missing


@pytest.fixture
def hooks(monkeypatch):
    pytest.importorskip("mkdocs")
    monkeypatch.syspath_prepend(str(TOOLS))
    import docs_hooks

    return docs_hooks


def test_every_notebook_is_an_example_page(hooks):
    config = {"nav": [{"Home": "index.md"}, {"Examples": ["examples/index.md"]}], **DOCS}
    hooks.on_config(config)
    pages = [next(iter(e.values())) for e in config["nav"][1]["Examples"] if isinstance(e, dict)]
    notebooks = sorted(p.name for p in (ROOT / "notebooks").glob("*.ipynb"))
    assert sorted(Path(p).name for p in pages) == notebooks
    assert config["nav"][1]["Examples"][0] == "examples/index.md"


def test_every_subpackage_has_an_api_page(hooks):
    import jaxbox

    config = {"nav": [{"API reference": ["api/jaxbox.md"]}], **DOCS}
    hooks.on_config(config)
    pages = config["nav"][0]["API reference"]
    assert pages[0] == "api/jaxbox.md"
    assert [next(iter(p.values())) for p in pages[1:]] == [
        f"api/jaxbox.{name}.md" for name in jaxbox._SUBPACKAGES
    ]
    page = hooks.api_page("fit")
    assert "::: jaxbox.fit" in page and "        - fit_model" in page


def test_a_page_missing_from_the_nav_joins_the_how_to_guides(hooks, tmp_path):
    (tmp_path / "index.md").write_text("# Home\n")
    (tmp_path / "extra.md").write_text("# Extra notes\n")
    config = {"nav": [{"Home": "index.md"}, {"How-to guides": ["a.md"]}], "docs_dir": tmp_path}
    hooks.on_config(config)
    assert config["nav"][1]["How-to guides"] == ["a.md", {"Extra notes": "extra.md"}]


def test_every_public_name_has_a_docstring(hooks):
    pytest.importorskip("griffe")
    assert hooks.missing_docstrings() == []


def test_docstring_extension():
    pytest.importorskip("griffe")
    sys.path.insert(0, str(TOOLS))
    try:
        from griffe_jaxbox import comment_docstring, escape_adjacent_brackets, plain_roles
    finally:
        sys.path.remove(str(TOOLS))
    lines = ["x = 1", "#: the first line", "#: the second", "LIMIT = 5.0", "Y = 2  #: trailing"]
    assert comment_docstring(lines, 4) == "the first line\nthe second"
    assert comment_docstring(lines, 5) == "trailing"
    assert comment_docstring(lines, 1) is None
    assert escape_adjacent_brackets("x0 [S, n] [°C]") == "x0 [S, n] \\[°C]"
    assert escape_adjacent_brackets("``a[0] [1]`` [N] [K]") == "``a[0] [1]`` [N] \\[K]"
    assert escape_adjacent_brackets("[W/K]") == "[W/K]"
    assert plain_roles("see :func:`fit_model` and :class:`~jaxbox.data.Dataset`") == (
        "see `fit_model` and `Dataset`"
    )
    assert plain_roles(":meth:`jaxbox.models.RCModel.segmented`") == (
        "`jaxbox.models.RCModel.segmented`"
    )
