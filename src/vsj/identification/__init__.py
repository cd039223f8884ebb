"""Characterisation: fitting the report's models to measurement files (section 4)."""
