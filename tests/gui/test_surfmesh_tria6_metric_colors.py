"""GUI test: a second-order (tria6) FEM mesh colored by a metric, and the color scales of a
document where one mesh is colored by a metric and another by quality.

The tria6 mesh is FreeCAD's own (femexamples' rc_wall_2d: 418 tria6 on a flat wall with an
opening, the same nodes on every FreeCAD release), seen from the top with an orthographic
camera placed here, so that each point of the wall has a known pixel. The reference is computed
here from the FEM nodes: the aspect ratio of each element from its corners with Verdict's
formula written out (hmax·(a+b+c)/(4√3·A)), its color from the metric's scale (green at 1,
yellow at the threshold, red beyond), and what the view must draw at each element's centroid:
FEM meshes other than tria3 are colored per node (FreeCAD 0.20 draws element colors wrong on
tria6), each node in the color of the worst element around it, and FreeCAD draws a tria6 as
four triangles, the centroid lying in the middle one, whose corners are the mid-side nodes: the
color there is that of the three mid-side nodes interpolated at the pixel's centre (an element
beyond the threshold is red all over). Checked on the screenshot at every element's centroid,
and again after saving and opening the document (the workbench shows the stored colors again).

Then a tria3 plate inside the wall's opening is colored by quality with *Measure quality*: the
view shows two color scales, stacked, each titled with what it shows and naming its mesh
(titles and names read back from the overlay's scene graph), each on its light panel with its
bar's and swatches' colors (checked on a screenshot on black), the plate's elements in their
quality's colors. *Clear quality colors* on the plate leaves the wall's scale alone; undo brings
both back; hiding the wall leaves the quality scale alone; renaming the plate renames it on its
scale.

Exit code 0 = pass (tests/gui/README.md).
"""

import math
import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, pixels, reopen  # noqa: E402

code = 1
W, H = 800, 600  # the screenshots' size
CAM_HEIGHT, CAM_X, CAM_Y = 4400.0, 1544.0, 0.0  # the wall (x 0…4000) right of the scales


def to_pixel(x, y):
    """The screenshot's (column, row) of point (x, y) of the plane z = 0 seen from the top (an
    orthographic camera of height CAM_HEIGHT at (CAM_X, CAM_Y): H / CAM_HEIGHT pixels a unit),
    as floats: pixel (i, j) covers [i, i + 1) × [j, j + 1)."""
    s = H / CAM_HEIGHT
    return W / 2 + (x - CAM_X) * s, H / 2 - (y - CAM_Y) * s


def from_pixel(i, j):
    """The point (x, y) of the plane z = 0 at the centre of pixel (i, j)."""
    s = H / CAM_HEIGHT
    return CAM_X + (i + 0.5 - W / 2) / s, CAM_Y - (j + 0.5 - H / 2) / s


def barycentric(p, a, b, c):
    """Barycentric coordinates of 2D point ``p`` in triangle ``a b c``."""
    import numpy as np

    m = np.array([[a[0] - c[0], b[0] - c[0]], [a[1] - c[1], b[1] - c[1]]])
    u, v = np.linalg.solve(m, np.array([p[0] - c[0], p[1] - c[1]]))
    return np.array([u, v, 1.0 - u - v])


def region(img, box):
    """The pixels of ``img`` inside ``box`` (x0, y0, x1, y1 in the view's -1 … 1
    coordinates), 3 pixels in from its edges."""
    x0, y0, x1, y1 = box
    cols = slice(int((x0 + 1) / 2 * W) + 3, int((x1 + 1) / 2 * W) - 3)
    rows = slice(int((1 - y1) / 2 * H) + 3, int((1 - y0) / 2 * H) - 3)
    return img[rows, cols]


def at(img, x, y):
    """The pixel of ``img`` at (x, y) in the view's -1 … 1 coordinates."""
    return img[min(int((1 - y) / 2 * H), H - 1), min(int((x + 1) / 2 * W), W - 1)]


