"""Dataset, training, ONNX export, estimate and evaluate, on a tiny dataset and a model trained here."""
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.inference.training.dataset import DatasetConfig, generate, load, sample_spec, shard_path
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.preprocess import Roi, find_swatch_roi, swatch_crop
from hairdigi.render.domain.bounds import SwatchModel
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import SceneSpec, render
from hairdigi.render.domain.rig_geometry import CameraPose, light_blocks_view

from conftest import TINY


def test_samples_are_deterministic_and_in_range():
    cfg = DatasetConfig(**TINY)
    a, b = sample_spec(cfg, 5), sample_spec(cfg, 5)
    assert a == b and sample_spec(cfg, 6) != a
    cameras = [sample_spec(DatasetConfig(n=400), i).camera for i in range(400)]
    polars = np.array([c.polar_deg for c in cameras])
    assert 0 <= min(polars) and max(polars) <= 45 and np.mean(polars > 30) > 0.2
    assert not any(light_blocks_view(c) for c in cameras)   # about 12 of these 400 were drawn again


def test_a_camera_behind_a_light_is_detected_and_skipped_in_training():
    from hairdigi.inference.training.dataset import usable

    behind = CameraPose(50.0, 90.0, 4.0)          # straight behind light 0 (polar 50°, azimuth 90°)
    beside = CameraPose(50.0, 150.0, 4.0)         # between lights 0 and 1
    assert light_blocks_view(behind) and not light_blocks_view(beside)
    assert not light_blocks_view(CameraPose(0.0, 0.0, 4.0)) and not light_blocks_view(CameraPose(45.0, 30.0, 4.0))
    assert usable(np.array([[50.0, 90.0, 4.0], [50.0, 150.0, 4.0]])).tolist() == [False, True]
    # and the renderer agrees: the back of the light is what that camera sees
    dark = render(HairParams((255, 255, 255), 0, 0, 0), SceneSpec("swatch", camera=behind, strands=300), 24, 2)
    clear = render(HairParams((255, 255, 255), 0, 0, 0), SceneSpec("swatch", camera=beside, strands=300), 24, 2)
    assert dark.srgb.mean() < 2 < 40 < clear.srgb.mean()


def test_torch_absorption_matches_the_renderers():
    """The appearance loss term must see exactly the ``sigma_a`` the renderer gets."""
    import torch

    from hairdigi.inference.training.losses import appearance, sigma_a
    from hairdigi.render.domain.absorption import approximate_albedo, hair_sigma_a

    v = np.random.default_rng(0).random((300, 6))
    v[:11, 4] = np.linspace(0, 1, 11)                 # every knot of the melanin remap
    v[11:20, :3] = 0                                  # black dye: the clamped albedo
    ref = np.array([hair_sigma_a(HairParams.from_vector(x)) for x in v])
    assert np.allclose(sigma_a(torch.from_numpy(v)).numpy(), ref, rtol=1e-9, atol=1e-12)
    albedo = np.array([approximate_albedo(HairParams.from_vector(x)) for x in v])
    assert np.allclose(appearance(torch.from_numpy(v)).numpy() ** 3, albedo, atol=1e-5)
    x = torch.from_numpy(v).requires_grad_()
    appearance(x).sum().backward()
    assert torch.isfinite(x.grad).all()


def test_dataset_is_the_same_whatever_the_sharding(tmp_path):
    generate(DatasetConfig(**TINY), tmp_path / "a", workers=1, progress=False)
    generate(DatasetConfig(**{**TINY, "shard_size": 3}), tmp_path / "b", workers=1, progress=False)
    a, pa, ca, _ = load(tmp_path / "a")
    b, pb, cb, _ = load(tmp_path / "b")
    assert np.array_equal(pa, pb) and np.array_equal(ca, cb)   # the draws
    assert np.array_equal(a, b) and a.shape == (8, 32, 32, 3)   # and the renders
    counts = np.load(shard_path(tmp_path / "b", 0))["nonfinite"]   # each sample's NaN/Inf count travels with it
    assert counts.dtype == np.int64 and counts.tolist() == [0, 0, 0]


