"""Write ``docs/assets/fit-n2.png``, the picture of the README and of the site's home page.

The accepted model of ``jaxbox demo`` (forward selection over the experiment-1 hierarchy on twin
house N2, 8 starts per model) post-simulated on its identification and validation halves, drawn
by the report's own plot (:func:`jaxbox.validate.plot_fit`). Run from anywhere:
``python tools/docs_figure.py`` (about a minute on two cores).
"""

from pathlib import Path

import jaxbox
from jaxbox.datasets import twinhouse_exp1
from jaxbox.validate import plot_fit

OUT = Path(__file__).resolve().parents[1] / "docs" / "assets" / "fit-n2.png"


def main() -> None:
    jaxbox.enable_x64()
    gb = jaxbox.GreyBox(twinhouse_exp1("N2"), name="twin house N2")
    selection = jaxbox.forward_selection(gb, "exp1", starts=8, seed=0)
    case = selection.case
    v = case.validation
    fig = plot_fit(
        v,
        inputs=[n for n in ("T_amb", "Q_hea", "I_glo_hor") if n in v.inputs],
        title=(
            f"Twin house N2, accepted model {case.name}\nRMSE {v.se_auto:.2f} K on "
            f"identification, {v.se_cross:.2f} K on unseen validation data (shaded)"
        ),
    )
    fig.set_size_inches(9, 5.6)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=72)
    print(OUT, OUT.stat().st_size // 1024, "KiB")


if __name__ == "__main__":
    main()
