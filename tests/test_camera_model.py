"""The one camera model: what the simulated rig shoots and what training applies to linear renders."""
import numpy as np

from hairdigi.inference.preprocess import encode
from hairdigi.inference.training.train import augment
from hairdigi.render.camera_model import CameraModel, CaptureErrors, random_camera, sensor_response
from hairdigi.render.srgb import linear_to_srgb, srgb8_to_linear


def _textured(seed=0, size=64):
    rng = np.random.default_rng(seed)
    base = np.array([0.35, 0.22, 0.12], np.float32)
    return (base * rng.uniform(0.4, 1.6, (size, size, 1))).astype(np.float32)


def test_sensor_response_keeps_the_linear_mean():
    linear = _textured()
    frame = sensor_response(linear, CameraModel(), np.random.default_rng(1))
    assert frame.dtype == np.uint8 and frame.shape == linear.shape
    assert np.allclose(srgb8_to_linear(frame).reshape(-1, 3).mean(0), linear.reshape(-1, 3).mean(0), rtol=0.01)
    brighter = sensor_response(linear, CameraModel(exposure_ev=0.5), np.random.default_rng(1))
    assert np.allclose(srgb8_to_linear(brighter).reshape(-1, 3).mean(0),
                       2**0.5 * linear.reshape(-1, 3).mean(0), rtol=0.01)


def test_training_augmentation_keeps_the_linear_mean_within_the_calibration_residual():
    linear = _textured(2)
    truth = linear_to_srgb(linear.reshape(-1, 3).mean(0))
    means = []
    for k in range(40):
        x = augment(linear.astype(np.float16), 32, np.random.default_rng(k), crop_min=1.0, blur_max=1.5)
        means.append(srgb8_to_linear(np.clip((x + 0.5) * 255, 0, 255)).reshape(3, -1).mean(1))
    means = np.array(means)
    target = linear.reshape(-1, 3).mean(0)
    # no bias on average (encoding unquantised sRGB of an area mean is about linear-mean preserving)
    assert np.allclose(means.mean(0), target, rtol=0.03), (means.mean(0), target, truth)
    # and each draw strays only as far as a calibrated capture does (exposure 1.5%, cast 0.8%)
    assert np.abs(means / target - 1).max() < 0.08


def test_random_cameras_stray_as_far_as_a_calibrated_capture():
    """Training's random cameras move a swatch's mean colour about as far as the rig's colour
    correction leaves a capture (``hairdigi bench rig``: mean ΔE2000 0.57 after the CCM): not the
    ideal camera's rounding alone (0.15 here), not twice the residual."""
    from hairdigi.render.metrics import mean_colour_delta_e

    linear = _textured(3, 48)
    rng = np.random.default_rng(0)
    strays = np.array([mean_colour_delta_e(srgb8_to_linear(sensor_response(linear, random_camera(rng),
                                                                           np.random.default_rng(k))), linear)
                       for k in range(200)])
    ideal = mean_colour_delta_e(srgb8_to_linear(sensor_response(linear, CameraModel(), np.random.default_rng(9))),
                                linear)
    assert ideal < 0.25 and 0.3 < strays.mean() < 0.8 and strays.max() < 1.5, (ideal, strays.mean(), strays.max())
    wider = CaptureErrors(exposure_sd=0.06, cast_sd=0.03)          # the check can fail: 4x the residual
    rng = np.random.default_rng(0)
    assert np.mean([mean_colour_delta_e(srgb8_to_linear(sensor_response(linear, random_camera(rng, wider),
                                                                         np.random.default_rng(k))), linear)
                    for k in range(50)]) > 0.8


def test_encode_resizes_in_linear_light():
    """A fine black-and-white pattern averages to mid-grey in linear light, not in sRGB codes."""
    pattern = np.zeros((64, 64, 3), np.uint8)
    pattern[::2] = 255
    x = encode(pattern, 32)
    assert np.allclose(x + 0.5, linear_to_srgb(np.array([0.5]))[0], atol=0.01)   # 0.735, not 0.5
