"""The base every layer writes and reads through: atomic files and JSON (``files``), images (``images``),
figures and tables (``figures``)."""
