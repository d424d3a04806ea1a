"""Hair-dye development: the deposit + lift model, its fit, prediction, dose, card and CLI.

Records are written as ``hairdigi estimate`` writes them (refinement ``sigma_a`` set), with exact
``sigma_a`` where a test checks the algebra; the rig's response curve is rendered for real (small,
fixed seed, once per test session in the private cache).
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from hairdigi.inference import dye as D
from hairdigi.inference.levels import EVALUATION_LEVELS, LEVELS, natural_base
from hairdigi.inference.refine import fibre_appearance
from hairdigi.render.domain.absorption import dye_sigma_a, hair_sigma_a
from hairdigi.render.domain.dye_record import DyeRecord
from hairdigi.render.domain.estimate_parts import Provenance
from hairdigi.render.domain.params import load_params
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, read_record, write_record

DEPOSIT = dye_sigma_a((190.0, 70.0, 40.0), 0.55)   # a copper dye's absorption
LIFT = 0.35


@pytest.fixture(scope="module")
def curve():
    return D.rig_curve()


def _record(sigma, level: int, calibration: str | None = None) -> EstimateRecord:
    """An estimate record whose refinement found ``sigma`` (the Table 1 hair: the natural level's)."""
    provenance = Provenance(calibration={"id": calibration} if calibration else None)
    return EstimateRecord(hair=natural_base(level), refinement=RefinementRecord(ran=True, sigma_a=tuple(map(float, sigma))),
                          provenance=provenance)


def _pair(level: int, lift: float = LIFT, deposit=DEPOSIT, tmp=None, calibration=None):
    m = hair_sigma_a(natural_base(level))
    base, dyed = _record(m, level, calibration), _record((1 - lift) * m + deposit, level, calibration)
    if tmp is None:
        return D.sample_of(base, f"base{level}", f"b{level}"), D.sample_of(dyed, f"dyed{level}", f"d{level}")
    paths = tmp / f"base{level}.json", tmp / f"dyed{level}-{lift}.json"
    write_record(paths[0], base)
    write_record(paths[1], dyed)
    return paths


def _cli(*args, cwd=None):
    env = dict(os.environ, OMP_WAIT_POLICY="PASSIVE")
    return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "dye", *map(str, args)], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=600)


def test_characterise_then_apply_returns_the_truth_on_exact_sigma(curve):
    dye = D.characterise([_pair(8), _pair(5)], "copper", curve)
    assert dye.lift_measured and dye.lift == pytest.approx(LIFT, abs=1e-6)
    assert np.allclose(dye.deposit_sigma_a, DEPOSIT, atol=1e-6)
    assert dye.residual_de2000_max < 1e-3
    held_out = D.sample_of(_record(hair_sigma_a(natural_base(3)), 3), "base3", "b3")
    pred = D.apply(dye, held_out, 1.0, curve)
    truth = (1 - LIFT) * hair_sigma_a(natural_base(3)) + DEPOSIT
    assert np.allclose(pred.sigma_a, truth, atol=1e-6)
    # the record has an estimate's layout: sigma_a, and a Table 1 hair block that renders it
    data = pred.record.to_json()
    assert np.allclose(data["refinement"]["sigma_a"], truth, atol=1e-5)
    assert pred.exact and np.allclose(fibre_appearance(hair_sigma_a(pred.params)), fibre_appearance(truth), atol=2e-3)
    # lift is written as the lower melanin it leaves
    assert pred.params.melanin_concentration < natural_base(3).melanin_concentration
    assert EstimateRecord.from_json(json.loads(json.dumps(data))).sigma_a == pytest.approx(tuple(truth), abs=1e-5)


def test_lift_recovered_from_two_bases_with_intervals(curve):
    for lift in (0.0, 0.2, 0.55):
        dye = D.characterise([_pair(8, lift), _pair(3, lift)], "x", curve)
        assert dye.lift == pytest.approx(lift, abs=1e-4)
        assert dye.lift_low <= lift + 1e-4 and dye.lift_high >= lift - 1e-4
        assert dye.lift_high - dye.lift_low < 0.2        # two bases do measure it
        assert not any(w.startswith("one base") for w in dye.warnings)


