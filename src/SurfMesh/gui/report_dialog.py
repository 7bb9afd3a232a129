"""The report dialog: statistics table (HTML) and the histogram image."""

from __future__ import annotations

import FreeCADGui
from PySide import QtCore, QtGui

_open_dialogs = []


def show_report(label, report, modal=False):
    """Shows a non-modal dialog with the report of SurfMesh.app.document.report_object."""
    dlg = QtGui.QDialog(FreeCADGui.getMainWindow())
    dlg.setWindowTitle(f"SurfMesh report: {label}")
    dlg.setObjectName("SurfMeshReport")
    lay = QtGui.QVBoxLayout(dlg)
    table = QtGui.QTextBrowser(dlg)
    table.setObjectName("SurfMeshReportTable")
    table.setHtml(report["html"])
    table.setMinimumHeight(140)
    lay.addWidget(table)
    if report.get("histogram"):
        img = QtGui.QLabel(dlg)
        img.setObjectName("SurfMeshReportHistogram")
        img.setPixmap(QtGui.QPixmap(report["histogram"]))
        img.setAlignment(QtCore.Qt.AlignCenter)
        lay.addWidget(img)
    buttons = QtGui.QDialogButtonBox(QtGui.QDialogButtonBox.Close, parent=dlg)
    buttons.rejected.connect(dlg.close)
    lay.addWidget(buttons)
    dlg.setAttribute(QtCore.Qt.WA_DeleteOnClose)
    _open_dialogs.append(dlg)
    dlg.destroyed.connect(lambda *_: _open_dialogs.remove(dlg) if dlg in _open_dialogs else None)
    if modal:
        dlg.exec_()
    else:
        dlg.show()
    return dlg
