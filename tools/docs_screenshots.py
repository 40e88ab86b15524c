"""Screenshots of the built site, as a reader sees it: the home page, a how-to page and an
executed notebook page, each rendered by headless Chromium from the local ``site/`` folder.

    python tools/docs_screenshots.py [--site site] [--out build/docs/screenshots] [--require]

Each page must render (a PNG that is not blank) and show its pictures: the home page its figure,
the notebook page the plots of its executed cells (``data:image/png`` outputs, checked in the
HTML, and drawn in the screenshot). Without a Chromium (Debian package ``chromium``) the
screenshots are skipped with a note, exit 0, unless ``--require`` is given; the HTML checks run
either way. Exit 1 when a check fails.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: (name, page of the site, what the page must hold)
PAGES = (
    ("home", "index.html", ["assets/fit-n2.png"]),
    ("how-to", "how-to/gaps/index.html", ["segments"]),
    ("notebook", "examples/quickstart/index.html", ["jp-OutputArea"]),
)
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def browser() -> str | None:
    """The first Chromium on PATH, or None."""
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    return None


def check_html(site: Path) -> list[str]:
    """Problems with the built pages (missing page, picture or plot)."""
    problems = []
    for name, page, needles in PAGES:
        path = site / page
        if not path.exists():
            problems.append(f"{name}: {page} was not built")
            continue
        html = path.read_text(encoding="utf-8")
        problems += [f"{name}: {page} lacks {n!r}" for n in needles if n not in html]
    if (site / "index.html").exists() and not (site / "assets" / "fit-n2.png").exists():
        problems.append("home: assets/fit-n2.png is missing from the site")
    notebook = site / "examples" / "quickstart" / "index.html"
    html = notebook.read_text(encoding="utf-8") if notebook.exists() else ""
    plots = len(re.findall(r'<img[^>]*src="data:image/png', html))
    if plots < 2:
        problems.append(f"notebook: quickstart shows {plots} plot(s), expected 2 (not executed?)")
    return problems


def screenshot(chromium: str, url: str, png: Path, height: int = 2200) -> None:
    """One page into ``png`` (1280 px wide), with a fresh profile."""
    with tempfile.TemporaryDirectory(prefix="jaxbox-chromium-") as profile:
        cmd = [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--hide-scrollbars",
            f"--user-data-dir={profile}",
            f"--window-size=1280,{height}",
            "--virtual-time-budget=5000",
            f"--screenshot={png}",
            url,
        ]
        subprocess.run(cmd, check=True, capture_output=True, timeout=120)


def ink(png: Path) -> float:
    """Share of the pixels that are not (near) white: a blank page has none."""
    import matplotlib.image

    image = matplotlib.image.imread(png)[..., :3]
    return float((image.min(axis=-1) < 0.9).mean())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--site", type=Path, default=ROOT / "site")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "docs" / "screenshots")
    parser.add_argument("--require", action="store_true", help="fail without a Chromium")
    args = parser.parse_args(argv)

    problems = check_html(args.site)
    chromium = browser()
    if chromium is None:
        print("docs screenshots: no Chromium on PATH (Debian: apt-get install chromium); skipped")
        if args.require:
            problems.append("no Chromium to take the screenshots")
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        for name, page, _ in PAGES:
            png = args.out / f"{name}.png"
            png.unlink(missing_ok=True)
            try:
                screenshot(chromium, (args.site / page).resolve().as_uri(), png)
            except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as err:
                problems.append(f"{name}: Chromium failed: {err}")
                continue
            if not png.exists():
                problems.append(f"{name}: no screenshot written")
                continue
            share = ink(png)
            print(f"docs screenshots: {png} ({png.stat().st_size // 1024} KiB, ink {share:.1%})")
            if share < 0.02:
                problems.append(f"{name}: the screenshot is blank ({share:.1%} ink)")
    for problem in problems:
        print(f"docs screenshots: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.exit(main())