def test_one_pair_warns_that_lift_is_assumed(curve, tmp_path):
    dye = D.characterise([_pair(6, lift=0.0)], "deposit only", curve)
    assert not dye.lift_measured and dye.lift == 0.0 and dye.lift_low is None
    assert dye.warnings[0].startswith("one base: lift cannot be measured")
    assert np.allclose(dye.deposit_sigma_a, DEPOSIT, atol=1e-6)
    # a dyed hair lighter than its base: the least lift that explains it, said so; never the true lift
    lifted = D.characterise([_pair(6, lift=0.4)], "lifting", curve)
    assert 0.0 < lifted.lift < 0.4 and "least lift" in lifted.warnings[0]
    base, dyed = _pair(6, lift=0.0, tmp=tmp_path)
    run = _cli("characterise", "--pair", base, dyed, "--name", "one", "--out", tmp_path / "one.json")
    assert run.returncode == 0, run.stderr
    assert "warning: one base: lift cannot be measured" in run.stderr
    record = read_record(tmp_path / "one.json", DyeRecord)
    assert record.pairs[0].base_sha256 and record.pairs[0].dyed_sha256 != record.pairs[0].base_sha256


def test_dose_reaches_a_reachable_target(curve):
    dye = D.characterise([_pair(8), _pair(5)], "copper", curve)
    base = D.sample_of(_record(hair_sigma_a(natural_base(6)), 6))
    target = D.colour_of((1 - LIFT) * base.sigma_a + 1.6 * np.asarray(DEPOSIT), curve)
    result = D.dose(dye, base, target, curve)
    assert result.reachable and result.scale == pytest.approx(1.6, abs=0.02) and result.de2000 < 0.1
    assert result.message.startswith("dose 1.60")


def test_unreachable_target_is_said_to_be(curve, tmp_path):
    dye = D.characterise([_pair(8), _pair(5)], "copper", curve)
    base = D.sample_of(_record(hair_sigma_a(natural_base(6)), 6))
    blue, _ = D.target_colour("#2050F0")
    result = D.dose(dye, base, blue, curve)
    assert not result.reachable and result.de2000 > 10 and result.message.startswith("out of reach")
    paths = [_pair(level, tmp=tmp_path) for level in (8, 5)]
    assert _cli("characterise", "--pair", *paths[0], "--pair", *paths[1], "--name", "c",
                "--out", tmp_path / "c.json").returncode == 0
    run = _cli("dose", tmp_path / "c.json", "--base", paths[0][0], "--target", "#2050F0", "--out", tmp_path / "d.json")
    assert run.returncode == 0, run.stderr
    assert "out of reach" in run.stdout
    assert json.loads((tmp_path / "d.json").read_text())["reachable"] is False


