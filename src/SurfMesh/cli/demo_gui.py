"""GUI part of scripts/demo.sh (run by freecad under xvfb-run after demo.py):

    freecad <Mod>/SurfMesh/SurfMesh/cli/demo_gui.py   (SURFMESH_DEMO_OUTPUT=OUTDIR)

Opens OUTDIR/torus.FCStd, colors the tangled and the optimized meshes by quality, takes
screenshots of the 3D view (tangled, smoothed with shape, with Oddy) and puts them side by
side in OUTDIR/screenshot.png, then saves the document again with its view colors.
"""

import os
import sys
import traceback

code = 1
try:
    import FreeCAD
    import FreeCADGui

    import SurfMesh

    outdir = os.environ.get("SURFMESH_DEMO_OUTPUT", os.path.abspath("demo-output"))
    doc = FreeCAD.openDocument(os.path.join(outdir, "torus.FCStd"))
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    gdoc = FreeCADGui.getDocument(doc.Name)
    meshes = [doc.getObject(n) for n in
              ("TorusMesh", "TorusMesh_shape_optimized", "TorusMesh_oddy_optimized")]
    for o in doc.Objects:
        o.ViewObject.Visibility = False
    view = gdoc.ActiveView
    import time

    import matplotlib.image as mpimg

    def drawn_share(path):
        """Share of the image's pixels that are not the white background."""
        img = mpimg.imread(path)[..., :3]
        return float((img.sum(axis=-1) < 2.9).mean())

    shots = []
    for obj in meshes:
        obj.ViewObject.Visibility = True  # color a visible FEM view: hidden ones stay blank
        FreeCADGui.updateGui()
        SurfMesh.apply_colors(obj)
        path = os.path.join(outdir, f"view_{obj.Name}.png")
        # The off-screen render now and then comes back empty right after a change of the
        # scene: render again (up to 5 times) rather than show a blank view.
        for attempt in range(5):
            view.viewIsometric()
            view.fitAll()
            FreeCADGui.updateGui()
            view.saveImage(path, 800, 600, "White")
            if drawn_share(path) > 0.05:
                break
            time.sleep(0.5)
        else:
            raise RuntimeError(f"the 3D view of {obj.Label} rendered empty 5 times")
        shots.append(path)
        obj.ViewObject.Visibility = False
    for obj in meshes:
        obj.ViewObject.Visibility = obj.Name == "TorusMesh_shape_optimized"
    doc.save()
    backup = os.path.join(outdir, "torus.FCStd1")
    if os.path.exists(backup):
        os.remove(backup)

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    titles = ["tangled (shape quality)", "smoothed: shape", "smoothed: Oddy"]
    fig = Figure(figsize=(15, 4.8), dpi=100)
    FigureCanvasAgg(fig)
    for k, (p, t) in enumerate(zip(shots, titles)):
        ax = fig.add_subplot(1, 3, k + 1)
        ax.imshow(mpimg.imread(p)[60:560, 100:700])
        ax.set_title(t)
        ax.axis("off")
    fig.text(0.5, 0.02, "colors: red = poor, yellow, green = good quality; purple = tangled",
             ha="center")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(os.path.join(outdir, "screenshot.png"))
    print(f"wrote {outdir}/screenshot.png and the view_*.png images", flush=True)
    code = 0
except BaseException:
    traceback.print_exc()
sys.stdout.flush()
sys.stderr.flush()
os._exit(code)