try:
    import FreeCAD
    import FreeCADGui
    import Fem
    import numpy as np
    import Part
    from pivy import coin  # noqa: F401  (FreeCAD 1.x: getCameraNode needs pivy loaded)

    assert FreeCAD.GuiUp
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    import SurfMesh
    from femexamples.meshes import mesh_rc_wall_2d_tria6 as wall_mesh
    from SurfMesh.app import coloring, compat, metric_report, reports
    from SurfMesh.gui import legend, preferences

    preferences.set_color_by("quality")
    preferences.set_measure("shape")
    V = FreeCAD.Vector
    doc = FreeCAD.newDocument("SurfMeshTria6Colors")
    doc.UndoMode = 1
    corners = [V(0, -2000, 0), V(500, -2000, 0), V(500, 0, 0), V(3500, 0, 0),
               V(3500, -2000, 0), V(4000, -2000, 0), V(4000, 2000, 0), V(0, 2000, 0)]
    geo = doc.addObject("Part::Feature", "Wall")
    geo.Shape = Part.Face(Part.Wire([Part.makeLine(a, b)
                                     for a, b in zip(corners, corners[1:] + corners[:1])]))
    fm = Fem.FemMesh()
    wall_mesh.create_nodes(fm)
    wall_mesh.create_elements(fm)
    wall = doc.addObject("Fem::FemMeshObject", "WallMesh")
    wall.FemMesh = fm
    compat.set_mesh_shape(wall, geo)
    geo.ViewObject.Visibility = False
    doc.recompute()
    # (the workbench's observer looks at a new document once the GUI is updated: done here, so
    # that the colors checked first are those color_by_metric gives, not the stored ones)
    FreeCADGui.updateGui()
    ids = sorted(fm.Faces)
    check(len(ids) == 418 and all(len(fm.getElementNodes(e)) == 6 for e in ids),
          f"the wall's FEM mesh has {len(ids)} tria6")

    # ---- the reference: Verdict's aspect ratio on the corner nodes, the metric's colors -------
    node = {n: np.array(tuple(fm.getNodeById(n))) for n in fm.Nodes}
    ref = {}
    for e in ids:
        p = [node[n] for n in fm.getElementNodes(e)[:3]]
        a, b, c = (np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[1]),
                   np.linalg.norm(p[0] - p[2]))
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        ref[e] = max(a, b, c) * (a + b + c) / (4 * math.sqrt(3) * area)
    values = np.array([ref[e] for e in ids])
    t = float(np.round(np.quantile(values, 0.85), 3))
    beyond = {e for e in ids if ref[e] > t}
    check(0 < len(beyond) < len(ids) // 4,
          f"{len(beyond)} of {len(ids)} elements have an aspect ratio above {t}")
    good, limit, red = (np.array(metric_report.GOOD_RGB), np.array(metric_report.LIMIT_RGB),
                        np.array(metric_report.BEYOND_RGB))

    def ref_rgb(e):
        if e in beyond:
            return red
        f = min(max((ref[e] - 1.0) / (t - 1.0), 0.0), 1.0)
        return good * (1.0 - f) + limit * f

    # ---- color by the metric -------------------------------------------------------------------
    n = SurfMesh.color_by_metric(wall, "aspect_ratio", t)
    check(n == len(beyond), f"color_by_metric counts {n} elements beyond {t}")
    check(metric_report.colored_by(wall) == ("aspect_ratio", t), "the mesh records what it shows")
    rgb = np.array([c[:3] for c in wall.SurfMeshColors])
    err = np.abs(rgb - np.array([ref_rgb(e) for e in ids])).max()
    check(err < 1e-6, f"one color per element, its aspect ratio's (max error {err:.1e})")

    # what the view must draw at each centroid: the mid-side nodes' colors, each the color of
    # the worst element around the node
    worst = {}
    for e in ids:
        for nid in fm.getElementNodes(e):
            if nid not in worst or ref[e] > ref[worst[nid]]:
                worst[nid] = e
    expected, inside = {}, []
    for e in ids:
        ns = fm.getElementNodes(e)
        g = np.mean([node[k] for k in ns[:3]], axis=0)
        ci, cj = (int(v) for v in to_pixel(g[0], g[1]))
        mids = ns[3:6]
        w = barycentric(from_pixel(ci, cj), *[node[k][:2] for k in mids])
        inside.append(w.min())
        expected[e] = (ci, cj, sum(wk * ref_rgb(worst[k]) for wk, k in zip(w, mids)))
    check(min(inside) > 0.15, "each centroid's pixel lies well inside its element's middle "
          f"triangle (barycentric coordinates >= {min(inside):.2f})")

    def wall_view(name, background="White"):
        """A screenshot of the wall from the top (the camera placed as to_pixel says)."""
        view = FreeCADGui.ActiveDocument.ActiveView
        view.setCameraType("Orthographic")
        view.viewTop()
        view.fitAll()
        cam = view.getCameraNode()
        cam.height.setValue(CAM_HEIGHT)
        cam.position.setValue(CAM_X, CAM_Y, cam.position.getValue()[2])
        FreeCADGui.updateGui()
        path = os.path.join(out, name)
        view.saveImage(path, W, H, background)
        return pixels(path)

    def lighting(got, want, what):
        """The view's lighting of a flat mesh seen along its normal, the same for every
        element: a gain (the headlight's intensity: 1 on FreeCAD 0.20 and 1.0, about 0.8 on
        1.1) and an offset per channel (0.20's ambient light: about 0.04), fitted over all the
        points; returns each point's largest difference from its color so lit."""
        m = len(got)
        A = np.zeros((3 * m, 4))
        A[:, 0] = want.T.reshape(-1)
        for ch in range(3):
            A[ch * m:(ch + 1) * m, 1 + ch] = 1.0
        gain, *offset = np.linalg.lstsq(A, got.T.reshape(-1), rcond=None)[0]
        offset = np.array(offset)
        check(0.7 <= gain <= 1.05 and np.all(np.abs(offset) < 0.08),
              f"{what}: the lighting: gain {gain:.3f}, offset {np.round(offset, 3)}")
        return np.abs(got - np.minimum(gain * want + offset, 1.0)).max(axis=1)

    def centroid_colors(img, what):
        """Checks the wall's colors at every element's centroid against the expected ones
        (lit as lighting() finds)."""
        got = np.array([img[expected[e][1], expected[e][0]] for e in ids])
        want = np.array([expected[e][2] for e in ids])
        diff = lighting(got, want, what)
        bad = [(ids[k], np.round(got[k], 3).tolist(), np.round(want[k], 3).tolist())
               for k in np.argsort(-diff)[:3] if diff[k] > 0.05]
        check(not bad, f"{what}: every centroid of the {len(ids)} tria6 has its expected color "
              f"(max difference {diff.max():.3f}; worst {bad})")
        is_red = (got[:, 0] > 0.6) & (got[:, 1] < 0.12) & (got[:, 2] < 0.12)
        check({ids[k] for k in np.nonzero(is_red)[0]} == beyond,
              f"{what}: red at the centroid exactly where the reference is beyond {t}")
        return diff.max()

    img = wall_view("tria6_metric_colors.png")
    centroid_colors(img, "colored")
    legend.update(doc)
    title = f"SurfMesh: Aspect ratio (red: > {reports.format_value(t, 3)})"
    check(legend.shown(doc) == title, f"one color scale, the metric's ({legend.shown(doc)!r})")
    check("Mesh: WallMesh" in legend.texts(doc), f"naming the wall ({legend.texts(doc)})")

    # ---- saved and opened again: the stored colors shown again ---------------------------------
    path = os.path.join(out, "tria6_metric_colors.FCStd")
    doc = reopen(doc, path)
    wall = doc.getObject("WallMesh")
    img = wall_view("tria6_metric_colors_reopened.png")
    centroid_colors(img, "opened again")
    check(legend.shown(doc) == title, f"and its color scale ({legend.shown(doc)!r})")
    check(not FreeCADGui.getDocument(doc.Name).Modified, "showing them changes nothing")
    doc.UndoMode = 1

    # ---- a tria3 plate in the opening colored by quality: two scales ---------------------------
    plane = doc.addObject("Part::Plane", "PlateShape")
    plane.Length, plane.Width = 2600.0, 1400.0
    plane.Placement.Base = V(700, -1800, 0)
    nx, ny = 6, 4
    pm = Fem.FemMesh()
    nid = {}
    for j in range(ny + 1):
        for i in range(nx + 1):
            x, y = 700 + 2600 * i / nx, -1800 + 1400 * j / ny
            if 0 < i < nx and 0 < j < ny:  # interior nodes moved: qualities from 0.5 to 1
                x += 0.3 * 2600 / nx * math.sin(1.7 * i + 2.3 * j)
                y += 0.3 * 1400 / ny * math.cos(2.9 * i - 1.1 * j)
            nid[i, j] = len(nid) + 1
            pm.addNode(x, y, 0.0, nid[i, j])
    tri = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = nid[i, j], nid[i + 1, j], nid[i + 1, j + 1], nid[i, j + 1]
            tri += [(a, b, c), (a, c, d)] if (i + j) % 2 else [(a, b, d), (b, c, d)]
    for k, f in enumerate(tri):
        pm.addFace(list(f), k + 1)
    plate = doc.addObject("Fem::FemMeshObject", "Plate")
    plate.FemMesh = pm
    compat.set_mesh_shape(plate, plane)
    plane.ViewObject.Visibility = False
    doc.recompute()
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(plate)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.updateGui()
    check(metric_report.colored_by(plate) is None and "SurfMeshColors" in plate.PropertiesList,
          "Measure quality colors the plate by quality")
    # the shape measure of a planar triangle against the equilateral one: 4√3·A / Σ l²
    pts = {k: np.array(tuple(pm.getNodeById(k))) for k in pm.Nodes}
    ref_q = []
    for f in tri:
        p = [pts[k] for k in f]
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        ref_q.append(4 * math.sqrt(3) * area / sum(np.sum((p[k] - p[k - 1]) ** 2)
                                                    for k in range(3)))
    ref_q = np.array(ref_q)
    q = np.array(plate.SurfMeshQuality)
    check(np.abs(q - ref_q).max() < 1e-9 and ref_q.min() < 0.75,
          f"the plate's quality is the shape measure's ({ref_q.min():.2f} … {ref_q.max():.2f})")
    legend.update(doc)
    qtitle = "SurfMesh quality (shape)"
    check(legend.shown(doc) == title + "\n" + qtitle,
          f"two color scales: the wall's metric, the plate's quality ({legend.shown(doc)!r})")
    texts = legend.texts(doc)
    for line in ("SurfMesh: Aspect ratio", f"(red: > {reports.format_value(t, 3)})",
                 "Mesh: WallMesh", "SurfMesh quality", "(shape)", "Mesh: Plate", "tangled",
                 "left out", "n/a"):
        check(line in texts, f"the overlay's scene draws {line!r}")
    drawn = legend.drawn(doc)
    check([d["title"] for d in drawn] == [title, qtitle]
          and [d["labels"] for d in drawn] == [("WallMesh",), ("Plate",)]
          and [d["panel"] for d in drawn] == legend.layout(2),
          "stacked: the wall's scale above the plate's")

    def scales_drawn(img, what):
        """Each scale drawn shows its panel, its bar's colors and its swatches."""
        for d in legend.drawn(doc):
            panel = region(img, d["panel"])
            light = float((panel.mean(axis=2) > 0.75).mean())
            check(light > 0.6, f"{what}: {d['title']!r} on a light panel ({light:.2f})")
            bx0, by0, bx1, by1 = d["bar"]
            stops = np.array(d["stops"])
            for f in (0.05, 0.3, 0.5, 0.7, 0.95):
                want = np.array([np.interp(f, stops[:, 0], stops[:, c]) for c in (1, 2, 3)])
                got = at(img, (bx0 + bx1) / 2, by0 + f * (by1 - by0))
                check(np.abs(got - want).max() < 0.06,
                      f"{what}: its bar at {f:.0%} is {np.round(got, 2)} ({np.round(want, 2)})")
            for rgb, label, (sx0, sy0, sx1, sy1) in d["swatches"]:
                got = at(img, (sx0 + sx1) / 2, (sy0 + sy1) / 2)
                check(np.abs(got - np.array(rgb)).max() < 0.03,
                      f"{what}: its {label!r} swatch is {np.round(got, 2)}")

    img = wall_view("tria6_two_scales.png", "Black")
    scales_drawn(img, "two scales")
    check(drawn[0]["metric"] == ("aspect_ratio", t)
          and np.allclose(drawn[0]["stops"][0][1:], metric_report.GOOD_RGB)
          and np.allclose(drawn[1]["stops"][0][1:], coloring.quality_rgb([0.0])[0]),
          "the wall's bar goes from green, the plate's from red")
    centroid_colors(img, "beside the plate")
    want = coloring.quality_rgb(ref_q)
    got = []
    for f in tri:
        g = np.mean([pts[k] for k in f], axis=0)
        i, j = (int(v) for v in to_pixel(g[0], g[1]))
        got.append(img[j, i])
    diff = lighting(np.array(got), np.asarray(want), "the plate").max()
    check(diff < 0.05, f"the plate's {len(tri)} elements in their quality's colors at their "
          f"centroids (max difference {diff:.3f})")

    # ---- clearing the plate's colors leaves the wall's scale -----------------------------------
    FreeCADGui.Selection.addSelection(plate)
    FreeCADGui.runCommand("SurfMesh_ClearColors")
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.updateGui()
    check("SurfMeshColors" not in plate.PropertiesList, "the plate's colors cleared")
    check(legend.shown(doc) == title, f"the wall's scale alone ({legend.shown(doc)!r})")
    texts = legend.texts(doc)
    check("SurfMesh quality" not in texts and "Mesh: Plate" not in texts
          and "Mesh: WallMesh" in texts, "no quality scale left in the overlay")
    check([d["panel"] for d in legend.drawn(doc)] == [legend._PANEL], "on the lone panel")
    img = wall_view("tria6_after_clear.png", "Black")
    scales_drawn(img, "after clearing")
    below = region(img, (-0.99, -0.98, -0.58, legend._PANEL[1] - 0.02))
    check(float((below.mean(axis=2) > 0.75).mean()) < 0.05,
          "nothing drawn where the plate's scale was below it")
    doc.undo()
    for _ in range(3):
        FreeCADGui.updateGui()
    check(legend.shown(doc) == title + "\n" + qtitle, f"undo: both scales again "
          f"({legend.shown(doc)!r})")

    # ---- hiding the wall, renaming the plate ---------------------------------------------------
    wall.ViewObject.Visibility = False
    FreeCADGui.updateGui()
    check(legend.shown(doc) == qtitle, f"the wall hidden: the quality scale alone "
          f"({legend.shown(doc)!r})")
    plate.Label = "OpeningPlate"
    FreeCADGui.updateGui()
    check("Mesh: OpeningPlate" in legend.texts(doc), "renamed on its scale")
    wall.ViewObject.Visibility = True
    FreeCADGui.updateGui()
    check(legend.shown(doc) == title + "\n" + qtitle, "the wall shown: both scales again")

    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_tria6_metric_colors", code, last=None)
