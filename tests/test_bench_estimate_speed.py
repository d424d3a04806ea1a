"""``hairdigi bench estimate-speed``: each session in a fresh process, its estimates timed from the image to the record."""
import csv
import json

import pytest

from hairdigi.app.cli import main


@pytest.mark.slow
def test_a_fresh_session_s_estimates_are_tabled_first_and_later(tmp_path, capsys):
    assert main(["bench", "estimate-speed", "--quick", "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "estimate_speed.csv")))
    summary = json.loads((tmp_path / "estimate_speed.json").read_text())["summary"]
    assert [(r["hair"], r["structure"], r["capture"], r["first"]) for r in rows] == [
        ("copper (the demo)", "layered", "1", "True"), ("copper (the demo)", "layered", "2", "False")]
    assert all(float(r["estimate_s"]) > 0 and int(r["check_renders"]) >= 1 for r in rows)
    assert (summary["first"]["n"], summary["later"]["n"], summary["goal_s"]) == (1, 1, 3.0)
    assert summary["first"]["median"] == pytest.approx(float(rows[0]["estimate_s"]), abs=0.01)
    assert (tmp_path / "estimate_speed.png").stat().st_size > 0
    assert "the first estimate of a fresh session: median" in capsys.readouterr().out
