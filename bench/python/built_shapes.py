"""Shapes built with FreeCAD's Part module, for meshpart_parts.py (SURFMESH_MP_CAD_DIR=built):
surfaces the parts of ../shared/data/cad do not have — a sphere and a cone with their poles, a
scaled (B-spline) sphere, a loft through three B-spline sections, a revolved B-spline profile,
a circle swept along a five-turn helix, a filleted block with a hole, a fusion of a
cylinder, a sphere and a torus, a box with all edges rounded and its offset, a spherical
cavity, a plate with chamfered holes, an extruded B-spline and half a torus.

    freecadcmd bench/python/write_built_shapes.py   # writes them as BREP files
"""

import math
import os

import FreeCAD
import Part

V = FreeCAD.Vector


def periodic_section(k, z):
    pts = [V(10 * (1 + 0.3 * k) * math.cos(t * math.pi / 6),
             8 * (1 + 0.2 * (k % 2)) * math.sin(t * math.pi / 6), z) for t in range(12)]
    c = Part.BSplineCurve()
    c.interpolate(pts, PeriodicFlag=True)
    return Part.Wire(c.toShape())


def shapes():
    """name → Part.Shape."""
    out = {}
    out["sphere"] = Part.makeSphere(10)
    out["cone_apex"] = Part.makeCone(8, 0, 15)
    m = FreeCAD.Matrix()
    m.scale(2.0, 1.0, 0.6)
    out["ellipsoid"] = Part.makeSphere(10).transformGeometry(m)
    out["loft"] = Part.makeLoft([periodic_section(k, z) for k, z in enumerate((0, 15, 30))],
                                True, False)
    prof = Part.BSplineCurve()
    prof.interpolate([V(5, 0, 0), V(9, 0, 8), V(6, 0, 16), V(8, 0, 24), V(3, 0, 30)])
    wire = Part.Wire([Part.LineSegment(V(0, 0, 0), V(5, 0, 0)).toShape(), prof.toShape(),
                      Part.LineSegment(V(3, 0, 30), V(0, 0, 30)).toShape(),
                      Part.LineSegment(V(0, 0, 30), V(0, 0, 0)).toShape()])
    out["vase"] = Part.Face(wire).revolve(V(0, 0, 0), V(0, 0, 1), 360)
    helix = Part.Wire(Part.makeHelix(8, 40, 15))
    circle = Part.Wire(Part.makeCircle(2, V(15, 0, 0), V(0, 1, 0)))
    out["spring"] = helix.makePipeShell([circle], True, True)
    block = Part.makeBox(40, 30, 20).cut(Part.makeCylinder(6, 40, V(20, 15, -10)))
    out["filleted_block"] = block.makeFillet(
        3, [e for e in block.Edges if abs(e.Length - 40) < 1e-6 or abs(e.Length - 30) < 1e-6][:6])
    out["fused"] = Part.makeCylinder(5, 20).fuse(Part.makeSphere(7, V(0, 0, 20))).fuse(
        Part.makeTorus(9, 2, V(0, 0, 8)))
    # A box with every edge rounded, and its offset (offset surfaces of the planes, cylinders
    # and spheres).
    box = Part.makeBox(10, 6, 4)
    rounded = box.makeFillet(1.2, box.Edges)
    out["rounded_box"] = rounded
    out["offset"] = rounded.makeOffsetShape(0.7, 1e-6)
    # A spherical cavity cut into a box's top; a plate with three chamfered holes (cones).
    out["cavity"] = Part.makeBox(10, 10, 10).cut(Part.makeSphere(4, V(5, 5, 10)))
    plate = Part.makeBox(20, 12, 2)
    for x, y in ((4, 4), (10, 6), (16, 8)):
        plate = plate.cut(Part.makeCylinder(1.5, 2, V(x, y, 0)))
    out["chamfered_plate"] = plate.makeChamfer(
        0.4, [e for e in plate.Edges if isinstance(e.Curve, Part.Circle)])
    # A B-spline edge extruded (a surface of extrusion) and half a torus.
    wave = Part.BSplineCurve()
    wave.interpolate([V(0, 0, 0), V(3, 2, 0), V(6, -1, 0), V(9, 1, 0)])
    outline = Part.Wire([wave.toShape(), Part.LineSegment(V(9, 1, 0), V(9, 6, 0)).toShape(),
                         Part.LineSegment(V(9, 6, 0), V(0, 6, 0)).toShape(),
                         Part.LineSegment(V(0, 6, 0), V(0, 0, 0)).toShape()])
    out["extrusion"] = Part.Face(outline).extrude(V(0, 0, 4))
    out["half_torus"] = Part.makeTorus(6, 2).cut(Part.makeBox(20, 20, 20, V(0, 0, -10)))
    return out


def write(directory):
    """Writes every shape as <name>.brep into ``directory``; returns it."""
    os.makedirs(directory, exist_ok=True)
    for name, s in shapes().items():
        s.exportBrep(os.path.join(directory, name + ".brep"))
    return directory

