"""The report dialog: statistics table (HTML) and the histogram image of the quality measures,
then the element metrics (SurfMesh.metrics): per-metric statistics with the count beyond a
threshold, the histogram of the metric chosen with its threshold, colors by that metric and
CSV export."""

from __future__ import annotations

import os
import tempfile

import FreeCADGui
from PySide import QtCore, QtGui

_open_dialogs = []


def show_report(label, report, modal=False, metric_report=None, mesh=None):
    """Shows a non-modal dialog with the report of SurfMesh.app.document.report_object and,
    when given, the MetricReport of SurfMesh.app.metric_report for mesh object ``mesh``."""
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
    if mesh is not None:
        from SurfMesh.app import notes

        told = notes.details(mesh)
        if told:
            box = QtGui.QGroupBox("Notes on reading the mesh (details)", dlg)
            box.setObjectName("SurfMeshNotes")
            blay = QtGui.QVBoxLayout(box)
            items = QtGui.QListWidget(box)
            items.setObjectName("SurfMeshNotesList")
            items.setWordWrap(True)
            items.addItems(told)
            items.setMaximumHeight(110)
            blay.addWidget(items)
            lay.addWidget(box)
    if metric_report is not None:
        lay.addWidget(_metrics_box(dlg, metric_report, mesh))
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


def _metrics_box(dlg, rep, mesh):
    """The element metrics part of the dialog. Sets on ``dlg``: ``show_metric(name)``,
    ``export_csv(path)`` and ``color_by()`` (what its widgets do, for scripts and tests)."""
    from SurfMesh.app import metric_report, metrics
    from SurfMesh.gui import preferences, runner, selection

    box = QtGui.QGroupBox("Element metrics (FEM checks)", dlg)
    box.setObjectName("SurfMeshMetrics")
    lay = QtGui.QVBoxLayout(box)
    row = QtGui.QHBoxLayout()
    combo = QtGui.QComboBox(box)
    combo.setObjectName("metric")
    for name in rep.values:
        combo.addItem(metrics.METRICS[name]["label"], name)
    threshold = QtGui.QDoubleSpinBox(box)
    threshold.setObjectName("threshold")
    threshold.setDecimals(4)
    threshold.setRange(-1e12, 1e12)
    threshold.setToolTip("Elements worse than this count as beyond it (red)")
    row.addWidget(QtGui.QLabel("Metric", box))
    row.addWidget(combo, 1)
    row.addWidget(QtGui.QLabel("Threshold", box))
    row.addWidget(threshold)
    color = QtGui.QPushButton("Color by this metric", box)
    color.setObjectName("colorByMetric")
    export = QtGui.QPushButton("Export CSV…", box)
    export.setObjectName("exportCsv")
    row.addWidget(color)
    row.addWidget(export)
    lay.addLayout(row)
    table = QtGui.QTextBrowser(box)
    table.setObjectName("SurfMeshMetricTable")
    table.setMinimumHeight(160)
    lay.addWidget(table)
    hist = QtGui.QLabel(box)
    hist.setObjectName("SurfMeshMetricHistogram")
    hist.setAlignment(QtCore.Qt.AlignCenter)
    lay.addWidget(hist)
    thresholds = {}
    png = os.path.join(tempfile.gettempdir(), f"surfmesh_metric_{os.getpid()}_{id(dlg)}.png")

    def refresh():
        name = combo.currentData()
        t = threshold.value()
        thresholds[name] = t
        table.setHtml(rep.table_html(thresholds))
        rep.save_histogram(png, name, t)
        hist.setPixmap(QtGui.QPixmap(png))
        dlg.shown_metric = (name, t, rep.stats(name, t)["beyond"])

    def show_metric(name):
        if combo.findData(name) < 0:
            raise ValueError(f"unknown metric {name!r}")
        if combo.currentData() == name:
            on_metric()
        combo.setCurrentIndex(combo.findData(name))

    def on_metric(*_):
        name = combo.currentData()
        t = thresholds.get(name, preferences.metric_threshold(name))
        if t is None:
            t = metric_report.default_threshold(name, rep.values[name])
        threshold.blockSignals(True)
        threshold.setValue(t)
        threshold.blockSignals(False)
        refresh()

    def export_csv(path=None):
        if path is None:
            path, _ = QtGui.QFileDialog.getSaveFileName(
                dlg, "Export the element metrics", f"{rep.label}_metrics.csv",
                "CSV files (*.csv)")
            if not path:
                return None
        rep.write_csv(path)
        return path

    def color_by():
        if mesh is None:
            return None
        name, t = combo.currentData(), threshold.value()
        preferences.set_metric_threshold(name, t)
        args = selection.object_ref(mesh)
        try:
            return runner.run(f"SurfMesh.app.metric_report.color_by_metric({args}, {name!r}, "
                              f"{t!r})")
        except Exception as exc:
            runner.show_error("SurfMesh: color by metric", exc)
            return None

    combo.currentIndexChanged.connect(on_metric)
    threshold.valueChanged.connect(lambda *_: refresh())
    export.clicked.connect(lambda: export_csv())
    color.clicked.connect(color_by)
    color.setEnabled(mesh is not None)
    dlg.show_metric, dlg.export_csv, dlg.color_by = show_metric, export_csv, color_by
    start = preferences.color_by()
    combo.setCurrentIndex(max(combo.findData(start), 0))
    on_metric()
    return box
