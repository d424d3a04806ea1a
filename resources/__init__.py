"""hairdigi resources: the trained model and its card, sample parameters, hairstyles and charts.

Found through ``importlib.resources``, so they load the same from a checkout, a wheel or a frozen build."""
from importlib.resources import files
from pathlib import Path

ROOT = Path(str(files(__name__)))
MODELS = ROOT / "models"
SAMPLES = ROOT / "samples"
SAMPLE_PARAMS = SAMPLES / "auburn.json"
CHARTS = ROOT / "charts"
