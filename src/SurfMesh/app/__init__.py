"""Headless layer of SurfMesh: API, conversions, document functions, reports. Never imports
FreeCADGui or PySide."""
