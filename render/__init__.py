"""hairdigi: render."""
