"""Hair-dye development in the app: the Dye panel's model."""
