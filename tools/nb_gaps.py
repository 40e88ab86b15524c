"""Write notebooks/gaps.ipynb: fitting monitoring data with gaps (run from anywhere)."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/gaps.ipynb",
    [
        md(
            "# Data with gaps: masked outputs, interpolated inputs, segments\n\n"
            "Real monitoring data have holes. Here the bundled twin house N2 gets three of them "
            "in its identification window: the zone temperature missing for six hours (an output "
            "gap), the outdoor temperature missing for one hour (a short input gap) and every "
            "signal missing for a day (a long gap, as when a logger stops)."
        ),
        code(
            "import warnings\n\nimport numpy as np\n\nimport jaxbox\n\njaxbox.enable_x64()\n\n"
            "from jaxbox.data import Dataset\nfrom jaxbox.datasets import twinhouse_exp1\n"
            "from jaxbox.validate import plot_fit, uncertainty, validate\n\n"
            'frame = twinhouse_exp1("N2").frame\n'
            'frame.loc["2013-08-25 06:00":"2013-08-25 11:00", "T_zon"] = np.nan  # output gap\n'
            'frame.loc["2013-08-27 03:00", "T_amb"] = np.nan  # one hour of one input\n'
            'frame = frame.drop(frame.loc["2013-09-02 00:00":"2013-09-02 23:00"].index)  # a day\n'
            "data = Dataset(frame)  # the missing day comes back as rows of NaN\n"
            'print(len(data), "samples;", int(np.isnan(data["T_zon"]).sum()), "without T_zon")'
        ),
        md(
            "The identification window is the first half, the validation window the rest "
            "(`Dataset.windows`, the same rule as `--train`/`--validate`). The fit prepares its "
            "window: the output gap is masked (weight 0), the one-hour input gap is interpolated "
            "with a warning naming it, and the day-long gap splits the window into two segments. "
            "The segments share the parameters; each has its own initial states (`T_zon0_s2`, "
            "`T_wal0_s2` for the second)."
        ),
        code(
            "ident, valid = data.windows()\n"
            "with warnings.catch_warnings(record=True) as caught:\n"
            '    warnings.simplefilter("always")\n'
            '    result = jaxbox.fit_model("ZonWal", ident, starts=4, seed=0)\n'
            "for w in caught:\n"
            "    print(w.message)\n"
            'print("segments:", result.data.segments)\n'
            "print(result.summary())\n"
            'assert result.model.segments == 2 and "T_zon0_s2" in result.params'
        ),
        md(
            "Validation simulates segment by segment (each from its estimated initial states) "
            "and runs on over the validation window; the RMSE and the residual tests leave the "
            "missing samples out. The intervals count only the measured samples."
        ),
        code(
            "v = validate(result, valid)\n"
            'print(f"RMSE identification {v.se_auto:.3f} K, validation {v.se_cross:.3f} K")\n'
            'lb = v.residual_analysis("auto").outputs[0].ljung_box\n'
            'print(f"Ljung–Box, masked residuals: Q = {lb.statistic:.0f}, "\n'
            '      f"p = {lb.p_value:.2g}")\n'
            "print(uncertainty(result).summary())\n"
            "assert v.se_cross < 2.0"
        ),
        code("fig = plot_fit(v)"),
        md(
            "On the command line the same happens with `--max-gap` (default `1h`), and "
            "`--validate none` fits the whole file:\n\n"
            "```bash\n"
            "jaxbox fit house.csv --model ZonWal --max-gap 2h\n"
            "jaxbox fit house.csv --model ZonWal --validate none\n"
            "```"
        ),
    ],
)