def test_dataset_resumes_only_missing_shards(tmp_path):
    root = tmp_path / "ds"
    generate(DatasetConfig(**TINY), root, workers=1, progress=False)
    kept = shard_path(root, 0).stat().st_mtime_ns
    before = np.load(shard_path(root, 1))["images"].copy()
    shard_path(root, 1).unlink()
    generate(DatasetConfig(**TINY), root, workers=1, progress=False)
    assert shard_path(root, 0).stat().st_mtime_ns == kept
    assert np.array_equal(np.load(shard_path(root, 1))["images"], before)
    with pytest.raises(ValueError, match="other settings"):
        generate(DatasetConfig(**{**TINY, "spp": 4}), root, workers=1, progress=False)


def test_dataset_draws_and_records_each_swatchs_appearance_and_keeps_old_datasets(tmp_path):
    """Swatches of random shine, spread and greys on the layered swatch, each recorded in its
    shard; a dataset made before (no appearance, today's swatch) keeps its samples and still resumes."""
    import json

    from hairdigi.inference.training.dataset import read_shard, sample_spec, scene_of
    from hairdigi.render.domain.appearance import APPEARANCE_DRAW, FIELDS

    config = DatasetConfig(**TINY)
    generate(config, tmp_path / "new", workers=1, progress=False)
    looks = np.concatenate([read_shard(p)["appearance"] for p in sorted((tmp_path / "new").glob("shard-*.npz"))])
    assert looks.shape == (8, 3) and len(np.unique(looks[:, 0])) == 8
    for k, name in enumerate(FIELDS):
        low, high = APPEARANCE_DRAW[name]
        assert np.all((looks[:, k] >= low) & (looks[:, k] <= high)), name
    assert scene_of(config, 0).swatch_model is SwatchModel.LAYERED and scene_of(config, 0).appearance is not None
    # the old layout: a manifest without the new settings is read as today's swatch, fixed appearance
    old = DatasetConfig(**TINY, swatch_model="today", appearance="fixed")
    assert [sample_spec(old, i).params for i in range(8)] == [sample_spec(config, i).params for i in range(8)]
    root = tmp_path / "old"
    generate(old, root, workers=1, progress=False)
    manifest = json.loads((root / "manifest.json").read_text())
    for key in ("swatch_model", "appearance"):
        del manifest["config"][key]
    (root / "manifest.json").write_text(json.dumps(manifest))
    shard_path(root, 1).unlink()
    generate(old, root, workers=1, progress=False)            # resumes under the legacy defaults
    with pytest.raises(ValueError, match="other settings"):
        generate(config, root, workers=1, progress=False)      # the new draws are another dataset
    assert np.allclose(read_shard(shard_path(root, 0))["appearance"], [0.3, 0.0, 0.0])


def test_blur_augmentation_averages_noise_and_keeps_the_colour():
    from hairdigi.inference.training.train import augment

    rng = np.random.default_rng(0)
    noisy = np.clip(rng.normal([150, 90, 40], 40, (96, 96, 3)), 0, 255).astype(np.uint8)
    sharp = augment(noisy, 48, np.random.default_rng(1), crop_min=1.0, blur_max=0.0)
    blurred = [augment(noisy, 48, np.random.default_rng(k), crop_min=1.0, blur_max=1.5) for k in range(8)]
    from hairdigi.render.srgb import srgb8_to_linear

    def linear_mean(x):
        return srgb8_to_linear(np.clip((x + 0.5) * 255, 0, 255)).mean(axis=(1, 2))

    assert all(np.allclose(linear_mean(b), linear_mean(sharp), rtol=0.01) for b in blurred)
    assert np.mean([b.std(axis=(1, 2)).mean() for b in blurred]) < 0.8 * sharp.std(axis=(1, 2)).mean()