def test_bad_pairs_refused_with_one_line(curve, tmp_path):
    # a black base "dyed" to near-platinum: lighter than any lift of at most 95% leaves
    black = _record(hair_sigma_a(natural_base(1)), 1)
    white = _record(hair_sigma_a(natural_base(10)) * 0.3, 10)
    with pytest.raises(D.DyeError, match="cannot be"):
        D.characterise([(D.sample_of(black, "black"), D.sample_of(white, "white"))], "bleach?", curve)
    write_record(tmp_path / "black.json", black)
    write_record(tmp_path / "white.json", white)
    run = _cli("characterise", "--pair", tmp_path / "black.json", tmp_path / "white.json", "--name", "x",
               "--out", tmp_path / "x.json")
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert "cannot be" in run.stderr and not (tmp_path / "x.json").exists()
    # records corrected with different calibrations: refused, unless allowed (then a warning)
    a = _pair(8, tmp=tmp_path / "a", calibration="cal-A")
    b = _pair(5, tmp=tmp_path / "b", calibration="cal-B")
    run = _cli("characterise", "--pair", *a, "--pair", *b, "--name", "x", "--out", tmp_path / "x.json")
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and "calibrations" in run.stderr
    run = _cli("characterise", "--pair", *a, "--pair", *b, "--name", "x", "--out", tmp_path / "x.json",
               "--allow-mixed-calibrations")
    assert run.returncode == 0 and "warning: calibration" in run.stderr
    # a blocked capture (no estimate) and a file that is no record
    (tmp_path / "blocked.result.json").write_text(json.dumps({"capture": "c.png", "blocked": ["no chart in view"]}))
    run = _cli("characterise", "--pair", tmp_path / "blocked.result.json", a[1], "--name", "x", "--out", tmp_path / "y.json")
    assert run.returncode == 2 and "no chart in view" in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_apply_cli_writes_a_prediction_that_render_reads(curve, tmp_path):
    paths = [_pair(level, tmp=tmp_path) for level in (8, 5)]
    assert _cli("characterise", "--pair", *paths[0], "--pair", *paths[1], "--name", "copper",
                "--out", tmp_path / "dye.json").returncode == 0
    base3 = tmp_path / "base3.json"
    write_record(base3, _record(hair_sigma_a(natural_base(3)), 3))
    run = _cli("apply", tmp_path / "dye.json", "--base", base3, "--dose", "0.5", "--out", tmp_path / "pred.json")
    assert run.returncode == 0, run.stderr
    data = json.loads((tmp_path / "pred.json").read_text())
    truth = (1 - LIFT) * hair_sigma_a(natural_base(3)) + 0.5 * DEPOSIT
    assert np.allclose(data["refinement"]["sigma_a"], truth, atol=1e-5)
    assert data["provenance"]["prediction"]["dose"] == 0.5
    load_params(tmp_path / "pred.json")     # hairdigi render --params takes it


def test_dye_record_round_trip_and_errors(curve):
    dye = D.characterise([_pair(8), _pair(3)], "copper", curve)
    again = DyeRecord.from_json(json.loads(json.dumps(dye.to_json())))
    assert again.lift == pytest.approx(dye.lift, abs=1e-6) and len(again.pairs) == 2
    bad = dye.to_json() | {"lift": 1.5}
    with pytest.raises(RecordError, match="lift"):
        DyeRecord.from_json(bad)
    with pytest.raises(RecordError, match="not a dye record"):
        DyeRecord.from_json({"kind": "estimate"})


def test_natural_levels_get_lighter():
    blue = [hair_sigma_a(natural_base(level))[2] for level in LEVELS]
    assert all(a > b for a, b in zip(blue, blue[1:]))
    assert set(EVALUATION_LEVELS.values()) <= set(LEVELS)
    with pytest.raises(ValueError):
        natural_base(11)


