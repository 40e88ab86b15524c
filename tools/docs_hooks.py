"""MkDocs hooks of the documentation site (``hooks:`` in mkdocs.yml).

- **Examples**: every notebook in ``notebooks/`` becomes a page ``examples/<name>.ipynb``, listed
  under *Examples* in the order of ``EXAMPLES`` (a notebook not named there comes after, by
  name), titled by its first heading. Each is executed when the site is built, in a kernel of its
  own (a fresh temporary working folder; several notebooks side by side), and the build stops
  with the notebook's error when a cell fails. The outputs are not stored in git: an executed copy
  is kept in ``build/docs/notebooks/`` under a key of the notebook, the jaxbox sources and the
  kernel's preamble, so that a rebuild with nothing changed (``mkdocs serve``) executes nothing
  again. The kernels share a persistent JAX compilation cache in ``build/docs/jax`` and compile
  with XLA's backend optimisations off, as the tests do (the notebooks run briefly; compiling
  dominates).
- **Benchmarks**: every ``benchmarks/*.md`` becomes a page as committed (in the order of
  ``BENCHMARK_PAGES``, others by name), and the benchmarks' index gets a table of when and on
  which machine each was measured. The examples' index gets a table of the notebooks.
- **Figures**: jaxbox's plots return a ``matplotlib.figure.Figure`` without pyplot, which a
  notebook shows only as the last expression of a cell. So that every plot appears on the site,
  the kernel displays, after each cell, the figures that the cell bound to a name
  (``fig = plot_fit(v)``) and had not shown.
- **Math**: the equations are typeset by MathJax 3 from the site itself, not from a CDN, so that
  the site reads offline: ``on_files`` adds the ``tex-mml-chtml.js`` bundle and what it loads (its
  fonts, the TeX extensions it autoloads, the menu's accessibility components) from the
  ``django-static-mathjax`` package of the ``docs`` extra, as ``javascripts/mathjax/``.
- **API**: ``api/jaxbox.md`` is written from ``jaxbox.__all__`` (each top-level name linked to
  its definition in a subpackage), and every public name of every subpackage must have a
  docstring: one without is a warning, which ``mkdocs build --strict`` turns into a failure.

Environment: ``JAXBOX_DOCS_NOTEBOOKS=skip`` renders the notebooks without executing them (to
draft the prose; never in CI); ``JAXBOX_DOCS_JOBS=N`` runs N notebooks at once (default: the
number of cores, at most 4); ``JAXBOX_DOCS_TIMEOUT`` is the limit per cell in seconds (600).

Run as a script (``python tools/docs_hooks.py SRC DST``) it executes one notebook: the build
starts one such process per notebook.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
CACHE = ROOT / "build" / "docs"
#: the examples in reading order; other notebooks follow by name
EXAMPLES = (
    "quickstart",
    "validation",
    "selection",
    "search",
    "gaps",
    "stochastic",
    "control",
    "fleet",
    "design",
    "sweeps",
)

BENCHMARKS = ROOT / "benchmarks"
#: the benchmark pages in reading order, with their titles in the nav; other files follow by name
BENCHMARK_PAGES = {
    "RESULTS": "Against CasADi and scipy",
    "PEERS": "Peers on their own data",
    "CONVERGENCE": "Convergence of the starts",
    "ZOO": "Structure search on the zoo",
    "EXHAUSTIVE": "Search against the exhaustive reference",
    "VARIANTS": "Search on twin-house variants",
    "GAPS": "Gaps and segments",
    "STOCHASTIC": "Stochastic models",
    "FORECAST": "Forecast bands",
    "FLEET": "Fleets on Dask",
    "DESIGN": "Experiment design",
    "GPU": "On a GPU",
    "NOTES": "Notes on the numbers",
}

log = logging.getLogger("mkdocs.plugins.jaxbox")

#: where the MathJax files go in the site (``extra_javascript`` in mkdocs.yml names the bundle)
MATHJAX_URI = "javascripts/mathjax"
#: what of MathJax's ``es5/`` the site serves: the combined bundle and what it loads from beside it
MATHJAX_PARTS = (
    "tex-mml-chtml.js",
    "output/chtml/fonts/woff-v2",  # the CommonHTML output's fonts
    "input/tex/extensions",  # TeX packages loaded on first use (\color, \cancel, ...)
    "ui",  # the context menu
    "a11y",  # the menu's accessibility options
    "sre",  # the speech rule engine those load, and its locale files
)

#: run in the kernel before the notebook's first cell (and removed from the page)
_PREAMBLE = """\
def _jaxbox_docs_setup():
    import matplotlib.figure
    from IPython import get_ipython
    from IPython.display import display

    from matplotlib._pylab_helpers import Gcf

    shell = get_ipython()
    shown = {id(v) for v in shell.user_ns.values() if isinstance(v, matplotlib.figure.Figure)}

    def note_pyplot_figures():  # before the inline backend shows and closes them
        shown.update(id(m.canvas.figure) for m in Gcf.get_all_fig_managers())

    shell.events.register("post_execute", note_pyplot_figures)
    shell.run_line_magic("matplotlib", "inline")  # figures display as PNG

    def show_new_figures(result):
        if not result.success:
            return
        for value in list(shell.user_ns.values()):
            if isinstance(value, matplotlib.figure.Figure) and id(value) not in shown:
                shown.add(id(value))
                if result.result is not value:  # the last expression is shown already
                    display(value)

    shell.events.register("post_run_cell", show_new_figures)