def test_datasets_are_joined_for_training_and_sizes_must_agree(tiny_dataset, tmp_path):
    from hairdigi.inference.training.train import load_datasets

    images, params, cameras, configs = load_datasets([tiny_dataset, tiny_dataset])
    assert images.shape == (16, 32, 32, 3) and len(params) == len(cameras) == 16
    assert [c["n_loaded"] for c in configs] == [8, 8]
    generate(DatasetConfig(**{**TINY, "n": 2, "size": 24, "shard_size": 2}), tmp_path / "small", workers=1,
             progress=False)
    with pytest.raises(ValueError, match="different image sizes.*one --size"):
        load_datasets([tiny_dataset, tmp_path / "small"])
    generate(DatasetConfig(**{**TINY, "n": 2, "framing": "rig", "shard_size": 2}), tmp_path / "rig", workers=1,
             progress=False)
    with pytest.raises(ValueError, match="mix framings.*one framing"):
        load_datasets([tiny_dataset, tmp_path / "rig"])


def test_training_resumes_and_onnx_matches_torch(tiny_dataset, tiny_model, tmp_path):
    from hairdigi.inference.training.network import EncoderConfig
    from hairdigi.inference.training.train import TrainConfig, train

    run, onnx_path, diff = tiny_model
    assert diff < 1e-4
    history = json.loads((run / "history.json").read_text())
    assert [e["epoch"] for e in history["epochs"]] == [1, 2]
    assert (run / "training_curve.png").stat().st_size > 0
    # stop after one epoch, then resume: the result equals an uninterrupted run
    cfg = TrainConfig(epochs=2, batch_size=4, threads=1, val_fraction=0.25)
    enc = EncoderConfig(width=4, blocks=3, input_size=32)
    part = train(tiny_dataset, tmp_path / "r", enc, cfg, progress=False, epochs_now=1)
    assert len(part["epochs"]) == 1
    resumed = train(tiny_dataset, tmp_path / "r", enc, cfg, progress=False)
    assert [e["epoch"] for e in resumed["epochs"]] == [1, 2]
    assert resumed["epochs"][-1]["val_mse"] == pytest.approx(history["epochs"][-1]["val_mse"], rel=1e-5)


def test_estimate_writes_params_and_provenance(tiny_model, tmp_path, capsys):
    _, onnx_path, _ = tiny_model
    img = render(HairParams((200, 40, 40), 0.8, 0.2, 0.5), SceneSpec("swatch", framing="rig", strands=1500),
                 128, 4).srgb  # a whole rig frame: the swatch area is found
    cv2.imwrite(str(tmp_path / "s.png"), img[..., ::-1])
    out = tmp_path / "p.json"
    assert main(["estimate", str(tmp_path / "s.png"), "--model", str(onnx_path), "--out", str(out),
                 "--no-refine"]) == 0
    record = json.loads(out.read_text())
    p = HairParams.from_dict(record)
    assert all(0 <= v <= 255 for v in p.dye_rgb)
    prov = record["provenance"]
    assert len(prov["model"]["sha256"]) == 64 and len(prov["image_sha256"]) == 64 and prov["time"]
    assert prov["roi"] and prov["camera"]["polar_deg"] == pytest.approx(10.27, abs=0.01)
    assert record["refinement"] == {"ran": False} and isinstance(record["warnings"], list)
    assert set(record["encoder"]["view_spread"]) == {"dye_r", "dye_g", "dye_b", "dye_concentration",
                                                     "melanin_concentration", "melanin_ratio"}


