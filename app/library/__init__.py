"""The swatch library: its store, import of sessions and records, the colours it finds by, and its panel's model."""
