"""Running a headless call through FreeCADGui.doCommand (so the Python console shows the line
to replay in freecadcmd) and reporting errors to the user."""

from __future__ import annotations

import __main__

import FreeCAD
import FreeCADGui

RESULT = "_surfmesh_result"


def run(expression: str, title: str = "SurfMesh"):
    """Runs ``_surfmesh_result = <expression>`` through doCommand and returns its value.
    Exceptions are re-raised (the console shows them as well)."""
    FreeCADGui.addModule("SurfMesh")
    setattr(__main__, RESULT, None)
    FreeCADGui.doCommand(f"{RESULT} = {expression}")
    return getattr(__main__, RESULT, None)


def show_error(title: str, exc: BaseException):
    FreeCAD.Console.PrintError(f"{title}: {exc}\n")
    try:
        from PySide import QtGui

        QtGui.QMessageBox.warning(FreeCADGui.getMainWindow(), title, str(exc))
    except Exception:
        pass
