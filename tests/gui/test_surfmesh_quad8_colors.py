"""GUI test: a quad8 FEM mesh (FreeCAD's femexamples.ccx_cantilever_ele_quad8 with one side
node bent past its side's end, folding two elements) is colored by quality in the 3D view:
purple where the elements fold, and after Optimize no purple, the plate's 8:1 elements in the
poor (red) end of the scale. Exit code 0 = pass (tests/gui/README.md)."""

import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, pixels  # noqa: E402

code = 1


def shares(img):
    """Shares of purple (tangled) and red (poor) among the colored pixels of a screenshot
    (white background, dark edges and the color scale at the left excluded)."""
    import numpy as np

    img = img[:, int(0.22 * img.shape[1]):]
    a = img.reshape(-1, 3)
    a = a[(a.sum(axis=1) < 2.85) & (a.max(axis=1) > 0.15)]
    if len(a) == 0:
        return 0, 0.0, 0.0
    r, g, b = a.T
    purple = float(np.mean((b > 1.2 * g) & (r > 1.2 * g)))
    red = float(np.mean((r > 1.5 * g) & (r > 1.5 * b)))
    return len(a), purple, red


try:
    import FreeCAD
    import FreeCADGui
    import Fem
    import Part

    assert FreeCAD.GuiUp
    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/View").SetBool(
        "UseNavigationAnimations", False)
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    import SurfMesh
    from femexamples import ccx_cantilever_ele_quad8 as ex

    doc = ex.setup()
    doc.recompute()
    mesh = [o for o in doc.Objects if o.isDerivedFrom("Fem::FemMeshObject")][0]
    part = [o for o in doc.Objects if isinstance(getattr(o, "Shape", None), Part.Shape)
            and o.Shape.Faces and o is not mesh][0]  # (in 1.x some FEM objects' Shape is none)
    fem = mesh.FemMesh
    side = (set(fem.getElementNodes(1)[4:]) & set(fem.getElementNodes(4)[4:])).pop()
    bent = Fem.FemMesh()
    for nid, p in fem.Nodes.items():
        q = p + FreeCAD.Vector(0, 0, 400) if nid == side else p
        bent.addNode(q.x, q.y, q.z, nid)
    for f in fem.Faces:
        bent.addFace(list(fem.getElementNodes(f)), f)
    obj = doc.addObject("Fem::FemMeshObject", "Bent")
    obj.FemMesh = bent
    mesh.ViewObject.Visibility = False
    part.ViewObject.Visibility = False
    for o in doc.Objects:
        if o is not obj and hasattr(o, "ViewObject") and o.ViewObject is not None:
            o.ViewObject.Visibility = False
    doc.recompute()

    def shot(name):
        """Shares of the view from the side the mesh faces (the other side is culled while
        no element is tangled)."""
        view = FreeCADGui.ActiveDocument.ActiveView
        best = None
        for side, turn in (("front", view.viewFront), ("rear", view.viewRear)):
            turn()
            view.fitAll()
            FreeCADGui.updateGui()
            path = os.path.join(out, f"{side}_{name}")
            view.saveImage(path, 800, 600, "White")
            got = shares(pixels(path))
            if best is None or got[0] > best[0]:
                best = got
        return best

    rep = SurfMesh.measure_object(obj, part)
    check(rep.stats["invalid"] == 2, f"two quad8 folded ({rep!r})")
    n, purple, red = shot("quad8_bent.png")
    check(n > 5000, f"the quad8 mesh is drawn ({n} colored pixels)")
    check(purple > 0.05, f"folded quad8 drawn purple ({purple:.3f} of the colored pixels)")
    new = SurfMesh.optimize_object(obj, part)  # hides the original
    check(new.ViewObject.Visibility and not obj.ViewObject.Visibility, "the result is shown")
    check(new.SurfMeshStats["invalid"] == "0", f"optimized: none invalid ({new.SurfMeshStats})")
    n2, purple2, red2 = shot("quad8_optimized.png")
    check(n2 > 5000, f"the optimized quad8 mesh is drawn ({n2} colored pixels)")
    check(purple2 < 0.005, f"no purple after optimizing ({purple2:.4f})")
    check(red2 > 0.5, f"8:1 quad8 (quality 0.25) drawn in the poor, red end ({red2:.3f})")
    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_quad8_colors", code)
