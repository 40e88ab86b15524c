"""``write(path, cells)``: the one notebook writer of the tools/ scripts."""

from pathlib import Path

import nbformat as nbf
from nbformat.v4 import new_notebook

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"


def write(path, cells):
    """Write ``cells`` as ``notebooks/<name of path>`` (not executed: the tests run it)."""
    path = NOTEBOOKS / Path(path).name
    nb = new_notebook(
        cells=cells,
        metadata={
            "kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
            "language_info": {"name": "python"},
        },
    )
    nbf.write(nb, path)
