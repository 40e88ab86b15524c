"""Write notebooks/fleet.ipynb: rank a small synthetic fleet by its heat-loss coefficient."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/fleet.ipynb",
    [
        md(
            "# A fleet: rank buildings by heat-loss coefficient, with error bars\n\n"
            "Twelve synthetic buildings (`jaxbox.datasets.make_fleet`: the two-state model "
            "ZonWal with random plausible parameters, driven by two weeks of the bundled "
            "twin-house weather, with 0.1 K noise) whose true HLC is known. `jaxbox.fleet` "
            "fits each one, validates it and computes its KPIs with 95 % intervals (delta "
            "method from the parameter covariance). On the command line the same run is "
            "`jaxbox fleet DIR --out OUT --model ZonWal`, on a Dask cluster."
        ),
        code(
            "import tempfile\n"
            "from pathlib import Path\n\n"
            "import matplotlib.pyplot as plt\n"
            "import numpy as np\n\n"
            "import jaxbox\n"
            "from jaxbox.datasets import make_fleet\n"
            "from jaxbox.fleet import load_config, read_results, run_fleet\n\n"
            "jaxbox.enable_x64()\n"
            "work = Path(tempfile.mkdtemp())\n"
            "_, truth = make_fleet(12, work / 'fleet', days=14, seed=3)\n"
            "truth[['hlc', 'solar_aperture', 'tau1', 'tau2']].round(2)"
        ),
        md(
            "Fit ZonWal to every building (8 starts; halves for identification and "
            "validation). `workers=0` runs in this process; leave it out to start a local "
            "Dask cluster with one worker per core, or pass `scheduler='tcp://HOST:PORT'`."
        ),
        code(
            "config = load_config(models='ZonWal', starts=8, partition_size=6)\n"
            "summary = run_fleet(work / 'fleet', work / 'out', config, workers=0, progress=False)\n"
            "print(summary.counts, f'{summary.elapsed_s:.1f} s')\n"
            "rows = read_results(work / 'out').set_index('building')\n"
            "rows[['status', 'hlc', 'hlc_lo', 'hlc_hi', 'rmse_cross']].round(2)"
        ),
        md("Ranked by estimated HLC, with the 95 % intervals and the true values."),
        code(
            "ranked = rows.sort_values('hlc')\n"
            "y = np.arange(len(ranked))\n"
            "fig, ax = plt.subplots(figsize=(7, 5))\n"
            "err = [ranked['hlc'] - ranked['hlc_lo'], ranked['hlc_hi'] - ranked['hlc']]\n"
            "ax.errorbar(ranked['hlc'], y, xerr=err, fmt='o', capsize=4, label='estimate, 95 %')\n"
            "ax.plot(truth.loc[ranked.index, 'hlc'], y, 'x', color='k', label='true')\n"
            "ax.set_yticks(y, ranked.index)\n"
            "ax.set_xlabel('heat-loss coefficient [W/K]')\n"
            "ax.legend()\n"
            "ax.grid(alpha=0.3)\n"
            "inside = (ranked['hlc_lo'] <= truth.loc[ranked.index, 'hlc']) & "
            "(truth.loc[ranked.index, 'hlc'] <= ranked['hlc_hi'])\n"
            "print(f'{inside.sum()} of {len(ranked)} intervals hold the true HLC')"
        ),
        md(
            "Every row also holds the parameters with their intervals, the time constants "
            "and the solar aperture, the verdict and the timings; `OUT/fits/<building>.json` "
            "holds each building's full fit document."
        ),
        code(
            "first = rows.iloc[0]\n"
            "print(first[['model', 'solar_aperture', 'solar_aperture_lo', 'solar_aperture_hi']])\n"
            "print('time constants [h]:', np.round(first['tau_h'], 2))\n"
            "[(p['name'], p['value'], p['std']) for p in first['params'] if p['free']]"
        ),
    ],
)
