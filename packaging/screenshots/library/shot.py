"""The app on the simulated rig under Xvfb with the Library panel up: two coppers compared."""
import os, sys, time
from pathlib import Path
from PySide6.QtWidgets import QApplication
from PySide6.QtCore import QTimer
from hairdigi.app.library.store import Library
from hairdigi.app.library.importing import import_paths

out = Path(sys.argv[1])
with Library() as lib:
    import_paths(lib, ["/tmp/shot/march-shades", "/tmp/sess1"], progress=print)
    lib.tag("20260315-100200-000", ["copper", "march"]); lib.tag("20260315-101000-000", ["copper"])
    lib.note("20260315-100200-000", "the copper we measured in March")
app = QApplication(sys.argv[:1])
from hairdigi.app.gui.main_window import MainWindow
from hairdigi.app.session.rig_session import open_rig
rig, reason = open_rig(Path("/tmp/shot/session"), True, "0", "", fallback=True)
window = MainWindow(rig, {}, strand_view=False)
window.show()
dock = window.library_dock
dock.show(); dock.raise_()
panel = dock.widget()
def shoot():
    panel.near.setText("#b06a3a"); panel.refresh()
    while panel.model.rows.query.near != "#b06a3a":   # the query runs in a worker
        app.processEvents(); time.sleep(0.02)
    ids = [s.capture_id for s in panel.swatches]
    panel.table.setSelectionMode(panel.table.SelectionMode.MultiSelection)
    panel.table.selectRow(ids.index("20260315-100200-000")); panel.table.selectRow(ids.index("20260315-101000-000"))
    while panel.left.image.pixmap().isNull() or panel.right.image.pixmap().isNull():   # the captures, read in a worker
        app.processEvents(); time.sleep(0.02)
    window.grab().save(str(out / "app-library-xvfb.png"))
    panel.grab().save(str(out / "library-panel.png"))
    print("delta:", panel.delta.text())
    window.close(); rig.close(); app.quit()
QTimer.singleShot(8000, shoot)
app.exec()
