"""Write the quick-start and selection notebooks (run from anywhere: paths are repo-relative)."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/quickstart.ipynb",
    [
        md(
            "# Quick start: fit one model, validate it, plot\n\nThe bundled twin house N2 (IEA EBC Annex 58, experiment 1), hourly. The first half identifies the model, the second half validates it."
        ),
        code(
            'import jaxbox\n\njaxbox.enable_x64()  # every computation in float64\n\nfrom jaxbox.datasets import twinhouse_exp1\nfrom jaxbox.validate import check_validity, plot_fit, validate\n\ndata = twinhouse_exp1("N2")\nident, valid = data.split()\ndata'
        ),
        code('fig = data.plot(["T_zon", "T_amb", "Q_hea", "I_glo_hor"])'),
        md(
            "Fit the two-state model `ZonWal` (zone air + envelope) from four starts: the naming-convention guess and three Latin-hypercube samples around it, all in one batched call. Initial temperatures start from the data."
        ),
        code(
            'result = jaxbox.fit_model("ZonWal", ident, starts=4, seed=0)\nprint(result.summary())'
        ),
        md(
            "Post-simulate on the identification data (auto-validation) and on the unseen second half (cross-validation), then judge validity: parameters off their bounds, physical, with reasonable confidence intervals."
        ),
        code(
            'validation = validate(result, valid)\nprint(f"RMSE identification {validation.se_auto:.3f} K, validation {validation.se_cross:.3f} K")\nverdict = check_validity(result)\nprint(verdict.summary())\nassert validation.se_cross < 2.0'
        ),
        code("fig = plot_fit(validation)"),
    ],
)

write(
    "notebooks/selection.ipynb",
    [
        md(
            "# Forward selection on the twin house, with the report\n\nA `GreyBox` holds every identification attempt (`Case`) on one building. Forward selection climbs the experiment-1 hierarchy from the one-state model, each child starting from its parent's optimum, and stops when the validation error no longer improves. To stay short this notebook climbs the first three models; `jaxbox demo` climbs all six."
        ),
        code(
            'import tempfile\nfrom pathlib import Path\n\nimport jaxbox\n\njaxbox.enable_x64()\n\nfrom jaxbox.datasets import twinhouse_exp1\nfrom jaxbox.report import write_report\nfrom jaxbox.select import GreyBox, forward_selection\n\ndata = twinhouse_exp1("N2")\ngb = GreyBox(data, name="twin house N2")  # identification: first half; validation: the rest\ngb'
        ),
        code(
            'selection = forward_selection(\n    gb, ["Zon", "ZonWal", "ZonWalIntInf"], starts=4, seed=0, patience=2, progress=print\n)\nprint(selection.stopped)\nprint("accepted:", selection.accepted)'
        ),
        code(
            'gb.table()[["model", "n_params", "guess", "se_auto", "se_cross", "valid", "reasons"]]'
        ),
        code("fig = gb.plot(accepted=selection.accepted)"),
        md(
            "The accepted model is the valid one with the lowest validation error; it must beat the one-state model."
        ),
        code(
            'best = selection.case\nassert best is not None and best.is_valid\nassert best.se_cross < gb["Zon"].se_cross\nprint(best.result.summary())'
        ),
        md(
            "Save everything (plain JSON + NPZ, written atomically), load it back and write the self-contained HTML report."
        ),
        code(
            'out = Path(tempfile.mkdtemp(prefix="jaxbox-selection-"))\ngb.save(out / "greybox")\nback = GreyBox.load(out / "greybox")\nassert back[best.name].se_cross == best.se_cross\nreport = write_report(back, out / "report.html", selection)\nprint(report, report.stat().st_size // 1024, "KiB")'
        ),
    ],
)
