"""A rig's spectra as the command line and the window declare them: the simulated spectral rig's LEDs
and camera, or a real rig's declared ``inference.spectral_reading.RigSpectra``."""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hairdigi.inference.spectral_reading import RigSpectra

#: The simulated spectral rig's LEDs and camera when ``--led`` / ``--sensor`` name none.
SIM_LED, SIM_SENSOR = "LED-B4", "nikon-5100"

PAIR_PROBLEM = ("a real rig declares its spectra with --led and --sensor together (its LEDs' SPD and its camera's "
                "sensitivities, each a name or a CSV); give both, or neither")


def rig_spectra(sim: bool, spectral: bool, led: str | None, sensor: str | None) -> tuple[dict, RigSpectra | None]:
    """The simulated rig's spectral keywords for ``RigSession.simulated_rig`` (``illuminant``,
    ``sensitivities``; none for the RGB rig, without ``spectral``) and a real rig's declared spectra
    (None where it declares none). ``sensor`` "cie": the CIE observer, an ideal camera."""
    if sim:
        if not spectral:
            return {}, None
        sensor = sensor or SIM_SENSOR
        return {"illuminant": led or SIM_LED, "sensitivities": None if sensor == "cie" else sensor}, None
    if led is None:
        return {}, None
    # deferred: spectral_reading loads its tables (~0.15 s); the CLI's argument checks import this module
    from hairdigi.inference.spectral_reading import RigSpectra

    return {}, RigSpectra(led, None if sensor == "cie" else sensor)


def spectra_problem(led: str | None, sensor: str | None) -> str | None:
    """What is wrong with a real rig's declared LEDs and camera (both or neither; each a known spectrum or
    a readable CSV; the LEDs white, the camera's three channels visible and distinct), in one line, or None."""
    if (led is None) != (sensor is None):
        return PAIR_PROBLEM
    # deferred: spectral_reading loads its tables (~0.15 s); the CLI's argument checks import this module
    from hairdigi.render import spectra

    for flag, value, read in (("led", led, spectra.white_light_problem),
                              ("sensor", sensor, spectra.camera_sensitivities)):
        if value is not None and value != "cie":
            try:
                problem = read(value)
            except spectra.SpectrumError as exc:
                return f"--{flag}: {exc}"
            if isinstance(problem, str):   # the LEDs read, but not white: a rig's colour needs white light
                return f"--{flag}: {problem}"
    return None