_jaxbox_docs_setup()
del _jaxbox_docs_setup
"""


def _title(path: Path) -> str:
    """The notebook's first Markdown heading, else its name."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    for cell in nb.get("cells", []):
        if cell.get("cell_type") == "markdown":
            for line in "".join(cell.get("source", "")).splitlines():
                if line.startswith("#"):
                    return line.lstrip("#").strip()
    return path.stem


def notebooks() -> list[Path]:
    """The notebooks of ``notebooks/``, in reading order."""
    found = {p.stem: p for p in NOTEBOOKS.glob("*.ipynb")}
    order = [name for name in EXAMPLES if name in found]
    order += sorted(set(found) - set(order))
    return [found[name] for name in order]


def _key(path: Path) -> str:
    """A hash of the notebook, the jaxbox sources and the preamble: what its outputs depend on."""
    digest = hashlib.sha256(path.read_bytes())
    for source in sorted((ROOT / "jaxbox").rglob("*")):
        if source.is_file() and source.suffix in (".py", ".csv", ".json", ".gz", ".npz", ".txt"):
            digest.update(str(source.relative_to(ROOT)).encode())
            digest.update(source.read_bytes())
    digest.update(_PREAMBLE.encode())
    return digest.hexdigest()[:16]


def _execute_one(src: Path, dst: Path) -> tuple[Path, float, str]:
    """Execute ``src`` into ``dst`` in a process of its own; returns (dst, seconds, error)."""
    start = time.perf_counter()
    env = {
        **os.environ,
        "JAX_ENABLE_X64": "1",
        "JAX_COMPILATION_CACHE_DIR": str(CACHE / "jax"),
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0.5",
        "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "0",
        "XLA_FLAGS": " ".join(
            [os.environ.get("XLA_FLAGS", ""), "--xla_backend_optimization_level=0"]
        ).strip(),
        "JAXBOX_CACHE": "0",
        "PYTHONWARNINGS": os.environ.get("PYTHONWARNINGS", ""),
    }
    env.pop("MPLBACKEND", None)  # the kernel's inline backend draws the figures
    proc = subprocess.run(
        [sys.executable, __file__, str(src), str(dst)],
        env=env,
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    error = "" if proc.returncode == 0 else (proc.stderr or proc.stdout)[-4000:]
    return dst, time.perf_counter() - start, error


def execute_all(paths: list[Path]) -> dict[str, Path]:
    """Executed copies of ``paths`` (from the cache where nothing changed); raises on a failure."""
    from mkdocs.exceptions import PluginError

    out = CACHE / "notebooks"
    out.mkdir(parents=True, exist_ok=True)
    executed, todo = {}, []
    for path in paths:
        dst = out / f"{path.stem}-{_key(path)}.ipynb"
        executed[path.stem] = dst
        if not dst.exists():
            todo.append((path, dst))
    if not todo:
        return executed
    jobs = int(os.environ.get("JAXBOX_DOCS_JOBS", min(4, os.cpu_count() or 1)))
    log.info(f"executing {len(todo)} notebook(s), {jobs} at a time")
    start = time.perf_counter()
    failures = []
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        for dst, seconds, error in pool.map(lambda job: _execute_one(*job), todo):
            name = dst.name.rsplit("-", 1)[0]
            if error:
                failures.append(f"notebooks/{name}.ipynb failed:\n{error}")
            else:
                log.info(f"notebooks/{name}.ipynb executed in {seconds:.0f} s")
    if failures:
        raise PluginError("\n\n".join(failures))
    log.info(f"notebooks executed in {time.perf_counter() - start:.0f} s")
    return executed


# -- MkDocs events ----------------------------------------------------------------------------


#: what ``on_config`` put in the nav, so that ``on_files`` adds the same pages (a file appearing
#: during a build waits for the next one)
_BUILD: dict = {}


def on_config(config):
    """Fill the *Examples* section of the nav with every notebook, the *API reference* with every
    subpackage and *Benchmarks* with every benchmark file; a page of ``docs/`` that the nav does
    not name joins the *How-to guides*."""
    _BUILD["notebooks"] = notebooks()
    _BUILD["benchmarks"] = benchmarks()
    entries = [{_title(p): f"examples/{p.name}"} for p in _BUILD["notebooks"]]

    def is_notebook(entry) -> bool:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        return str(value).endswith(".ipynb")

    import jaxbox

    api = [{f"jaxbox.{name}": f"api/jaxbox.{name}.md"} for name in jaxbox._SUBPACKAGES]
    listed = set(_nav_pages(config["nav"] or []))
    docs = Path(config["docs_dir"])
    unlisted = sorted(
        p.relative_to(docs).as_posix()
        for p in docs.rglob("*.md")
        if p.relative_to(docs).as_posix() not in listed
    )
    for item in config["nav"] or []:
        if isinstance(item, dict) and "How-to guides" in item and unlisted:
            # a page added to docs/ without a nav entry still gets one
            item["How-to guides"] += [{_heading(docs / page): page} for page in unlisted]
        if isinstance(item, dict) and "Examples" in item:
            intro = [e for e in item["Examples"] if not is_notebook(e)]
            item["Examples"] = [*intro, *entries]
        if isinstance(item, dict) and "API reference" in item:
            item["API reference"] = ["api/jaxbox.md", *api]
        if isinstance(item, dict) and "Benchmarks" in item:
            pages = [{t: f"benchmarks/{p.stem.lower()}.md"} for p, t in _BUILD["benchmarks"]]
            item["Benchmarks"] = ["benchmarks/index.md", *pages]
    return config


def _nav_pages(nav) -> list[str]:
    """Every page named in (a part of) the nav."""
    pages = []
    for entry in nav:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        if isinstance(value, list):
            pages += _nav_pages(value)
        elif isinstance(value, str):
            pages.append(value)
    return pages


@event_priority(100)  # before mkdocs-jupyter's, which wraps the notebook files
def on_files(files, config):
    """Add the notebooks (executed) as pages and the generated API index."""
    from mkdocs.structure.files import File

    paths = _BUILD.get("notebooks") or notebooks()
    if os.environ.get("JAXBOX_DOCS_NOTEBOOKS", "").strip().lower() == "skip":
        log.info("JAXBOX_DOCS_NOTEBOOKS=skip: the examples are not executed")
        sources = {p.stem: p for p in paths}
    else:
        sources = execute_all(paths)
    for path in paths:
        uri = f"examples/{path.name}"
        if files.get_file_from_path(uri) is not None:
            files.remove(files.get_file_from_path(uri))
        page = CACHE / "pages" / uri  # a real file under a folder of its own: mkdocs-jupyter
        page.parent.mkdir(parents=True, exist_ok=True)  # reads it through File.src_dir
        shutil.copyfile(sources[path.stem], page)
        files.append(
            File(uri, str(CACHE / "pages"), config["site_dir"], config["use_directory_urls"])
        )
    for path, _ in _BUILD.get("benchmarks") or benchmarks():
        uri = f"benchmarks/{path.stem.lower()}.md"
        files.append(File.generated(config, uri, content=benchmark_page(path)))
    files.append(File.generated(config, "api/jaxbox.md", content=api_index()))
    for uri, path in mathjax_files():
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    import jaxbox

    for package in jaxbox._SUBPACKAGES:
        content = api_page(package)
        files.append(File.generated(config, f"api/jaxbox.{package}.md", content=content))
    for warning in missing_docstrings():
        log.warning(warning)
    return files


def mathjax_files() -> list[tuple[str, Path]]:
    """``(uri in the site, file)`` of the MathJax files the site serves, from the installed
    ``django-static-mathjax`` (MathJax 3's ``es5/`` build)."""
    import importlib.util

    from mkdocs.exceptions import PluginError

    spec = importlib.util.find_spec("mathjax")
    es5 = Path(spec.origin).parent / "static" / "mathjax" / "es5" if spec and spec.origin else None
    if es5 is None or not (es5 / MATHJAX_PARTS[0]).is_file():
        raise PluginError(
            "MathJax not found: install the docs extra (pip install -e '.[docs]'), which brings "
            "django-static-mathjax"
        )
    found = []
    for part in MATHJAX_PARTS:
        path = es5 / part
        for file in sorted(path.rglob("*")) if path.is_dir() else [path]:
            if file.is_file():
                found.append((f"{MATHJAX_URI}/{file.relative_to(es5).as_posix()}", file))
    return found


def on_page_markdown(markdown, page, config, files):
    """The benchmarks' index gets the table of every benchmark file, with when and where."""
    if page.file.src_uri == "benchmarks/index.md":
        return markdown.replace("<!-- benchmark table -->", benchmark_table())
    if page.file.src_uri == "examples/index.md":
        return markdown.replace("<!-- example table -->", example_table())
    return markdown


def _summary(path: Path) -> str:
    """The first sentences of the notebook's first paragraph of prose (after its heading)."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    for cell in nb.get("cells", []):
        if cell.get("cell_type") != "markdown":
            continue
        text = "".join(cell.get("source", ""))
        paragraphs = [p for p in re.split(r"\n\s*\n", text) if p.strip() and p[0] != "#"]
        if paragraphs:
            prose = re.sub(r"\s+", " ", paragraphs[0]).strip()
            sentence = ""
            for part in re.split(r"(?<=\.)\s", prose):  # sentences, up to a line's worth
                sentence = f"{sentence} {part}".strip()
                if len(sentence) >= 80:
                    break
            sentence = sentence if len(sentence) <= 240 else sentence[:237] + "…"
            if sentence.count("`") % 2:  # cut inside a code span
                sentence = sentence.replace("`", "")
            return sentence.replace("|", "\\|")
    return ""


def example_table() -> str:
    rows = ["| example | what it does |", "|---|---|"]
    for path in _BUILD.get("notebooks") or notebooks():
        rows.append(f"| [{_title(path)}]({path.name}) | {_summary(path)} |")
    return "\n".join(rows)


# -- benchmarks ---------------------------------------------------------------------------------


def benchmarks() -> list[tuple[Path, str]]:
    """``(file, title)`` of every ``benchmarks/*.md``, in reading order."""
    found = {p.stem: p for p in BENCHMARKS.glob("*.md")}
    order = [name for name in BENCHMARK_PAGES if name in found]
    order += sorted(set(found) - set(order))
    return [(found[name], BENCHMARK_PAGES.get(name) or _heading(found[name])) for name in order]


def _heading(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            return line.lstrip("#").strip()
    return path.stem


def benchmark_page(path: Path) -> str:
    """The file as a page: its first heading made the page's title (level 1), the rest as is."""
    lines = path.read_text(encoding="utf-8").splitlines()
    for i, line in enumerate(lines):
        if line.startswith("#"):
            lines[i] = "# " + line.lstrip("#").strip()
            break
    source = f"`benchmarks/{path.name}`"
    return "\n".join([*lines, "", f"*This page is {source} of the repository, as committed.*", ""])


def _committed(path: Path) -> str:
    """The date of the last commit of ``path`` (``YYYY-MM-DD``), or ``""``."""
    try:
        return subprocess.run(
            ["git", "log", "-1", "--format=%cs", "--", str(path)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=20,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _measured(path: Path) -> str:
    """When and where a benchmark file says it was measured (its *Written by* line, and its
    *CPU*/*GPU*/*Machine* line where that one names no machine); the date of its last commit
    where it gives none."""
    lines = [line.replace("`", "") for line in path.read_text(encoding="utf-8").splitlines()]
    written = next((x for x in lines if x.startswith(("Written by", "Generated by"))), "")
    text = re.split(r"[;(,]?\s*\(?raw numbers", written)[0].strip(" .;(")
    if text and not re.search(r"cores|CPU|GPU|x86|arm|Machine", text):
        inline = re.search(r"Machine: [^.;]*(?:\.\d[^.;]*)*", written)
        machine = inline.group(0) if inline else ""
        machine = machine or next((x for x in lines if re.match(r"- (CPU|GPU):|Machine:", x)), "")
        text = f"{text}; {machine.lstrip('- ').split(';')[0]}" if machine else text
    if not re.search(r"\d{4}-\d{2}-\d{2}", text):
        date = _committed(path)
        text = f"{text}; last committed {date}" if text else f"last committed {date}"
    text = re.sub(r"\s+", " ", text).strip(" ;")
    return text if len(text) <= 200 else text[:197] + "…"


def benchmark_table() -> str:
    rows = ["| page | file | measured |", "|---|---|---|"]
    for path, title in _BUILD.get("benchmarks") or benchmarks():
        page = f"{path.stem.lower()}.md"
        measured = _measured(path).replace("|", "\\|")
        rows.append(f"| [{title}]({page}) | `benchmarks/{path.name}` | {measured} |")
    return "\n".join(rows)


# -- API ----------------------------------------------------------------------------------------


def _first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring on one line, Sphinx roles as code, ``|`` escaped."""
    sys.path.insert(0, str(Path(__file__).parent))
    from griffe_jaxbox import plain_roles

    text = " ".join((doc or "").strip().split("\n\n")[0].split())
    return plain_roles(text).replace("|", "\\|")


def api_index() -> str:
    """The page of the top-level names: each linked to where it is defined and documented."""
    import jaxbox

    lines = [
        "# jaxbox",
        "",
        "::: jaxbox",
        "    options:",
        "      members: false",
        "      show_root_heading: false",
        "",
        "## Top-level names",
        "",
        "Loaded on first use; each is defined and documented in a subpackage.",
        "",
        "| name | defined in | summary |",
        "|---|---|---|",
    ]
    names = getattr(jaxbox, "_NAMES", {})
    for name in sorted(names):
        module = names[name]
        target = f"jaxbox.{module}.{name}"
        obj = getattr(jaxbox, name)
        summary = _first_paragraph(obj.__doc__)
        where = "jaxbox" if module.startswith("_") else f"jaxbox.{module}"
        lines.append(f"| [`{name}`][{target}] | `{where}` | {summary} |")
    lines += [
        "",
        "## Subpackages",
        "",
        "| package | |",
        "|---|---|",
    ]
    for package in jaxbox._SUBPACKAGES:
        module = getattr(jaxbox, package)
        summary = _first_paragraph(module.__doc__)
        lines.append(f"| [`jaxbox.{package}`](jaxbox.{package}.md) | {summary} |")
    lines += ["", "## Precision and the compilation cache", ""]
    for target in ("_x64.enable_x64", "_x64.PrecisionError", "_cache.enable_compilation_cache"):
        lines += [f"::: jaxbox.{target}", "    options:", "      heading_level: 3", ""]
    return "\n".join(lines)


def api_page(package: str) -> str:
    """The reference page of one subpackage: its docstring, then every public name."""
    import importlib

    module = importlib.import_module(f"jaxbox.{package}")
    lines = [f"# jaxbox.{package}", "", f"::: jaxbox.{package}", "    options:"]
    lines += ["      show_root_heading: false", "      members:"]
    lines += [f"        - {name}" for name in public_names(module)]
    return "\n".join(lines) + "\n"


def public_names(module) -> list[str]:
    """The public names of a package: ``__all__``, else the names not starting with ``_``."""
    import types

    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in vars(module) if not n.startswith("_")]
    return [
        n
        for n in names
        if not isinstance(getattr(module, n, None), types.ModuleType) and n != "annotations"
    ]


def missing_docstrings() -> list[str]:
    """A line for every public name of a jaxbox subpackage that has no docstring (griffe's view:
    a constant's ``#:`` comment counts)."""
    import importlib

    import griffe

    import jaxbox

    sys.path.insert(0, str(Path(__file__).parent))
    from griffe_jaxbox import JaxboxDocstrings

    package = griffe.load(
        "jaxbox",
        search_paths=[str(ROOT)],
        resolve_aliases=True,
        extensions=griffe.load_extensions(JaxboxDocstrings()),
    )
    missing = []
    for sub in jaxbox._SUBPACKAGES:
        module = package[sub]
        if not module.docstring:
            missing.append(f"jaxbox.{sub}: no module docstring")
        for name in public_names(importlib.import_module(f"jaxbox.{sub}")):
            member = module.members.get(name)
            if member is None:
                missing.append(f"jaxbox.{sub}.{name}: not found by griffe")
                continue
            try:
                target = member.final_target if member.is_alias else member
            except Exception:  # an alias to outside jaxbox
                continue
            if not target.docstring:
                missing.append(f"jaxbox.{sub}.{name}: no docstring")
    return missing


# -- one notebook, in a process of its own -----------------------------------------------------


def _run(src: Path, dst: Path) -> None:
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(src, as_version=4)
    nb.cells.insert(0, nbformat.v4.new_code_cell(_PREAMBLE))
    timeout = int(os.environ.get("JAXBOX_DOCS_TIMEOUT", "600"))
    with tempfile.TemporaryDirectory(prefix=f"jaxbox-docs-{src.stem}-") as work:
        client = NotebookClient(
            nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": work}}
        )
        client.execute()
    nb.cells.pop(0)
    for cell in nb.cells:  # number the cells as if the preamble had not run
        if cell.cell_type == "code" and cell.get("execution_count"):
            cell.execution_count -= 1
            for output in cell.get("outputs", []):
                if output.get("execution_count"):
                    output["execution_count"] -= 1
    tmp = dst.with_suffix(".partial")
    nbformat.write(nb, tmp)
    tmp.replace(dst)


if __name__ == "__main__":
    _run(Path(sys.argv[1]), Path(sys.argv[2]))
