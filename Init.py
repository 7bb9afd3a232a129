# SurfMesh — App-side initialization, run by FreeCAD at start-up (with or without the GUI).
#
# Run by exec (package.xml workbench): __file__ is not defined here. The headless API is the
# Python package SurfMesh (Mod/SurfMesh/SurfMesh), importable as `import SurfMesh`.
import FreeCAD

FreeCAD.addImportType  # noqa: B018  (the module only needs FreeCAD to be up)
