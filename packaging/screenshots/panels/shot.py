"""The Dye and Library panels side by side under Xvfb, each a view of its model (its work in workers).

A session of rendered captures (natural bases at four levels, two of them dyed copper, and a few
shades), estimate records as ``hairdigi estimate`` writes them, imported into a library of its own;
the Dye panel characterises the copper, previews it and renders its shade card; the Library panel
compares the two swatches nearest a copper colour.

    xvfb-run -a -s "-screen 0 1800x1000x24" .venv/bin/python packaging/screenshots/panels/shot.py OUT WORK
"""
import hashlib
import os
import sys
import time
from pathlib import Path

out, work = Path(sys.argv[1]), Path(sys.argv[2])
os.environ["HAIRDIGI_LIBRARY"] = str(work / "library.sqlite")
os.environ["HAIRDIGI_SESSIONS"] = str(work / "no-sessions")
os.environ.setdefault("HAIRDIGI_CACHE", str(work / "cache"))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from hairdigi.inference.levels import natural_base  # noqa: E402
from hairdigi.render.domain.absorption import dye_sigma_a, hair_sigma_a  # noqa: E402
from hairdigi.render.domain.params import HairParams  # noqa: E402
from hairdigi.render.domain.records import CaptureRecord, EstimateRecord, RefinementRecord, write_record  # noqa: E402
from hairdigi.render.renderer import SceneSpec, default_renderer  # noqa: E402

DEPOSIT, LIFT = dye_sigma_a((190.0, 70.0, 40.0), 0.55), 0.35
session = work / "march-shades"
captures = session / "captures"


def capture(i: int, name: str, hair: HairParams, sigma) -> str:
    """A capture as the rig saves it: the swatch's picture, its capture record and its estimate."""
    cid = f"20260315-10{i:02d}00-000"
    image = default_renderer().render(np.asarray(sigma, float), SceneSpec("swatch", framing="crop"), 96, 8, i).srgb
    cv2.imwrite(str(captures / f"{cid}.png"), image[..., ::-1])
    sha = hashlib.sha256((captures / f"{cid}.png").read_bytes()).hexdigest()
    write_record(captures / f"{cid}.json", CaptureRecord(id=cid, image=f"{cid}.png", image_sha256=sha,
                                                           captured=f"2026-03-15T10:{i:02d}:00+0000"))
    write_record(captures / f"{cid}.result.json", EstimateRecord(
        hair=hair, capture=f"{cid}.png", refinement=RefinementRecord(ran=True, sigma_a=tuple(map(float, sigma)))))
    print(name, cid, flush=True)
    return cid


if not captures.exists():
    captures.mkdir(parents=True)
    i = 0
    for level in (9, 7, 5, 3):
        base = natural_base(level)
        capture(i, f"level {level}", base, hair_sigma_a(base))
        i += 1
        if level in (7, 5):
            capture(i, f"level {level} dyed copper", base, (1 - LIFT) * hair_sigma_a(base) + DEPOSIT)
            i += 1
    for name, hair in (("auburn", HairParams((160, 40, 30), 0.6, 0.45, 0.4)),
                       ("rose gold", HairParams((230, 130, 140), 0.5, 0.1, 0.3)),
                       ("copper", HairParams((200, 80, 30), 0.7, 0.25, 0.2))):
        capture(i, name, hair, hair_sigma_a(hair))
        i += 1

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtWidgets import QApplication, QMainWindow  # noqa: E402

from hairdigi.app.gui.dye_panel import DyePanel, add_dye_dock, select_path  # noqa: E402
from hairdigi.app.gui.library_panel import LibraryPanel, add_library_dock  # noqa: E402

app = QApplication(sys.argv[:1])


def wait_until(what: str, condition, timeout_s: float = 300.0) -> None:
    start = time.monotonic()
    while not condition():
        app.processEvents()
        time.sleep(0.02)
        if time.monotonic() - start > timeout_s:
            raise TimeoutError(what)
    print(f"{what}: {time.monotonic() - start:.1f} s", flush=True)


window = QMainWindow()
window.setWindowTitle("hairdigi — Dye and Library panels")
window.resize(1700, 940)
dye_dock = add_dye_dock(window, session)
library_dock = add_library_dock(window)
window.splitDockWidget(dye_dock, library_dock, Qt.Orientation.Horizontal)
window.show()
window.resizeDocks([dye_dock, library_dock], [900, 800], Qt.Orientation.Horizontal)
dye: DyePanel = dye_dock.widget()
wait_until("dye records", lambda: dye.base_combo.count() == 9)
ids = [Path(dye.base_combo.itemData(i)).name.removesuffix(".result.json") for i in range(dye.base_combo.count())]
for base, dyed in ((1, 2), (3, 4)):   # level 7 and level 5, each with its copper-dyed twin
    select_path(dye.base_combo, captures / f"{ids[base]}.result.json")
    select_path(dye.dyed_combo, captures / f"{ids[dyed]}.result.json")
    dye.add_pair()
dye.name_edit.setText("Copper 7.4")
dye.characterise()
wait_until("characterised", lambda: "saved Copper-7.4.json" in dye.dye_info.text()
           and dye.dye_combo.currentText() == "Copper-7.4")
select_path(dye.target_combo, captures / f"{ids[0]}.result.json")    # on the level-9 blonde
dye.preview()
wait_until("preview", lambda: not dye.style_label.pixmap().isNull())
dye.card()
wait_until("shade card", lambda: not dye.card_label.pixmap().isNull())

wait_until("library open", lambda: isinstance(library_dock.widget(), LibraryPanel))
library: LibraryPanel = library_dock.widget()
library.import_sessions([str(session)])
wait_until("library rows", lambda: library.table.rowCount() == 9)
library.search.setText("")
library.near.setText("#b06a3a")
library.refresh()
wait_until("near a copper", lambda: library.model.rows.query.near == "#b06a3a")
library.table.setSelectionMode(library.table.SelectionMode.MultiSelection)
library.table.selectRow(0)
library.table.selectRow(1)
wait_until("swatch images", lambda: not library.left.image.pixmap().isNull() and not library.right.image.pixmap().isNull())
print("delta:", library.delta.text(), flush=True)
for _ in range(20):
    app.processEvents()
    time.sleep(0.02)
window.grab().save(str(out / "app-panels-xvfb.png"))
window.close()
app.processEvents()
