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
        import os

        from SurfMesh import paths
        from SurfMesh.gui.preferences import PreferencePage

        # the preference dialog's icon of the group "SurfMesh": preferences-surfmesh.svg
        FreeCADGui.addIconPath(os.path.join(paths.resources_dir(), "icons"))

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


class _SurfMeshViewObserver:
    """Keeps SurfMesh's colors in the 3D views:
    - FreeCAD does not save the colors of a FEM mesh's view: when a document is opened, the
      FEM meshes SurfMesh colored (SurfMeshColors) get them back from their stored quality
      (SurfMesh.app.document.show_stored_colors), once the document is restored;
    - the color scales (SurfMesh.gui.legend) are shown while visible meshes of the document
      show SurfMesh's colors, one per coloring, naming its meshes.
    SurfMesh is imported only for documents that have such meshes."""

    def __init__(self):
        self._pending = {}  # document name -> what its coming update does besides the scale

    def slotCreatedDocument(self, doc):
        self._later(doc.Name, "opened")

    def slotDeletedDocument(self, doc):
        if "SurfMesh.gui.legend" in sys.modules:
            sys.modules["SurfMesh.gui.legend"]._nodes.pop(doc.Name, None)
        if "SurfMesh.app.document" in sys.modules:
            sys.modules["SurfMesh.app.document"]._FEM_COLORED.pop(doc.Name, None)

    def slotUndoDocument(self, doc):
        self._later(doc.Name, "undone")

    def slotRedoDocument(self, doc):
        self._later(doc.Name, "undone")

    # What the color scales show: the colors, what they are by (measure, metric, threshold),
    # which meshes are shown, and their names.
    _SHOWN = ("SurfMeshColors", "SurfMeshColorBy", "SurfMeshThreshold", "SurfMeshMeasure",
              "Visibility", "Label")

    def slotChangedObject(self, obj, prop):
        if prop in self._SHOWN:
            self._touched(obj)

    def slotRemoveDynamicProperty(self, obj, prop):
        if prop in ("SurfMeshColors", "SurfMeshColorBy", "SurfMeshThreshold"):
            self._touched(obj, colored=True)

    def slotDeletedObject(self, obj):
        self._touched(obj)

    def _touched(self, obj, colored=False):
        try:
            if colored or "SurfMeshColors" in obj.PropertiesList:
                self._later(obj.Document.Name, None)
        except Exception:  # an object on its way out: nothing to show
            pass

    def _later(self, name, what):
        """One update per document for a burst of changes, after FreeCAD has finished them
        ("opened": the FEM views get their stored colors once the document is restored;
        "undone": the FEM views follow the document after an undo or a redo)."""
        from PySide import QtCore

        first = name not in self._pending
        whats = self._pending.setdefault(name, set())
        if what:
            whats.add(what)
        if first:
            QtCore.QTimer.singleShot(0, lambda: self._update(name, 0))

    def _update(self, name, tries):
        import FreeCAD
        from PySide import QtCore

        doc = FreeCAD.listDocuments().get(name)
        if doc is None:
            self._pending.pop(name, None)
            return
        if getattr(doc, "Restoring", False):  # still being read
            if tries < 3000:
                QtCore.QTimer.singleShot(200, lambda: self._update(name, tries + 1))
            else:
                self._pending.pop(name, None)
            return
        whats = self._pending.pop(name, set())
        opened = "opened" in whats
        undone = "undone" in whats and "SurfMesh.app.document" in sys.modules
        objs = [o for o in doc.Objects if "SurfMeshColors" in o.PropertiesList]
        if not objs and not undone and "SurfMesh.gui.legend" not in sys.modules:
            return
        try:
            if undone:
                sys.modules["SurfMesh.app.document"].sync_view_colors(doc)
            elif opened:
                from SurfMesh.app.document import show_stored_colors

                for obj in objs:
                    if "FemMesh" in obj.PropertiesList:
                        show_stored_colors(obj)
            from SurfMesh.gui import legend

            legend.update(doc)
        except Exception as exc:  # a damaged property: the document still opens
            FreeCAD.Console.PrintWarning(f"SurfMesh: {name}: colors not shown: {exc}\n")


import sys  # noqa: E402

import FreeCAD as _App  # noqa: E402

_App.addDocumentObserver(_SurfMeshViewObserver())
