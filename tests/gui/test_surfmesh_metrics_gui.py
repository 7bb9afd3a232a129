"""GUI test: element metrics in the GUI — the Quality report's metric statistics, histogram
with the threshold, CSV export and colors by a metric; the preference that makes *Measure
quality* color by a metric.

The reference values are computed here from the FEM mesh's nodes with Verdict's triangle
formulas written out (aspect ratio hmax·(a+b+c)/(4√3·A), smallest angle by the law of
cosines), not by SurfMesh.
"""

import csv
import math
import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, pixels, report_text  # noqa: E402

code = 1
try:
    import FreeCAD
    import FreeCADGui
    import numpy as np
    from PySide import QtGui

    assert FreeCAD.GuiUp
    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/View").SetBool(
        "UseNavigationAnimations", False)
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    os.makedirs(out, exist_ok=True)
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    mw = FreeCADGui.getMainWindow()

    from SurfMesh.app import examples, metric_report
    from SurfMesh.gui import legend, preferences

    preferences.set_color_by("quality")
    preferences.set_measure("shape")
    doc = FreeCAD.newDocument("SurfMeshMetricsGui")
    doc.UndoMode = 1
    tor = examples.make_torus(doc)
    mesh = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    tor.ViewObject.Visibility = False
    doc.recompute()
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()

    # ---- the reference: Verdict's formulas on the FEM nodes --------------------------------
    fem = mesh.FemMesh
    ids = sorted(fem.Faces)
    ref_aspect, ref_min_angle = {}, {}
    for e in ids:
        p = [np.array(tuple(fem.getNodeById(n))) for n in fem.getElementNodes(e)[:3]]
        a, b, c = (np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[1]),
                   np.linalg.norm(p[0] - p[2]))
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        ref_aspect[e] = max(a, b, c) * (a + b + c) / (4 * math.sqrt(3) * area)
        angles = [math.degrees(math.acos((y * y + z * z - x * x) / (2 * y * z)))
                  for x, y, z in ((a, b, c), (b, c, a), (c, a, b))]
        ref_min_angle[e] = min(angles)
    values = np.array([ref_aspect[e] for e in ids])
    t = float(np.round(np.quantile(values, 0.8), 4))
    expected_beyond = int((values > t).sum())
    check(0 < expected_beyond < len(ids), f"{expected_beyond} of {len(ids)} elements have an "
          f"aspect ratio above {t}")

    # ---- Quality report: metric statistics, histogram with the threshold, CSV ---------------
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(mesh)
    FreeCADGui.runCommand("SurfMesh_Report")
    FreeCADGui.updateGui()
    dialogs = [w for w in mw.findChildren(QtGui.QDialog, "SurfMeshReport") if w.isVisible()]
    check(len(dialogs) == 1, "the report dialog is open")
    dlg = dialogs[0]
    box = dlg.findChild(QtGui.QGroupBox, "SurfMeshMetrics")
    check(box is not None, "with its element metrics")
    dlg.show_metric("aspect_ratio")
    dlg.findChild(QtGui.QDoubleSpinBox, "threshold").setValue(t)
    FreeCADGui.updateGui()
    check(dlg.shown_metric == ("aspect_ratio", t, expected_beyond),
          f"the count beyond the threshold is the reference's ({dlg.shown_metric})")
    table = dlg.findChild(QtGui.QTextBrowser, "SurfMeshMetricTable").toPlainText()
    for label in ("Aspect ratio", "Smallest angle", "Scaled Jacobian", "Jacobian ratio",
                  "Distance to the CAD face", "Warpage"):
        check(label in table, f"the table has {label}")
    lines = [ln.strip() for ln in table.splitlines() if ln.strip()]
    row = lines[lines.index("Aspect ratio"):][:8]  # label, min, mean, max, threshold, beyond…
    check(row[1] == f"{min(values):.3f}" and row[3] == f"{max(values):.3f}"
          and row[5] == str(expected_beyond),
          f"its aspect ratio row has the reference's min, max and count ({row})")
    hist = dlg.findChild(QtGui.QLabel, "SurfMeshMetricHistogram")
    check(hist.pixmap() is not None and not hist.pixmap().isNull(), "the histogram is shown")
    shot = os.path.join(out, "gui_metric_histogram.png")
    hist.pixmap().save(shot)
    img = pixels(shot)
    red = (img[..., 0] > 0.8) & (img[..., 1] < 0.2) & (img[..., 2] < 0.2)
    cols = np.nonzero(red.sum(axis=0) > 0.4 * img.shape[0])[0]
    check(cols.size > 0, "the threshold is drawn as a red vertical line on it")

    path = os.path.join(out, "gui_metrics.csv")
    check(dlg.export_csv(path) == path and os.path.exists(path), "CSV exported")
    with open(path, newline="") as f:
        rows = {int(r["element_id"]): r for r in csv.DictReader(f)}
    check(sorted(rows) == ids, "one CSV row per element id")
    err = max(abs(float(rows[e]["aspect_ratio"]) - ref_aspect[e]) / ref_aspect[e] for e in ids)
    check(err < 1e-8, f"CSV aspect ratios equal the reference (rel. error {err:.1e})")

    # ---- color by the metric -----------------------------------------------------------------
    undo0 = doc.UndoCount
    beyond = dlg.color_by()
    FreeCADGui.updateGui()
    check(beyond == expected_beyond, f"{beyond} elements colored beyond the threshold")
    check(doc.UndoCount == undo0 + 1, "in one undo step")
    check(metric_report.colored_by(mesh) == ("aspect_ratio", t), "the mesh records what it shows")
    rgb = np.array([c[:3] for c in mesh.SurfMeshColors])
    is_red = np.all(np.isclose(rgb, metric_report.BEYOND_RGB, atol=1e-6), axis=1)
    order = [int(e) for e in ids]
    check(list(np.array(order)[is_red]) == [e for e in ids if ref_aspect[e] > t],
          "red exactly where the reference is beyond the threshold")
    legend.update(doc)
    check(legend.shown(doc) == f"SurfMesh: Aspect ratio (red: > {t:.3f})".replace(
        f"{t:.3f}", __import__("SurfMesh").app.reports.format_value(t, 3)),
        f"the color scale names the metric and threshold ({legend.shown(doc)!r})")
    dlg.close()
    FreeCADGui.Selection.clearSelection()
    shot = os.path.join(out, "gui_metric_colors.png")
    view.saveImage(shot, 800, 600, "White")
    img = pixels(shot)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red_px = ((r > 0.55) & (g < 0.15) & (b < 0.15)).mean()
    green_px = ((g > 0.45) & (r < 0.5) & (b < 0.4)).mean()
    check(red_px > 0.002 and green_px > 0.05,
          f"the view shows red and green elements ({red_px:.4f}, {green_px:.4f})")

    # ---- the preference: Measure quality colors by the smallest angle ------------------------
    preferences.set_color_by("min_angle")
    preferences.set_metric_threshold("min_angle", 40.0)
    FreeCADGui.Selection.addSelection(mesh)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    expected = [e for e in ids if ref_min_angle[e] < 40.0]
    check(metric_report.colored_by(mesh) == ("min_angle", 40.0), "Measure colors by the metric")
    rgb = np.array([c[:3] for c in mesh.SurfMeshColors])
    is_red = np.all(np.isclose(rgb, metric_report.BEYOND_RGB, atol=1e-6), axis=1)
    check(list(np.array(order)[is_red]) == expected,
          f"red where the reference angle is below 40° ({len(expected)} elements)")
    text = report_text(mw)
    check(f"colored by smallest angle: {len(expected)} element(s) < 40.000 in red" in text,
          "the report view says how many")
    preferences.set_color_by("quality")
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    legend.update(doc)
    check(metric_report.colored_by(mesh) is None and legend.shown(doc) ==
          "SurfMesh quality (shape)", "back to quality colors with the preference")

    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finally:
    try:
        from SurfMesh.gui import preferences as _p

        _p.set_color_by("quality")
    except Exception:
        pass
finish("test_surfmesh_metrics_gui", code, last=None)
