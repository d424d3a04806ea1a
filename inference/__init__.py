"""hairdigi: inference."""
