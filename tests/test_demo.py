"""``jaxbox demo``, the README's first command, run end to end as the README runs it: the
selection over the experiment-1 hierarchy on twin house N2, its table and HLC on stdout, the
report and the selection document in its folder."""

import json

from jaxbox.cli._main import main


def test_the_demo_runs_and_writes_its_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Holzkirchen" in text and "heat-loss coefficient" in text
    assert f"report: {out / 'report.html'}" in text
    doc = json.loads((out / "selection.json").read_text())
    assert doc["dataset"] == "twinhouse_exp1:N2"
    assert doc["accepted"] and doc["accepted"].startswith("ZonWal")
    assert [r["model"] for r in doc["table"]][0] == "Zon"
    hlc = doc["hlc"]
    assert 100 < hlc["value"] < 300 and hlc["ci95"][0] <= hlc["value"] <= hlc["ci95"][1]
    assert (out / "report.html").stat().st_size > 10_000
