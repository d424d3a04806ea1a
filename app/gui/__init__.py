"""The PySide6 desktop app: Qt widgets over the Qt-free session in app/session/rig_session.py."""
