"""hairdigi: hardware."""
