# SurfMesh — GUI initialization, run by FreeCAD at start-up with the GUI.
#
# Run by exec (package.xml workbench): __file__ is not defined here, so the icon paths come
# from the imported package (SurfMesh.paths).
import FreeCADGui


class SurfMeshWorkbench(FreeCADGui.Workbench):
    """Measure, smooth and untangle surface meshes on CAD surfaces."""

    MenuText = "SurfMesh"
    ToolTip = "Quality, smoothing and untangling of surface meshes (Mesh and FEM) on CAD shapes"

    def __init__(self):
        from SurfMesh import paths

        self.__class__.Icon = paths.icon("SurfMesh")

    def Initialize(self):
        from SurfMesh.gui import commands

        names = commands.register()
        self.appendToolbar("SurfMesh", names)
        self.appendMenu("SurfMesh", names)

    def Activated(self):
        pass

    def Deactivated(self):
        pass

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(SurfMeshWorkbench())
