"""``hairdigi app``: open the main window on the rig, or on the simulated rig when none is found."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from PySide6.QtWidgets import QApplication, QDialog, QDialogButtonBox, QFormLayout, QLineEdit

from hairdigi.app.gui.main_window import MainWindow, settings_store
from hairdigi.app.session.rig_session import open_rig

SETTING_DEFAULTS = {"camera": "0", "serial_port": "", "output_folder": str(Path.home() / "hairdigi-sessions" / "default"),
                    "hairstyle_size": 512}


def read_settings() -> dict:
    store = settings_store()
    return {k: type(v)(store.value(k, v)) for k, v in SETTING_DEFAULTS.items()}


def write_settings(values: dict) -> None:
    store = settings_store()
    for k, v in values.items():
        store.setValue(k, v)


class SettingsDialog(QDialog):
    """Camera, serial port, output folder and render defaults, kept in QSettings."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("hairdigi settings")
        form = QFormLayout(self)
        self.fields = {}
        for key, value in read_settings().items():
            self.fields[key] = QLineEdit(str(value))
            form.addRow(key.replace("_", " "), self.fields[key])
        self.fields["camera"].setToolTip("an OpenCV camera index or stream URL, or genicam (the first GenICam "
                                         "camera) or genicam:ID (arv-tool-0.8 lists the IDs); used at the next start")
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Save | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self._save)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def _save(self) -> None:
        write_settings({k: type(SETTING_DEFAULTS[k])(f.text()) for k, f in self.fields.items()})
        self.accept()


def run_app(sim: bool = False, session: str | None = None, tour: str | None = None, camera: str | None = None) -> int:
    """The window on the rig; ``camera`` (an OpenCV index or URL, or ``genicam[:ID]``) overrides the setting."""
    app = QApplication.instance() or QApplication(sys.argv[:1])
    settings = read_settings()
    folder = Path(session or settings["output_folder"])
    rig, reason = open_rig(folder, sim, camera or settings["camera"], settings["serial_port"], fallback=True)
    offscreen = os.environ.get("QT_QPA_PLATFORM") == "offscreen"
    window = MainWindow(rig, {"hairstyle_size": settings["hairstyle_size"]}, strand_view=not offscreen)
    menu = window.menuBar().addMenu("&File")
    menu.addAction("Import RAW still…", window.import_still_dialog)
    menu.addAction("Open hair model…", window.open_hair_dialog)
    menu.addAction("Settings…", lambda: SettingsDialog(window).exec())
    menu.addAction("Quit", window.close)
    window.menuBar().addMenu("&Help").addAction("About hairdigi", window.show_about)
    if reason:
        window.statusBar().showMessage(f"simulated rig: {reason}")
    window.show()
    if tour:
        from hairdigi.app.gui.tour import run_tour
        run_tour(window, tour)
    code = app.exec()
    rig.close()
    return code
