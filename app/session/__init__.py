"""The bench session: lights, exposure, calibration, capture and estimate on a rig, real or simulated."""
