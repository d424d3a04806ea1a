"""A demo library: the simulated rig's real session plus a session of rendered swatches."""
import hashlib, sys
from pathlib import Path
import cv2, numpy as np
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import CaptureRecord, EstimateRecord, write_record
from hairdigi.render.renderer import SceneSpec, render

out = Path(sys.argv[1]); cap = out / "captures"; cap.mkdir(parents=True, exist_ok=True)
shades = [("platinum", HairParams((255,255,255),0,0.02,0.5)), ("golden blonde", HairParams((230,180,90),0.4,0.15,0.3)),
          ("copper", HairParams((200,80,30),0.7,0.25,0.2)), ("auburn", HairParams((160,40,30),0.6,0.45,0.4)),
          ("chestnut", HairParams((255,255,255),0,0.55,0.6)), ("mahogany", HairParams((140,30,60),0.5,0.55,0.6)),
          ("dark brown", HairParams((255,255,255),0,0.75,0.8)), ("black", HairParams((255,255,255),0,0.97,0.9)),
          ("rose gold", HairParams((230,130,140),0.5,0.1,0.3)), ("violet", HairParams((110,60,160),0.8,0.3,0.5)),
          ("copper 2", HairParams((210,90,35),0.7,0.27,0.25))]
for i, (name, hair) in enumerate(shades):
    cid = f"20260315-10{i:02d}00-000"
    img = render(hair, SceneSpec("swatch", framing="crop"), 96, 8, i).srgb
    cv2.imwrite(str(cap / f"{cid}.png"), img[..., ::-1])
    write_record(cap / f"{cid}.json", CaptureRecord(id=cid, image=f"{cid}.png", image_sha256=hashlib.sha256((cap / f"{cid}.png").read_bytes()).hexdigest(), captured=f"2026-03-15T10:{i:02d}:00+0000"))
    write_record(cap / f"{cid}.result.json", EstimateRecord(hair=hair, capture=f"{cid}.png"))
    print(name, cid)
