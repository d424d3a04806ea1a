"""hairdigi resources: the trained model and its card, sample parameters, hairstyles and charts."""
from pathlib import Path

ROOT = Path(__file__).resolve().parent
MODELS = ROOT / "models"
SAMPLES = ROOT / "samples"
SAMPLE_PARAMS = SAMPLES / "auburn.json"
