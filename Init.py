# SurfMesh — App-side initialization, run by FreeCAD at start-up (with or without the GUI).
#
# Run by exec (package.xml workbench): __file__ is not defined here. Nothing is needed at
# start-up: the headless API is the package SurfMesh (Mod/SurfMesh/SurfMesh), imported on
# demand with `import SurfMesh`; the test suites are run by scripts/test.sh.
