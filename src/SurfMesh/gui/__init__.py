"""GUI layer of SurfMesh: commands, task panels, report dialog. The only part of the package
that imports FreeCADGui or PySide."""
