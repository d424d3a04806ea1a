"""hairdigi: app."""
