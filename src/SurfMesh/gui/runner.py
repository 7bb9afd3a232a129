"""Running a headless call through FreeCADGui.doCommand (so the Python console shows the line
to replay in freecadcmd) and reporting errors to the user."""

from __future__ import annotations

import __main__

import FreeCAD
import FreeCADGui

RESULT = "_surfmesh_result"


def run(expression: str, title: str = "SurfMesh"):
    """Runs ``_surfmesh_result = <expression>`` through doCommand and returns its value.
    Exceptions are re-raised (the console shows them as well). Meanwhile the cursor is busy
    and the status bar names the stage the run is in."""
    from PySide import QtCore, QtGui

    from SurfMesh.app import progress

    bar = FreeCADGui.getMainWindow().statusBar()

    def stage(text):
        bar.showMessage(f"{title}: {text}…")
        QtGui.QApplication.processEvents(QtCore.QEventLoop.ExcludeUserInputEvents)

    FreeCADGui.addModule("SurfMesh")
    setattr(__main__, RESULT, None)
    QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
    try:
        with progress.stage_hook(stage):
            FreeCADGui.doCommand(f"{RESULT} = {expression}")
    finally:
        QtGui.QApplication.restoreOverrideCursor()
        bar.clearMessage()
    return getattr(__main__, RESULT, None)


def show_error(title: str, exc: BaseException):
    FreeCAD.Console.PrintError(f"{title}: {exc}\n")
    try:
        from PySide import QtGui

        QtGui.QMessageBox.warning(FreeCADGui.getMainWindow(), title, str(exc))
    except Exception:
        pass