def test_shade_card_renders_ten_levels(curve, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from hairdigi.inference import dye_card
    from hairdigi.inference.dye_card import shade_card

    dye = D.characterise([_pair(8, lift=0.0), _pair(3, lift=0.0)], "copper", curve)
    real, drawn = dye_card.draw_card, []    # the real card, its figure kept to look at
    monkeypatch.setattr(dye_card, "draw_card", lambda *a, **kw: drawn.append(real(*a, **kw)) or drawn[-1])
    png, pdf, table, rows = shade_card(dye, tmp_path / "card.png", size=16, spp=2, curve=curve)
    # drawn on no GUI canvas: pyplot never held it (the Dye panel draws it in a worker while Qt runs)
    assert len(drawn) == 1 and plt.get_fignums() == [] and type(drawn[0].canvas).__name__ == "FigureCanvasBase"
    assert png.stat().st_size > 1000 and pdf.read_bytes()[:4] == b"%PDF"
    assert [r["level"] for r in rows] == list(LEVELS)
    # a deposit shows less on black hair than on blonde
    assert rows[0]["de2000"] < rows[8]["de2000"]
    assert all(r["result"]["srgb"].startswith("#") and len(r["result"]["lab"]) == 3 for r in rows)
    # each result under daylight, tungsten and a shop LED, adapted: a copper deposit moves under tungsten
    assert all(list(r["under"]) == ["D65", "A", "shop-led"] and r["under"]["D65"]["de2000_from_daylight"] == 0
               for r in rows)
    assert max(r["under"]["A"]["de2000_from_daylight"] for r in rows) > 1.0
    assert json.loads(table.read_text())["levels"][5]["under"]["A"]["srgb"] == rows[5]["under"]["A"]["srgb"]
    # and as a lab's spectrophotometer reads each dyed swatch: darker levels read darker
    sci = [r["instrument"]["d/8 SCI"][0] for r in rows]
    assert list(rows[0]["instrument"]) == ["d/8 SCI", "d/8 SCE", "45/0"] and sci[0] < sci[4] < sci[9]


def test_a_grey_absorption_looks_the_same_under_every_light_on_the_card(curve):
    from hairdigi.inference.dye_card import under_lights

    grey = under_lights(np.full(3, 0.4), curve)
    assert all(v["de2000_from_daylight"] < 0.5 for v in grey.values())


def test_dye_panel_characterises_session_captures(curve, tmp_path, qtbot):
    """The app's Dye panel: captures of the session listed, two pairs characterised and saved (its model's
    works run in workers: the panel shows what they found when they are done)."""
    from dataclasses import replace

    from hairdigi.app.gui.dye_panel import DyePanel, select_path

    captures = tmp_path / "captures"
    paths = {}
    for level in (8, 5):
        m = hair_sigma_a(natural_base(level))
        for kind, sigma in (("base", m), ("dyed", (1 - LIFT) * m + DEPOSIT)):
            name = f"{kind}{level}"
            paths[name] = captures / f"{name}.result.json"
            write_record(paths[name], replace(_record(sigma, level), capture=f"{name}.png"))
    (captures / "blocked.result.json").write_text(json.dumps({"capture": "b.png", "blocked": ["no chart"]}))
    panel = DyePanel(tmp_path)
    qtbot.addWidget(panel)
    qtbot.waitUntil(lambda: panel.base_combo.count() == 4, timeout=20_000)   # the blocked capture is not offered
    for level in (8, 5):
        assert select_path(panel.base_combo, paths[f"base{level}"]) and select_path(panel.dyed_combo, paths[f"dyed{level}"])
        panel.add_pair()
    assert panel.pair_list.count() == 2
    panel.name_edit.setText("Copper 7/4")
    panel.characterise()
    qtbot.waitUntil(lambda: panel.dye_combo.currentText() == "Copper-7-4", timeout=60_000)
    saved = read_record(tmp_path / "dyes" / "Copper-7-4.json", DyeRecord)
    assert saved.lift == pytest.approx(LIFT, abs=1e-4) and saved.lift_measured
    assert "lift 0.35" in panel.dye_info.text()


def test_evaluation_dyes_are_table1_hair_with_the_model_sigma():
    """The held-out dyed swatches (hidden Table 1 hair, as the simulated rig needs) have exactly the
    model's sigma_a: melanin lifted through the remap, the dye's deposit added."""
    from hairdigi.app.evaluation.dye_evaluation import DyeEvalConfig, draw_dyes, dyed_hair

    config = DyeEvalConfig()
    dyes = draw_dyes(config)
    assert len(dyes) == 12 and all(0 <= d["lift"] <= config.lift_max for d in dyes)
    assert draw_dyes(config)[3]["deposit"].tolist() == dyes[3]["deposit"].tolist()     # fixed seed
    for d in dyes:
        for level in EVALUATION_LEVELS.values():
            base = natural_base(level)
            expected = (1 - d["lift"]) * hair_sigma_a(base) + d["deposit"]
            assert np.allclose(hair_sigma_a(dyed_hair(base, d)), expected, rtol=0, atol=1e-9)
