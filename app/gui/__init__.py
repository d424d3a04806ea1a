"""The PySide6 desktop app: Qt widgets over the Qt-free session in app/rig_session.py."""
