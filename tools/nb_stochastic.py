"""Write notebooks/stochastic.ipynb: output error against maximum likelihood on one building."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/stochastic.ipynb",
    [
        md(
            "# Output error or maximum likelihood?\n\n"
            "The same two-state model `BM_TiTe` (zone air + envelope) of twin house N2 "
            "(experiment 1, hourly), estimated twice on the first half of the data:\n\n"
            '* **output error** (`method="oe"`, the default): least squares on the simulated '
            "output, deterministic model;\n"
            '* **maximum likelihood** (`method="ml"`): the stochastic form '
            "`dx = (A x + B u) dt + σ dω`, `y = C x + e`, its likelihood from a Kalman filter; "
            "diffusions `sigma_zon`, `sigma_wal` [K/√s] and the measurement noise `sigma_y_zon` "
            "[K] are estimated with the physical parameters.\n\n"
            "We compare the intervals, the whiteness of the residuals and the k-step-ahead "
            "prediction errors."
        ),
        code(
            "import numpy as np\n"
            "import pandas as pd\n\n"
            "import jaxbox\n\n"
            "jaxbox.enable_x64()\n"
            "from jaxbox.datasets import twinhouse_exp1\n"
            "from jaxbox.validate import analyse_residuals, uncertainty\n\n"
            'ident, valid = twinhouse_exp1("N2").split()\n'
            'oe = jaxbox.fit_model("BM_TiTe", ident, starts=4)\n'
            'ml = jaxbox.fit_model("BM_TiTe", ident, method="ml", starts=4)\n'
            "print(ml.summary())"
        ),
        md(
            "## Intervals\n\nOutput error: `σ²(JᵀJ)⁻¹` from the output sensitivities, which "
            "assumes white residuals. Maximum likelihood: the inverse of the exact Hessian of the "
            "negative log-likelihood (by JAX)."
        ),
        code(
            "unc = uncertainty(oe)\n"
            "oe_sd = dict(zip(unc.names, unc.std))\n"
            "rows = []\n"
            "for n in unc.names:\n"
            "    rows.append({\n"
            '        "parameter": n,\n'
            '        "OE value": oe.params[n],\n'
            '        "OE sd %": 100 * oe_sd[n] / abs(oe.params[n]),\n'
            '        "ML value": ml.params[n],\n'
            '        "ML sd %": 100 * ml.sd[n] / abs(ml.params[n]),\n'
            "    })\n"
            'pd.DataFrame(rows).set_index("parameter").round(3)'
        ),
        md(
            "## Whiteness\n\nOutput-error residuals against the standardised one-step "
            "innovations of the filter: Ljung–Box and cumulated-periodogram p-values."
        ),
        code(
            "oe_sim = jaxbox.simulate_model(oe.model, oe.params, ident)\n"
            'e_oe = ident["T_zon"] - oe_sim.y[:, 0]\n'
            'oe_tests = analyse_residuals(e_oe, output_names=["T_zon"])\n'
            "ml_tests = ml.innovation_tests()\n"
            "pd.DataFrame({\n"
            '    "OE residuals": {"Ljung-Box p": oe_tests["T_zon"].ljung_box.p_value,\n'
            '                     "periodogram p": oe_tests["T_zon"].periodogram.p_value},\n'
            '    "ML innovations": {"Ljung-Box p": ml_tests["T_zon"].ljung_box.p_value,\n'
            '                       "periodogram p": ml_tests["T_zon"].periodogram.p_value},\n'
            "})"
        ),
        md(
            "## k-step-ahead prediction\n\nWhat a model-predictive controller needs: from the "
            "filtered state now, predict k hours ahead with the measured inputs. Output error has "
            "no state estimator; its error is that of the open-loop simulation whatever k."
        ),
        code(
            "ks = ml.k_step_errors((1, 2, 4, 8, 24), data=valid)\n"
            "sim = ml.simulation_rmse(valid)\n"
            "oe_valid = jaxbox.simulate_model(oe.model, oe.params, valid)\n"
            'oe_open = float(np.sqrt(np.mean((valid["T_zon"] - oe_valid.y[:, 0]) ** 2)))\n'
            "pd.DataFrame({\n"
            '    "ML, filtered then k steps": {k: v["rmse"]["T_zon"] for k, v in ks.items()},\n'
            '    "ML, open loop": {k: sim["T_zon"] for k in ks},\n'
            '    "OE, open loop": {k: oe_open for k in ks},\n'
            '}).rename_axis("k [h]").round(3)'
        ),
        md(
            "## Smoothed states\n\nThe envelope temperature is not measured: the smoother "
            "estimates it from the zone temperature, with its uncertainty."
        ),
        code(
            "est = ml.states(valid)\n"
            "frame = est.to_frame()\n"
            'ax = frame[["T_zon_smoothed", "T_wal_smoothed"]].plot(figsize=(9, 3))\n'
            'lo = frame["T_wal_smoothed"] - 2 * frame["T_wal_smoothed_sd"]\n'
            'hi = frame["T_wal_smoothed"] + 2 * frame["T_wal_smoothed_sd"]\n'
            "ax.fill_between(frame.index, lo, hi, alpha=0.3)\n"
            'ax.set_ylabel("°C");'
        ),
        md(
            "The same from the command line:\n\n"
            "```\n"
            "jaxbox fit twinhouse_exp1:N2 --model BM_TiTe --method ml --json > fit.json\n"
            "jaxbox estimate twinhouse_exp1:N2 --model BM_TiTe --params fit.json --out states.csv\n"
            "```"
        ),
    ],
)
