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
        from SurfMesh.gui.preferences import PreferencePage

        FreeCADGui.addPreferencePage(PreferencePage, "SurfMesh")
        self.appendToolbar("SurfMesh", names)
        self.appendMenu("SurfMesh", names)

    def Activated(self):
        pass

    def Deactivated(self):
        pass

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(SurfMeshWorkbench())


class _SurfMeshColorsOnOpen:
    """FreeCAD does not save the colors of a FEM mesh's view: when a document is opened, the
    FEM meshes SurfMesh colored (SurfMeshColors) get them back from their stored quality
    (SurfMesh.app.document.show_stored_colors). Runs once the document is restored; SurfMesh
    is imported only for a document that has such a mesh."""

    def slotCreatedDocument(self, doc):
        self._later(doc.Name, 0)

    def _later(self, name, tries):
        from PySide import QtCore

        QtCore.QTimer.singleShot(0 if tries == 0 else 200, lambda: self._show(name, tries))

    def _show(self, name, tries):
        import FreeCAD

        doc = FreeCAD.listDocuments().get(name)
        if doc is None:
            return
        if getattr(doc, "Restoring", False):  # still being read
            if tries < 3000:
                self._later(name, tries + 1)
            return
        objs = [o for o in doc.Objects
                if "SurfMeshColors" in o.PropertiesList and "FemMesh" in o.PropertiesList]
        if not objs:
            return
        from SurfMesh.app.document import show_stored_colors

        for obj in objs:
            try:
                show_stored_colors(obj)
            except Exception as exc:  # a damaged property: the document still opens
                FreeCAD.Console.PrintWarning(f"SurfMesh: {obj.Label}: colors not shown: {exc}\n")


import FreeCAD as _App  # noqa: E402

_App.addDocumentObserver(_SurfMeshColorsOnOpen())
