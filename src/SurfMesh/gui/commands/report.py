"""SurfMesh_Report: the paper-style statistics table and the quality histogram (before/after
for an optimized mesh)."""

from __future__ import annotations

import os
import tempfile

from SurfMesh import paths
from SurfMesh.gui import runner, selection


class ReportCommand:
    def GetResources(self):
        return {
            "Pixmap": paths.icon("SurfMesh_Report"),
            "MenuText": "Quality report",
            "ToolTip": "Shows the quality statistics of the selected mesh for every measure "
            "(min, max, mean, std. dev., tangled elements; before and after for an optimized "
            "mesh), a histogram of the element quality, and the element metrics FEM checks use "
            "(aspect ratio, angles, Jacobian ratio, warpage…) with a threshold, their "
            "histogram, colors and CSV export.",
        }

    def IsActive(self):
        return selection.one_mesh_selected()

    def Activated(self):
        mesh, shape = selection.selected_mesh_or_say()
        if mesh is None:
            return
        png = os.path.join(tempfile.gettempdir(), f"surfmesh_report_{mesh.Name}.png")
        args = selection.call_arguments(mesh, shape, shape_keyword=True) + f", histogram={png!r}"
        try:
            report = runner.run(f"SurfMesh.app.document.report_object({args})")
            metrics = runner.run("SurfMesh.app.metric_report.metric_report("
                                 f"{selection.call_arguments(mesh, shape, shape_keyword=True)})")
        except Exception as exc:
            runner.show_error("SurfMesh: report", exc)
            return
        from SurfMesh.gui.report_dialog import show_report

        show_report(mesh.Label, report, metric_report=metrics, mesh=mesh)
