"""GUI test: a document made without the GUI (freecadcmd: a tangled FEM mesh and a tangled
Mesh of a torus, both optimized with SurfMesh.optimize_object, saved) opened in the GUI shows
every mesh: the optimized ones are drawn (pixels on screen) and take their quality colors.

FreeCAD 0.20 draws a plain Fem::FemMeshObject made headless as nothing once its file is opened
in the GUI; the optimized FEM mesh must not be one. Exit code 0 = pass (tests/gui/README.md)."""

import os
import subprocess
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish  # noqa: E402

code = 1


HEADLESS = r'''
import sys
import FreeCAD, Mesh, MeshPart, SurfMesh
from SurfMesh.app import examples
path = sys.argv[-1]
doc = FreeCAD.newDocument("Headless")
tor = examples.make_torus(doc)
fem = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusFem")
examples.tangle_to(fem, tor.Shape, target=20, seed=3)
SurfMesh.optimize_object(fem, tor)
tri = doc.addObject("Mesh::Feature", "TorusTri")
tri.Mesh = MeshPart.meshFromShape(Shape=tor.Shape, LinearDeflection=0.2)
SurfMesh.optimize_object(tri, tor)
doc.recompute()
doc.saveAs(path)
print("saved", path, [o.Name for o in doc.Objects], flush=True)
'''

try:
    import FreeCAD
    import FreeCADGui
    import matplotlib.image as mpimg
    import numpy as np

    import SurfMesh

    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "headless.FCStd")
    script = os.path.join(out, "make_headless.py")
    with open(script, "w") as f:
        f.write(HEADLESS)
    if os.path.exists(path):
        os.remove(path)
    # "--": FreeCAD 1.x opens every further argument as a file of its own
    p = subprocess.run(["freecadcmd", script, "--", path], capture_output=True, text=True,
                       timeout=300, stdin=subprocess.DEVNULL)
    saved = os.path.exists(path)
    check(saved, "freecadcmd saved the document" if saved else
          f"freecadcmd did not save the document (exit {p.returncode}): {p.stderr[-500:]}")

    doc = FreeCAD.openDocument(path)
    fem_new = doc.getObject("TorusFem_optimized")
    tri_new = doc.getObject("TorusTri_optimized")
    check(fem_new is not None and tri_new is not None, "optimized objects in the file")
    check(SurfMesh.stats_of(fem_new)["tangled"] == 0, "FEM mesh optimized headless, untangled")
    view = FreeCADGui.getDocument(doc.Name).ActiveView

    def shot(obj, tag):
        for o in doc.Objects:
            o.ViewObject.Visibility = o is obj
        view.viewIsometric()
        view.fitAll()
        FreeCADGui.updateGui()
        p = os.path.join(out, f"headless_{tag}.png")
        view.saveImage(p, 800, 600, "White")
        img = mpimg.imread(p)[..., :3].reshape(-1, 3)
        drawn = img[(img.sum(axis=1) < 2.85) & (img.max(axis=1) > 0.15)]
        share = len(drawn) / len(img)
        r, g, b = drawn.T if len(drawn) else (np.zeros(1),) * 3
        # Quality colors: green (good) and yellow to red (fair to poor); the default views are
        # grey (Mesh) and orange-yellow shaded (FEM) — checked on the uncolored views below.
        colored = ((g > 1.25 * r) & (g > 1.25 * b)) | ((r > 0.8 * g) & (g > 1.5 * b))
        return share, float(np.mean(colored)) if len(drawn) else 0.0

    for obj, tag in ((doc.getObject("TorusFem"), "fem_input"), (fem_new, "fem_optimized"),
                     (tri_new, "mesh_optimized")):
        SurfMesh.clear_colors(obj)
        share, _ = shot(obj, tag)
        check(share > 0.05, f"{obj.Name} drawn when the file is opened ({share:.3f} of the view)")
    for obj, tag in ((fem_new, "fem_colored"), (tri_new, "mesh_colored")):
        SurfMesh.apply_colors(obj)
        share, colored = shot(obj, tag)
        check(share > 0.05 and colored > 0.5,
              f"{obj.Name} shows its quality colors ({share:.3f} drawn, {colored:.3f} colored)")
    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_headless_file", code, last=None)
