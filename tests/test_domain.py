"""Inputs outside the training domain get warnings; a clean swatch render gets none."""
import cv2
import numpy as np
import pytest

from hairdigi.inference.domain_checks import domain_stats, domain_warnings
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import SceneSpec, render
from hairdigi.render.domain.rig_geometry import CameraPose

RNG = np.random.default_rng(0)
GARBAGE = {
    "noise": RNG.integers(0, 256, (200, 200, 3), dtype=np.uint8),
    "solid colour": np.full((200, 200, 3), (120, 80, 60), np.uint8),
    "near-white noise": RNG.integers(235, 256, (200, 200, 3), dtype=np.uint8),
    "near-black noise": RNG.integers(0, 20, (200, 200, 3), dtype=np.uint8),
    "grey noise as RGB": np.repeat(RNG.integers(0, 256, (200, 200, 1), dtype=np.uint8), 3, 2),
    "checkerboard": (np.kron(np.indices((8, 8)).sum(0) % 2, np.ones((25, 25)))[..., None] * 200 + 20)
    .repeat(3, 2).astype(np.uint8),
    "white card": np.clip(245 + RNG.normal(0, 2, (200, 200, 3)), 0, 255).astype(np.uint8),
}


#: Why each is not a swatch: the reason its warnings must give.
REASONS = {"noise": "colour channels vary independently", "solid colour": "flat colour", "near-white noise": "flat colour",
           "near-black noise": "flat colour", "grey noise as RGB": "no colour (R = G = B",
           "checkerboard": "far more contrast than a hair swatch", "white card": "flat colour"}


@pytest.mark.parametrize("name", sorted(GARBAGE))
def test_garbage_is_flagged_for_its_reason(name):
    warnings = domain_warnings(domain_stats(GARBAGE[name]))
    assert all(w.startswith("out of domain: ") for w in warnings), warnings
    assert any(REASONS[name] in w for w in warnings), (name, warnings)


def test_a_portrait_is_flagged():
    import matplotlib.cbook as cbook

    photo = cv2.imread(str(cbook.get_sample_data("grace_hopper.jpg", asfileobj=False)))[..., ::-1]
    assert any("contrast" in w for w in domain_warnings(domain_stats(np.ascontiguousarray(photo))))


@pytest.mark.parametrize("hair, pose", [(HairParams((200, 60, 40), 0.7, 0.3, 0.4), CameraPose(0, 0)),
                                        (HairParams((255, 255, 255), 0.0, 0.95, 0.9), CameraPose(40, 200)),
                                        (HairParams((250, 240, 200), 0.2, 0.03, 0.2), CameraPose(20, 60))])
def test_clean_swatch_renders_are_not_flagged(hair, pose):
    img = render(hair, SceneSpec("swatch", camera=pose, strand_seed=5), 64, 32, seed=1).srgb
    assert domain_warnings(domain_stats(img)) == []


def test_the_estimate_record_carries_the_warnings(tiny_model):
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import estimate_image, record
    from hairdigi.render.domain.records import EstimateRecord, WarningKind

    _, onnx_path, _ = tiny_model
    encoder = Encoder(onnx_path)
    result = estimate_image(GARBAGE["noise"], encoder, refine_colour=False)
    rec = record(result, encoder)
    assert rec.warnings and rec.reliable is False
    assert all(w.kind is WarningKind.OUT_OF_DOMAIN for w in rec.warnings)
    data = rec.to_json()                      # the file says so too, and reads back the same
    assert data["reliable"] is False and EstimateRecord.from_json(data).warnings == rec.warnings
    # a solid colour is refused as flat before any estimate (no confident answer, no zero uncertainty)
    from hairdigi.inference.preprocess import ImageError
    with pytest.raises(ImageError, match="flat"):
        estimate_image(GARBAGE["solid colour"], encoder, refine_colour=False)
