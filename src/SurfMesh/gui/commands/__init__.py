"""FreeCAD commands of the SurfMesh workbench (one class per file)."""

COMMANDS = [
    "SurfMesh_Measure",
    "SurfMesh_SelectTangled",
    "SurfMesh_Optimize",
    "SurfMesh_Report",
    "SurfMesh_ClearColors",
]


def register():
    """Registers every command with FreeCADGui.addCommand."""
    import FreeCADGui

    from SurfMesh.gui.commands.clear_colors import ClearColorsCommand
    from SurfMesh.gui.commands.measure import MeasureCommand
    from SurfMesh.gui.commands.optimize import OptimizeCommand
    from SurfMesh.gui.commands.report import ReportCommand
    from SurfMesh.gui.commands.select_tangled import SelectTangledCommand

    FreeCADGui.addCommand("SurfMesh_Measure", MeasureCommand())
    FreeCADGui.addCommand("SurfMesh_SelectTangled", SelectTangledCommand())
    FreeCADGui.addCommand("SurfMesh_Optimize", OptimizeCommand())
    FreeCADGui.addCommand("SurfMesh_Report", ReportCommand())
    FreeCADGui.addCommand("SurfMesh_ClearColors", ClearColorsCommand())
    return COMMANDS
