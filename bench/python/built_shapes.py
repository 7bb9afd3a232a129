"""Shapes built with FreeCAD's Part module, for meshpart_parts.py (SURFMESH_MP_CAD_DIR=built):
surfaces the parts of ../shared/data/cad do not have — a sphere and a cone with their poles, a
scaled (B-spline) sphere, a loft through three B-spline sections, a revolved B-spline profile,
a circle swept along a five-turn helix, a filleted block with a hole and a fusion of a
cylinder, a sphere and a torus.
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
    return out


def write(directory):
    """Writes every shape as <name>.brep into ``directory``; returns it."""
    os.makedirs(directory, exist_ok=True)
    for name, s in shapes().items():
        s.exportBrep(os.path.join(directory, name + ".brep"))
    return directory
