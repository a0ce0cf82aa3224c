"""Data shipped with the package: the built-in part job (part.gcode; see tests/data/part/SOURCES.md)."""
