"""Write notebooks/design.ipynb: plan an identification experiment, compare it with a PRBS, and
check the predicted parameter spread against repeated fits."""

from _notebook import write
from nbformat.v4 import new_code_cell as code
from nbformat.v4 import new_markdown_cell as md

write(
    "notebooks/design.ipynb",
    [
        md(
            "# Experiment design: a shorter identification experiment\n\n"
            "`jaxbox.design.plan` finds the heating schedule that minimises the predicted "
            "variance of the heat-loss coefficient (HLC) of `ZonWal`, within 0–3 kW and a "
            "comfort band of 15–35 °C, by differentiating the Fisher information through the "
            "simulator. The prior parameters are those fitted on the bundled twin house N2 "
            "(`jaxbox fit twinhouse_exp1:N2 --model ZonWal --json > fit.json` gives them; "
            "`plan('ZonWal', 'fit.json')` reads such a file). Noise σ = 0.05 K, four days, hourly, "
            "the bundled weather."
        ),
        code(
            "import matplotlib.pyplot as plt\nimport numpy as np\n\nimport jaxbox\n\n"
            "jaxbox.enable_x64()\nfrom jaxbox import design\n\n"
            'prior = {"C_zon": 2.615e7, "C_wal": 3.115e8, "R_wal": 7.129e-3, "gA": 1.79}\n'
            'd = design.plan("ZonWal", prior, sigma=0.05, days=4, power=(0, 3000), '
            'comfort=(15, 35), criterion="hlc")\nprint(d.summary())'
        ),
        md(
            "The designed schedule against the PRBS of the same length and energy (its clock "
            "period the best of 1, 2, 4, … h for the HLC), with the zone temperature each "
            "predicts."
        ),
        code(
            "fig, (a, b) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)\n"
            'for name, style in (("designed", "-"), ("prbs", "--")):\n'
            "    a.step(d.index, d.schedules[name] / 1000, style, where='post', label=name)\n"
            '    b.plot(d.index, d.reports[name]["outputs"][:, 0], style, label=name)\n'
            'a.set_ylabel("heating [kW]")\nb.set_ylabel("predicted T_zon [°C]")\n'
            "b.axhspan(15, 35, color='g', alpha=0.05)\na.legend()\nfig.autofmt_xdate()"
        ),
        md(
            "**Checked, not only predicted.** Simulate the building with each schedule, add "
            "noise of σ = 0.05 K, fit `ZonWal` to 30 noise realisations of each in one batched "
            "call, and compare the observed spread of the estimates with the predicted standard "
            "deviations."
        ),
        code(
            "ctx = d.context\ntheta = ctx.theta(0)\nmodel = ctx.setup.model\n"
            "rng = np.random.default_rng(0)\nR = 30\nrequests = []\n"
            'for name in ("designed", "prbs"):\n'
            "    signals = {n: ctx.inputs[:, i] for i, n in enumerate(model.inputs)}\n"
            '    signals["Q_hea"] = d.schedules[name]\n'
            "    base = jaxbox.Dataset.from_arrays(ctx.index, signals)\n"
            "    y = jaxbox.simulate_model(model, theta, base).y[:, 0]\n"
            "    for _ in range(R):\n"
            "        noisy = base.with_columns(T_zon=y + rng.normal(0, 0.05, len(y)))\n"
            '        requests.append({"model": model, "data": noisy, "starts": 1, '
            '"guess": theta})\n'
            "results = jaxbox.fit_batch(requests)\n"
            "observed = {}\n"
            'for k, name in enumerate(("designed", "prbs")):\n'
            "    P = np.array([[r.params[p] for p in ctx.setup.free] "
            "for r in results[k * R : (k + 1) * R]])\n"
            "    hlc = 1 / P[:, ctx.setup.free.index('R_wal')]\n"
            "    observed[name] = dict(zip(ctx.setup.free, P.std(axis=0, ddof=1)), "
            "HLC=hlc.std(ddof=1))\n"
            "for name in observed:\n"
            '    print(name, {k: f"{v:.3g}" for k, v in observed[name].items()})'
        ),
        code(
            "fig, ax = plt.subplots(figsize=(6, 6))\n"
            'for name, marker in (("designed", "o"), ("prbs", "s")):\n'
            "    rep = d.reports[name]\n"
            '    pred = {**rep["std"], "HLC": rep["hlc_std"]}\n'
            "    rel_pred = [pred[k] / abs(theta.get(k, rep['hlc']) if k != 'HLC' else rep['hlc']) "
            "for k in pred]\n"
            "    rel_obs = [observed[name][k] / abs(theta.get(k, rep['hlc']) if k != 'HLC' else "
            "rep['hlc']) for k in pred]\n"
            "    ax.loglog(rel_pred, rel_obs, marker, label=name)\n"
            "    for k, x, y in zip(pred, rel_pred, rel_obs):\n"
            "        ax.annotate(k, (x, y), fontsize=7)\n"
            "lim = [min(ax.get_xlim()[0], ax.get_ylim()[0]), max(ax.get_xlim()[1], "
            "ax.get_ylim()[1])]\n"
            "ax.plot(lim, lim, 'k:', lw=1)\n"
            'ax.set_xlabel("predicted relative std")\nax.set_ylabel("observed relative std '
            '(30 fits)")\nax.legend()'
        ),
        md(
            "The points sit on the diagonal within the sampling error of 30 realisations "
            "(about ±13 %; the envelope capacity, barely identifiable in four days, strays "
            "furthest: the linearisation holds where the estimate is precise). The designed "
            "experiment pins the HLC down better than the PRBS of the same energy, as predicted. "
            "On the command line:\n\n"
            "```\njaxbox design --params fit.json --days 7 --sigma 0.05 --power 0:3000 "
            "--comfort 15:35 --out schedule.csv\n```"
        ),
    ],
)
