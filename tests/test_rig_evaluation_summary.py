"""``hairdigi evaluate --rig``'s summary and lines: what the goals are judged by (error, the twin, each estimate's
time, and how often the records' stated intervals held), from rows as the evaluation writes them."""
from __future__ import annotations

import argparse

from hairdigi.app.evaluation import modes
from hairdigi.app.evaluation.rig import summarise
from hairdigi.render.domain.params import HairParams


def _rows() -> list[dict]:
    rows = []
    for i, name in enumerate(("copper", "black", "platinum", "red")):
        for k in range(3):
            rows.append({"hidden": name, "structure": "thin", "source": "live" if k else "raw still", "cast": "1/1/1",
                         "exposure_ev": 0.0, "seconds": 3.0 + k, "de2000": 0.2 * (i + 1) + 0.1 * k,
                         "encoder_de2000": 5.0, "residual_de2000": 0.1 * (k + 1), "twin_de2000": 0.3 * (k + 1),
                         "estimate_seconds": 1.0 + i + 0.5 * k,
                         "stated_p68": 0.5, "stated_p95": 0.75})
    rows.append({"hidden": "red", "structure": "thin", "source": "live", "cast": "1/1/1", "exposure_ev": 0.5,
                 "seconds": 0.4, "blocked": "swatch: over-exposed"})
    return rows


def test_the_summary_times_each_estimate_apart_from_the_capture_and_counts_the_stated_intervals() -> None:
    s = summarise(_rows(), [(n, HairParams()) for n in ("copper", "black", "platinum", "red")])
    assert s["estimated"] == 12 and s["captures"] == 13
    assert s["estimate_seconds"] == {"n": 12, "median": 3.0, "p95": 4.725, "worst": 5.0}
    assert s["seconds"]["median"] == 4.0            # the simulated capture and calibration counted too
    held = s["stated_intervals_held"]
    assert held["p68"] == round(5 / 12, 3) and held["p95"] == round(8 / 12, 3)


def test_the_rig_mode_says_the_twin_each_estimates_time_and_the_stated_intervals(monkeypatch, tmp_path) -> None:
    summary = summarise(_rows(), [(n, HairParams()) for n in ("copper", "black", "platinum", "red")])
    monkeypatch.setattr(modes, "evaluate_rig", lambda out, config: summary)
    args = argparse.Namespace(out=str(tmp_path), rig_random=0, structure=None, hidden_structures=None, ship=False)
    lines = "\n".join(modes.rig(args).text)
    assert "the twin against the capture: median 0.60" in lines, lines     # the twin's render, not the residual
    assert "each estimate, from the image to the record: median 3.0 s, p95 4.7 s, worst 5.0 s" in lines, lines
    assert "stated held for 42% (68%) and 67% (95%) of the captures" in lines, lines


def test_the_twin_distance_is_a_render_of_the_answer_against_the_capture(tmp_path, tiny_model) -> None:
    """``twin_distance`` renders what the app's twin shows (the answer fitted on its structure, over the capture's
    region) and measures it against the capture's colour: near for the estimate, far for another hair."""
    from dataclasses import replace

    import numpy as np

    from hairdigi.app.evaluation.rig import twin_distance
    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.inference.encoder import Encoder

    _, onnx_path, _ = tiny_model
    session = RigSession.simulated_rig(tmp_path / "s", spp=8, encoder=Encoder(onnx_path))
    try:
        session.calibrate()
        record = session.capture().record
    finally:
        session.close()
    near = twin_distance(record, None)
    fitted = record.refinement.fitted_sigma_a or record.refinement.sigma_a
    other = replace(record, refinement=replace(record.refinement, sigma_a=tuple(3 * np.asarray(fitted)),
                                               fitted_sigma_a=tuple(3 * np.asarray(fitted))))
    assert near is not None and near < 0.8, near
    assert twin_distance(other, None) > 3 * max(near, 0.5)