@pytest.mark.parametrize("make, message", [
    (lambda p: p.write_text("hello"), "not an image"),
    (lambda p: p.write_bytes(cv2.imencode(".png", np.random.default_rng(0).integers(0, 255, (64, 64, 3), np.uint8))[1].tobytes()[:-30]), "truncated"),
    (lambda p: cv2.imwrite(str(p), np.random.default_rng(0).integers(0, 255, (16, 16, 3), np.uint8)), "too small"),
    (lambda p: cv2.imwrite(str(p), np.full((64, 64, 3), 128, np.uint8)), "flat"),
    (lambda p: cv2.imwrite(str(p), np.random.default_rng(0).integers(0, 65535, (64, 64, 3)).astype(np.uint16)), "16-bit"),
])
def test_estimate_rejects_bad_input_clearly(tiny_model, tmp_path, capsys, make, message):
    _, onnx_path, _ = tiny_model
    path = tmp_path / "bad.png"
    make(path)
    out = tmp_path / "p.json"
    assert main(["estimate", str(path), "--model", str(onnx_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists() and path.exists()  # nothing written, the input kept


def test_missing_model_names_the_fix(tmp_path, capsys):
    cv2.imwrite(str(tmp_path / "s.png"), np.random.default_rng(0).integers(0, 255, (64, 64, 3), np.uint8))
    assert main(["estimate", str(tmp_path / "s.png"), "--model", str(tmp_path / "none.onnx"),
                 "--out", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err
    assert "--model" in err and "no such file" in err and "check the path" in err


def test_swatch_area_is_found_in_a_rig_frame_and_crops_are_kept_whole():
    p = HairParams((120, 60, 30), 0.5, 0.4, 0.6)
    rig = render(p, SceneSpec("swatch", framing="rig"), 128, 8).srgb
    roi = find_swatch_roi(rig)
    # the swatch is 1 unit wide in a 1.9-unit view: about 67 px, centred
    assert 50 < roi.w < 85 and abs(roi.x + roi.w / 2 - 64) < 10, roi
    crop = render(p, SceneSpec("swatch", framing="crop"), 96, 8).srgb
    assert find_swatch_roi(crop) == Roi(0, 0, 96, 96)
    region, _ = swatch_crop(rig)
    assert region.shape[0] == region.shape[1] >= 32
    noise = np.random.default_rng(0).integers(0, 255, (64, 64, 3), np.uint8)
    assert find_swatch_roi(noise) == Roi(0, 0, 64, 64)  # one material everywhere: taken as all hair


SMALL_JUDGE = dict(size=32, spp=4, seed=5)


@pytest.mark.slow
def test_convergence_sweep_reports_each_input_spp(tiny_model, tmp_path):
    from hairdigi.inference.training.convergence import convergence_sweep
    from hairdigi.inference.training.evaluate import Judge, prepare_heldout
    from hairdigi.inference.refine import RefineSettings

    _, onnx_path, _ = tiny_model
    judge = Judge(**SMALL_JUDGE)
    root = prepare_heldout(tmp_path / "h", n=3, size=32, spp=4, workers=1, judge=judge, progress=False)
    rows = convergence_sweep(Encoder(onnx_path), root, tmp_path / "sweep", spps=(2, 16, 2), count=3,
                             settings=RefineSettings(size=16, spp=2, check_spp=2, iterations=1), judge=judge, progress=False)
    assert [(r["spp"], r["swatches"]) for r in rows] == [(2, 3), (16, 3), (2, 3)]
    # each row is its own input spp: the inputs are rendered again at it, so the same spp again reads the
    # same errors and another spp other ones (a sweep that ignored the spp would give three equal rows)
    errors = [{k: v for k, v in r.items() if k.startswith(("encoder_de", "refined_de"))} for r in rows]
    assert errors[0] == errors[2], rows
    assert errors[1]["encoder_de_median"] != errors[0]["encoder_de_median"], rows
    assert errors[1]["refined_de_median"] != errors[0]["refined_de_median"], rows
    assert read_table(tmp_path / "sweep" / "convergence.csv") == rows
    assert (tmp_path / "sweep" / "convergence.png").stat().st_size > 0


def test_refine_bench_writes_speed_against_error(tiny_model, tmp_path):
    from hairdigi.app.evaluation.bench_refine import bench_refine
    from hairdigi.inference.training.evaluate import Judge, prepare_heldout

    _, onnx_path, _ = tiny_model
    judge = Judge(**SMALL_JUDGE)
    root = prepare_heldout(tmp_path / "h", n=2, size=32, spp=4, workers=1, judge=judge, progress=False)
    rows = bench_refine(Encoder(onnx_path), root, tmp_path / "b", sizes=(16,), spps=(2,), iterations=(0, 2),
                        count=2, judge=judge, progress=False)
    assert [(r["size"], r["spp"], r["iterations"], r["swatches"]) for r in rows] == [(16, 2, 0, 2), (16, 2, 2, 2)]
    # speed: two check renders cost time that no iterations do not
    assert rows[1]["polish_s"] > rows[0]["polish_s"], rows
    # error: the check renders moved the answer, which is judged against the truth (never exactly 0)
    assert rows[1]["de_median"] != rows[0]["de_median"] and all(r["de_median"] > 0 for r in rows), rows
    assert read_table(tmp_path / "b" / "refine_bench.csv") == rows
    assert (tmp_path / "b" / "refine_bench.png").stat().st_size > 0


def read_table(path: Path) -> list[dict]:
    """A bench's CSV, each value back to the int or float it was written from."""
    import csv

    with open(path, newline="", encoding="utf-8") as f:
        return [{k: int(v) if v.lstrip("-").isdigit() else float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def test_evaluate_judges_clean_inputs_and_measures_interval_coverage(tiny_model, tmp_path):
    from hairdigi.inference.training.evaluate import Judge, evaluate
    from hairdigi.inference.refine import RefineSettings

    _, onnx_path, _ = tiny_model
    summary = evaluate(Encoder(onnx_path), tmp_path / "eval", n=6, size=32, spp=4, workers=1,
                       settings=RefineSettings(size=16, spp=2, check_spp=2, iterations=1), judge=Judge(**SMALL_JUDGE),
                       progress=False)
    a = summary["buckets"]["all"]
    assert a["count"] == 6 and summary["n"] == 6
    for who in ("encoder", "refined", "floor"):
        d = a[f"{who}_mean_colour_de2000"]
        assert d["max"] >= d["p95"] >= d["median"] >= 0
    assert a["floor_mean_colour_de2000"]["median"] > 0        # input vs the truth's render: never identical
    # a 2-epoch encoder is poor; refinement to the capture's colour must beat it
    assert a["refined_mean_colour_de2000"]["median"] < a["encoder_mean_colour_de2000"]["median"]
    assert set(summary["coverage"]) == {"dye_r", "dye_g", "dye_b", "dye_concentration", "melanin_concentration",
                                        "melanin_ratio"}
    assert "not computed" in summary["lpips"] and summary["latency_ms_median_1_thread"] > 0
    samples = json.loads((tmp_path / "eval" / "samples.json").read_text())
    assert summary["judge_nonfinite"] == 0 and all(r["judge_nonfinite"] == 0 for r in samples)
    table = json.loads((tmp_path / "eval" / "uncertainty.json").read_text())
    assert table["coverage"] == 0.68 and len(table["half_width"]["dye_r"]) == 3
    assert (tmp_path / "eval" / "evaluation.json").exists() and (tmp_path / "eval" / "samples.json").exists()


def test_encoder_bench_and_model_card(tiny_model, tmp_path):
    from hairdigi.inference.training.evaluate import Judge, prepare_heldout
    from hairdigi.inference.training.report import bench_encoders, model_card

    run, onnx_path, _ = tiny_model
    prepare_heldout(tmp_path / "bench" / "heldout", n=3, size=32, spp=4, workers=1, judge=Judge(**SMALL_JUDGE),
                    progress=False)
    rows = bench_encoders([onnx_path], tmp_path / "bench", n=3, size=32, spp=4, workers=1,
                          judge=Judge(**SMALL_JUDGE), progress=False)
    assert rows[0]["latency_ms"] > 0 and rows[0]["parameters"] > 1000 and rows[0]["l1_floor"] > 0
    assert (tmp_path / "bench" / "encoder_bench.png").stat().st_size > 0
    evaluation = json.loads((tmp_path / "bench" / "encoder" / "evaluation.json").read_text())
    (tmp_path / "encoder-notes.md").write_text("## Known limits\n- a hand-written note\n")
    convergence = [{"spp": 4, "swatches": 2, "render_s": 0.1, "encoder_de_median": 1.5, "encoder_de_p95": 2.0,
                    "refined_de_median": 0.3, "refined_de_p95": 0.6}]
    card = model_card(onnx_path, run, evaluation, tmp_path / "encoder.md", rows, convergence)
    text = card.read_text()
    assert Encoder(onnx_path).sha256 in text and "floor" in text and "not computed" in text
    assert "a hand-written note" in text and "| 4 | 0.10 | 1.50 / 2.00 | 0.30 / 0.60 |" in text
    assert "fibre colour" in text and "camera_model" in text   # the loss and the capture chain are named
    assert json.loads(card.with_suffix(".json").read_text())["datasets"][0]["n"] == 8
    # and through the command line, which also ships the measured intervals beside the model
    out = tmp_path / "cli" / "encoder.md"
    out.parent.mkdir()
    assert main(["model-card", "--run", str(run), "--model", str(onnx_path), "--out", str(out),
                 "--evaluation", str(tmp_path / "bench" / "encoder" / "evaluation.json")]) == 0
    assert out.exists() and (out.parent / "uncertainty.json").exists()


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (Linux /proc)."""
    found, todo = set(), [pid]
    while todo:
        for children in Path(f"/proc/{todo.pop()}/task").glob("*/children"):
            kids = {int(c) for c in children.read_text().split()} - found
            found |= kids
            todo += kids
    return found


def alive(pid: int) -> bool:
    """Running (not exited, not a zombie waiting to be reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.mark.slow
def test_killed_run_leaves_no_orphan_workers_and_resumes(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    root = tmp_path / "ds"
    cfg = dict(n=40, size=32, spp=2, seed=5, strands=150, shard_size=2)
    code = ("from hairdigi.inference.training.dataset import DatasetConfig, generate; "
            f"generate(DatasetConfig(**{cfg!r}), {str(root)!r}, workers=2, progress=False)")
    proc = subprocess.Popen([sys.executable, "-c", code])
    # the waits are generous: under the tier's own load (2 cores, other renders) a fresh process takes
    # tens of seconds to import Mitsuba and start its pool, and a worker finishes the render it is in
    deadline = time.monotonic() + 300
    while not list(root.glob("shard-*.npz")) and time.monotonic() < deadline:
        time.sleep(0.1)
    workers = descendants(proc.pid)
    assert workers, "the pool's workers were not found"
    proc.send_signal(signal.SIGTERM)
    proc.wait(120)
    deadline = time.monotonic() + 120
    while any(map(alive, workers)) and time.monotonic() < deadline:   # until every worker has exited
        time.sleep(0.05)
    assert not any(map(alive, workers)), "a worker renders on after its run was stopped"
    written = sorted(p.name for p in root.glob("shard-*.npz"))
    assert 0 < len(written) < 20
    generate(DatasetConfig(**cfg), root, workers=1, progress=False)
    images, params, _, _ = load(root)
    assert len(images) == 40 and not list(root.glob(".*.npz"))  # complete, no stray temp files


def test_evaluate_flags_an_unusable_swatch_instead_of_aborting(tiny_model, tmp_path):
    """A held-out render can be unusable (a camera that sees the back of a light renders black)."""
    from hairdigi.inference.training.dataset import shard_path
    from hairdigi.inference.training.evaluate import Judge, evaluate, prepare_heldout

    _, onnx_path, _ = tiny_model
    judge = Judge(**SMALL_JUDGE)
    root = prepare_heldout(tmp_path / "h", n=4, size=32, spp=4, workers=1, judge=judge, progress=False)
    shard = dict(np.load(shard_path(root, 0)))
    shard["images"][1] = 0                      # swatch 1: a black frame (the camera adds its read noise)
    np.savez(shard_path(root, 0), **shard)
    summary = evaluate(Encoder(onnx_path), tmp_path / "e", n=4, size=32, spp=4, data_root=root, workers=1,
                       refine_colour=False, judge=judge, progress=False)
    rows = json.loads((tmp_path / "e" / "samples.json").read_text())
    assert summary["n"] == 4 and summary["heldout_flagged_out_of_domain"] >= 1
    assert any("out of domain" in w for w in rows[1]["warnings"])
