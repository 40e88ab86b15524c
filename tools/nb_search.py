"""Write notebooks/search.ipynb: a structure search on a zoo building with gaps."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/search.ipynb",
    [
        md(
            "# A structure search on a test building with gaps\n\n"
            "`jaxbox.datasets.make_zoo` draws synthetic buildings whose truth is known: a "
            "structure of the component grammar, plausible parameters, the bundled real weather, "
            "realistic heating, sensor noise and gaps. Here one building of two states (zone air "
            "and envelope) with a boundary to a measured attic temperature, hourly, heated by a "
            "PRBS, with missing readings and an outage of every signal."
        ),
        code(
            "import warnings\n\nimport jaxbox\n\njaxbox.enable_x64()\n"
            "from jaxbox.data import DataWarning\n\n"
            "(b,) = jaxbox.datasets.make_zoo(\n"
            '    1, seed=4, structure="Zon+Wal+Bou", step="60min", heating="prbs", gaps=1.0,\n'
            "    offset=0.0, noise=0.05,\n"
            ")\n"
            'print(b.structure, f"noise {b.noise:.3f} K", "gaps:", b.gaps, "outages:", b.outages)\n'
            "print({k: f'{v:.4g}' for k, v in b.params.items()})"
        ),
        md(
            "The search starts from the simplest structure the columns can drive and, step by "
            "step, fits every one-component extension of the best structure so far in one "
            "batched call. A child must be valid and lower the validation error by 2 %; an "
            "invalid child prunes its branch. The gaps are handled as everywhere in jaxbox: "
            "output gaps masked, short input gaps interpolated, long ones split the data into "
            "segments with their own initial states. Here the search may add at most two "
            "components (`max_depth=2`), to keep the notebook short."
        ),
        code(
            "with warnings.catch_warnings():\n"
            '    warnings.simplefilter("ignore", DataWarning)\n'
            '    gb = jaxbox.GreyBox(b.data, name="zoo building")\n'
            "    search = jaxbox.structure_search(gb, starts=4, max_depth=2, progress=print)"
        ),
        md("The search tree: each structure, what it adds, its validation SE and its fate."),
        code(
            "print(search.tree_text())\n"
            'print("accepted:", search.accepted, "| truth:", b.structure)\n'
            "assert search.case is not None and search.case.is_valid"
        ),
        md(
            "The accepted model against the truth: its heat-loss coefficient, and its "
            "validation error against the noise level."
        ),
        code(
            "from jaxbox.validate import kpi_values, plot_fit\n\n"
            "case = search.case\n"
            "hlc = kpi_values(case.model, case.result.params)['hlc']\n"
            "print(f\"HLC {hlc:.1f} W/K (truth {b.kpis['hlc']:.1f} W/K)\")\n"
            'print(f"validation RMSE {case.se_cross:.3f} K, noise {b.noise:.3f} K")\n'
            "fig = plot_fit(case.validation)"
        ),
    ],
)
