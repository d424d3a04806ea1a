"""``hairdigi evaluate --dye --rig``: the dye protocol (``app/evaluation/dye_evaluation.py``) on
simulated-rig captures: each base and dyed swatch is put under the simulated rig and captured the way
an operator does (``RigSession.calibrate`` once on the ColorChecker, then ``RigSession.capture``: the
live frame through the camera model with a white-balance cast, ``cv2.mcc`` and the CCM, estimated on
the swatch area). All captures share one session and so one calibration, as a lab's shift does."""
from __future__ import annotations

import os
import time
from pathlib import Path

from hairdigi.app.evaluation.dye_evaluation import evaluate_dye
from hairdigi.app.session.blockers import messages
from hairdigi.app.session.rig_session import RigSession
from hairdigi.render.camera_model import CameraModel
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import write_record

#: The simulated sensor's white-balance error (the CCM corrects it) and the rig's light-render spp.
CAST, SPP = (1.1, 1.0, 0.9), 32


def rig_capture(folder: str | os.PathLike, encoder, cast=CAST, spp: int = SPP):
    """A capture function for ``evaluate_dye``: the hidden hair under the simulated rig, captured."""
    folder = Path(folder)

    def capture(hidden: HairParams, index: int, path: Path) -> float:
        session = RigSession.simulated_rig(folder, hidden=hidden, camera_model=CameraModel(cast=tuple(cast)),
                                           spp=spp, encoder=encoder)
        try:
            if session.profile is None:
                session.calibrate()
            start = time.perf_counter()
            result = session.capture()
            seconds = time.perf_counter() - start
        finally:
            session.close()
        if result.record is None or result.blocked:
            raise RuntimeError(f"the simulated capture of {path.stem} was blocked: {'; '.join(messages(result.blocked))}")
        write_record(path, result.record)
        return seconds

    return capture


def evaluate_dye_rig(encoder, out_dir: str | os.PathLike, config) -> dict:
    """The dye protocol on simulated-rig captures; the same outputs as the clean run."""
    out = Path(out_dir)
    return evaluate_dye(encoder, out, config, capture=rig_capture(out / "session", encoder),
                        inputs=f"simulated-rig captures (cast {CAST}, {SPP} spp light renders) through cv2.mcc and the CCM")
