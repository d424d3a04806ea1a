"""``hairdigi app``: open the main window on the rig, or on the simulated rig when none is found."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from PySide6.QtWidgets import QApplication, QComboBox, QDialog, QDialogButtonBox, QFormLayout, QLineEdit

from hairdigi.app.gui.main_window import MainWindow, settings_store
from hairdigi.app.gui.tour import run_tour
from hairdigi.app.session.profile import ProfileError, RigProfile, merged, profile_path, read_profile, write_profile
from hairdigi.app.session.rig_session import open_rig
from hairdigi.app.session.declared_spectra import rig_spectra, spectra_problem
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, STRUCTURE_MODES, StructureMode

SETTING_DEFAULTS = {"camera": "0", "serial_port": "", "output_folder": str(Path.home() / "hairdigi-sessions" / "default"),
                    "hairstyle_size": 512, "led": "", "sensor": "", "structure": str(DEFAULT_STRUCTURE)}


#: Settings picked from a list, not typed.
CHOICES = {"structure": STRUCTURE_MODES}


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
            default = str(SETTING_DEFAULTS[key])
            self.fields[key] = _choice(CHOICES[key], str(value), default) if key in CHOICES else QLineEdit(str(value))
            form.addRow(key.replace("_", " "), self.fields[key])
        self.fields["led"].setToolTip("the rig's LEDs: a named light or a CSV of wavelength (nm), power; with the "
                                      "sensor, each capture is read in the camera's RGB (as hairdigi app --led)")
        self.fields["sensor"].setToolTip("the camera's sensitivities: a named camera, cie, or a CSV of wavelength "
                                         "(nm), r, g, b (as hairdigi app --sensor); used at the next start")
        self.fields["structure"].setToolTip("how estimates treat the swatch's physical structure: assumed (hairdigi's "
                                            "layered swatch, the default), family (for a lab's swatches, built another "
                                            "way: the structure read decisively, else the mean of those its texture "
                                            "shows) or read (as "
                                            "hairdigi app --structure; hairdigi evaluate --structures measures each); "
                                            "used at the next start")
        self.fields["camera"].setToolTip("an OpenCV camera index or stream URL, or genicam (the first GenICam "
                                         "camera) or genicam:ID (arv-tool-0.8 lists the IDs); used at the next start")
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Save | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self._save)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def _save(self) -> None:
        write_settings({k: type(SETTING_DEFAULTS[k])(f.currentText() if isinstance(f, QComboBox) else f.text())
                        for k, f in self.fields.items()})
        self.accept()


def _choice(options: tuple[str, ...], value: str, default: str) -> QComboBox:
    """A list to pick one of ``options`` from, showing ``value`` (``default``, when not one of them)."""
    box = QComboBox()
    box.addItems(list(options))
    found = box.findText(value)
    box.setCurrentIndex(found if found >= 0 else max(0, box.findText(default)))
    return box


def declared_spectra(settings: dict, led: str | None, sensor: str | None) -> tuple[str | None, str | None, str | None]:
    """A real rig's LEDs and camera: ``led`` and ``sensor`` when given (then remembered in the settings),
    else the settings'; and why the settings' are not used (a pair half given, an unknown or unreadable
    spectrum), or None."""
    if led is not None or sensor is not None:
        write_settings({"led": led or "", "sensor": sensor or ""})
        return led, sensor, None
    led, sensor = settings["led"] or None, settings["sensor"] or None
    problem = spectra_problem(led, sensor)
    if problem is not None:
        return None, None, f"the settings' led and sensor are not used: {problem}"
    return led, sensor, None


def chosen_structure(settings: dict, structure: str | None) -> tuple[str, str | None]:
    """How estimates treat the swatch's structure: ``structure`` when given (then remembered in the settings),
    else the settings'; and why the settings' is not used (not a mode), or None."""
    if structure is not None:
        write_settings({"structure": structure})
        return structure, None
    if settings["structure"] in STRUCTURE_MODES:
        return settings["structure"], None
    return str(DEFAULT_STRUCTURE), (f"the settings' structure {settings['structure']!r} is not one of "
                                    f"{', '.join(STRUCTURE_MODES)}; '{DEFAULT_STRUCTURE}' is used (Settings > structure)")


def session_rig(folder: Path, settings: dict, sim: bool, led: str | None, sensor: str | None,
                structure: str | None) -> tuple[str | None, str | None, StructureMode, str | None]:
    """The rig the app runs: the session's rig profile (``app.session.profile``), each flag given overriding it for
    this run; without a profile, the flags or the settings, kept as the session's profile (declared once).
    Returns (led, sensor, structure, the status line: the profile read, its overrides and problems; or None)."""
    try:
        kept = read_profile(folder)
    except ProfileError as exc:            # a damaged profile is said, and the settings stand in this once
        kept, damaged = None, str(exc)
    else:
        damaged = None
    if kept is not None:                   # the session's rig profile, each flag overriding it for this run
        profile, notices = merged(kept, {"sensitivities": sensor, "led": led, "structure": structure})
        led, sensor, structure = profile.led, profile.sensitivities, profile.structure
        spectra = None if sim else spectra_problem(led, sensor)
        problem, wrong = "; ".join(filter(None, [f"rig profile {profile_path(folder)}", *notices, spectra])), None
    else:
        problem = None
        if not sim:
            led, sensor, problem = declared_spectra(settings, led, sensor)
        structure, wrong = chosen_structure(settings, structure)
        if damaged is None and not problem and not wrong:    # declared once: the session keeps what this run uses
            folder.mkdir(parents=True, exist_ok=True)
            write_profile(folder, RigProfile(None if sim else sensor, None if sim else led, structure))
    problem = "; ".join(filter(None, [damaged, problem, wrong])) or None
    return led, sensor, StructureMode(structure), problem


def run_app(sim: bool = False, session: str | None = None, tour: str | None = None, camera: str | None = None,
            spectral: bool = False, led: str | None = None, sensor: str | None = None,
            structure: str | None = None) -> int:
    """The window on the rig; ``camera`` (an OpenCV index or URL, or ``genicam[:ID]``) overrides the setting.
    ``led`` and ``sensor``: a real rig's declared spectra (remembered), or with ``sim`` and ``spectral``
    the simulated spectral rig's (``session.spectra.rig_spectra``); ``structure``, how estimates treat the
    swatch's physical structure (remembered). A session with a rig profile (``app.session.profile``) runs as it
    declares, a flag overriding it for this run (said in the status bar); a session without one keeps what this
    run uses as its profile."""
    app = QApplication.instance() or QApplication(sys.argv[:1])
    settings = read_settings()
    folder = Path(session or settings["output_folder"])
    led, sensor, structure, problem = session_rig(folder, settings, sim, led, sensor, structure)
    simulated, spectra = rig_spectra(sim, spectral, led, sensor)
    rig, reason = open_rig(folder, sim, camera or settings["camera"], settings["serial_port"], fallback=True,
                           spectra=spectra, structure=structure, **simulated)
    offscreen = os.environ.get("QT_QPA_PLATFORM") == "offscreen"
    window = MainWindow(rig, {"hairstyle_size": settings["hairstyle_size"]}, strand_view=not offscreen)
    menu = window.menuBar().addMenu("&File")
    menu.addAction("Import RAW still…", window.import_still_dialog)
    menu.addAction("Open hair model…", window.open_hair_dialog)
    menu.addAction("Settings…", lambda: SettingsDialog(window).exec())
    menu.addAction("Quit", window.close)
    window.menuBar().addMenu("&Help").addAction("About hairdigi", window.show_about)
    if reason or problem:
        window.statusBar().showMessage("; ".join(filter(None, [reason and f"simulated rig: {reason}", problem])))
    window.show()
    if tour:
        run_tour(window, tour)
    code = app.exec()
    rig.close()
    return code
