"""What the GUI test scripts share. Each script runs as its own FreeCAD GUI process (see
README.md) and imports this module after putting tests/gui on sys.path:

    sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
    from gui_testing import check, finish

The checks made so far, screenshots as pixels, the message boxes the GUI opens (closed as they
open, their texts kept), the report view's text, and the verdict line with the exit code.
"""

import os
import sys

#: What was checked, in order (the verdict line shows the last few).
checks = []

# FreeCAD 1.x animates camera moves (fit all, standard views) by default: a view read right
# after one would show where the animation is, not where it goes. The tests see the end.
try:
    import FreeCAD

    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/View").SetBool(
        "UseNavigationAnimations", False)
except ImportError:
    pass


def check(cond, what):
    """Records ``what`` when ``cond`` holds; raises AssertionError(what) otherwise."""
    if not cond:
        raise AssertionError(what)
    checks.append(what)


def pixels(path):
    """(H, W, 3) float RGB of a PNG screenshot."""
    import matplotlib.image as mpimg

    return mpimg.imread(path)[..., :3]


def show_task_panel(mw):
    """Shows the task panel's dock: FreeCAD 1.1 keeps its "Tasks" dock in an overlay that a
    fresh configuration under Xvfb leaves hidden (0.20 and 1.0 show the Combo View's Tasks tab).
    The tests look at and press what the panel shows."""
    from PySide import QtGui

    for dock in mw.findChildren(QtGui.QDockWidget, "Tasks"):
        if not dock.isVisible():
            dock.setFloating(True)
            dock.show()
            dock.raise_()


def reopen(doc, path):
    """Saves ``doc`` as ``path``, closes it and opens it again (the GUI given time to show it);
    returns the document opened."""
    import FreeCAD
    import FreeCADGui

    doc.saveAs(path)
    FreeCAD.closeDocument(doc.Name)
    doc = FreeCAD.openDocument(path)
    for _ in range(5):
        FreeCADGui.updateGui()
    return doc


def report_text(mw):
    """Everything the report view of main window ``mw`` shows (its messages arrive as posted
    events: the GUI is updated first)."""
    import FreeCADGui
    from PySide import QtGui

    FreeCADGui.updateGui()
    edits = [w for w in mw.findChildren(QtGui.QTextEdit) if "Report" in w.objectName()]
    return "\n".join(w.toPlainText() for w in edits)


class MessageBoxCloser:
    """Closes the modal message boxes the GUI opens for errors, keeping their texts."""

    def __init__(self):
        from PySide import QtCore

        self.texts = []
        self.timer = QtCore.QTimer()
        self.timer.setInterval(20)
        self.timer.timeout.connect(self.tick)
        self.timer.start()

    def tick(self):
        from PySide import QtGui

        w = QtGui.QApplication.activeModalWidget()
        if isinstance(w, QtGui.QMessageBox):
            self.texts.append(w.text())
            w.accept()

    def stop(self):
        self.timer.stop()


def finish(name, code, last=5):
    """Prints the verdict line (PASS/FAIL, how many checks, the last ``last`` of them; all
    when None) and quits at once with ``code`` (tests/gui/README.md: FreeCAD would otherwise
    keep its window open)."""
    shown = checks if last is None else checks[-last:]
    print(f"{name}: {'PASS' if code == 0 else 'FAIL'} ({len(checks)} checks: "
          f"{'; '.join(shown)})", flush=True)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
