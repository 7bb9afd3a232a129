"""Example documents: the paper's torus (section 6.2) and helpers to tangle a mesh on purpose.

    doc = FreeCAD.newDocument("torus")
    ex = SurfMesh.app.examples.make_torus_example(doc)   # Part torus + tangled Gmsh FEM mesh

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import numpy as np

from SurfMesh.app import api, conversion

TORUS_R = 10.0
TORUS_r = 4.0


def make_torus(doc, name="Torus", R=TORUS_R, r=TORUS_r):
    """A Part::Torus (major radius R, minor r) centred at the origin, axis z."""
    tor = doc.addObject("Part::Torus", name)
    tor.Radius1 = R
    tor.Radius2 = r
    doc.recompute()
    return tor


def make_gmsh_mesh(doc, part, size, name=None, order="1st", recombine=False):
    """A 2D Gmsh FEM mesh (FemMeshGmsh) of ``part`` with characteristic length ``size``
    (``recombine``: quadrilaterals, Gmsh's RecombineAll). Returns the mesh object;
    RuntimeError when Gmsh produced no mesh."""
    import ObjectsFem

    from SurfMesh.app import compat

    obj = ObjectsFem.makeMeshGmsh(doc, name or f"{part.Name}_Mesh")
    compat.set_mesh_shape(obj, part)  # its Part (0.20) or Shape (1.x)
    obj.ElementDimension = "2D"
    obj.ElementOrder = order
    obj.CharacteristicLengthMax = float(size)
    obj.RecombineAll = bool(recombine)
    doc.recompute()
    message = compat.run_gmsh_mesher(obj)
    if obj.FemMesh.FaceCount == 0:
        # Gmsh 4.13 and 4.15 (FreeCAD 1.0, 1.1) refuse a closed face whose period does not
        # start at 0 ("Impossible to mesh periodic surface"), such as a Part::Torus's (v in
        # [π, 3π]): mesh the same surface over [0, period] instead (the nodes lie on the
        # part's surface all the same), then link the part again.
        same = _periodic_from_zero(part.Shape)
        if same is not None:
            helper = doc.addObject("Part::Feature", f"{part.Name}_GmshShape")
            helper.Shape = same
            helper.Label = f"{part.Label} (periodic range from 0, for Gmsh)"
            compat.set_mesh_shape(obj, helper)
            doc.recompute()
            message = compat.run_gmsh_mesher(obj)
            compat.set_mesh_shape(obj, part)
            doc.removeObject(helper.Name)
            doc.recompute()
    if obj.FemMesh.FaceCount == 0:
        raise RuntimeError(f"Gmsh produced no surface mesh for {part.Label}: {message}")
    obj.addProperty("App::PropertyString", "GmshMessages", "SurfMesh", "Gmsh's warnings")
    obj.GmshMessages = message or ""
    return obj


def _periodic_from_zero(shape):
    """A one-face ``shape`` whose surface is closed in u or v over exactly one period, made
    again over the same surface with each such range starting at 0 (None for another shape)."""
    import math

    import Part

    if len(shape.Faces) != 1:
        return None
    face = shape.Faces[0]
    surf = face.Surface
    u0, u1, v0, v1 = face.ParameterRange
    changed = False
    rng = [u0, u1, v0, v1]
    for k, (periodic, period) in enumerate(((surf.isUPeriodic(), 2 * math.pi),
                                            (surf.isVPeriodic(), 2 * math.pi))):
        lo, hi = rng[2 * k], rng[2 * k + 1]
        if not periodic:
            continue
        try:
            period = surf.UPeriod() if k == 0 else surf.VPeriod()
        except Exception:  # noqa: BLE001
            pass
        if abs((hi - lo) - period) < 1e-9 * period and abs(lo) > 1e-12:
            rng[2 * k], rng[2 * k + 1] = 0.0, period
            changed = True
    if not changed:
        return None
    new = surf.toShape(*rng)
    if face.Orientation == "Reversed":  # the same side out (the mesh's winding follows it)
        new.reverse()
    # the same surface, where the part is (face.Surface carries the part's placement)
    if (abs(new.Area - face.Area) > 1e-9 * face.Area
            or not new.BoundBox.isInside(face.BoundBox.Center)
            or new.distToShape(Part.Vertex(face.valueAt(0.5 * (u0 + u1),
                                                        0.5 * (v0 + v1))))[0]
            > 1e-9 * shape.BoundBox.DiagonalLength):
        return None
    return new


def node_parameters(data, face):
    """(u,v) of every node of ``data`` on a FreeCAD face's surface (Surface.parameter)."""
    import FreeCAD

    surf = face.Surface
    return np.array(
        [surf.parameter(FreeCAD.Vector(*map(float, p))) for p in data.nodes], dtype=np.float64
    )


def perturb_on_surface(data, face, amplitude, seed=0, movable=None, uv=None):
    """New node positions x = φ(u + δu, v + δv) for the nodes in ``movable`` (default: all):
    (δu, δv) = amplitude · (ξ1 / |φu|, ξ2 / |φv|) with ξ ~ N(0, 1) drawn with a fixed seed, so
    that the move is about ``amplitude`` (a length) in every direction on the surface.
    Nodes stay exactly on the surface."""
    surf = face.Surface
    if uv is None:
        uv = node_parameters(data, face)
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal(uv.shape)
    if movable is None:
        movable = np.ones(len(uv), dtype=bool)
    out = data.nodes.copy()
    for i in np.nonzero(movable)[0]:
        u0, v0 = float(uv[i][0]), float(uv[i][1])
        du, dv = face.derivative1At(u0, v0)
        u = u0 + amplitude * noise[i][0] / max(du.Length, 1e-300)
        v = v0 + amplitude * noise[i][1] / max(dv.Length, 1e-300)
        p = surf.value(float(u), float(v))
        out[i] = (p.x, p.y, p.z)
    return out


def tangle_to(mesh_obj, shape, target=73, seed=7, measure="shape", lo=0.0, hi=None, steps=30):
    """Perturbs the (u,v) of the free nodes of a single-face mesh with a fixed random direction
    scaled by an amplitude found by bisection so that about ``target`` elements are tangled.
    Replaces the object's mesh; returns (amplitude, tangled count)."""
    data = conversion.read_mesh(mesh_obj)
    face = shape.Faces[0]
    _, handle = api.prepare(mesh_obj, shape)
    movable = np.asarray(handle.node_kinds()) != 0
    uv = node_parameters(data, face)
    if hi is None:
        hi = 0.05 * shape.BoundBox.DiagonalLength
    best = None
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        nodes = perturb_on_surface(data, face, mid, seed=seed, movable=movable, uv=uv)
        trial = conversion.MeshData(**{**data.__dict__, "nodes": nodes})
        count = api.measure(trial, shape, measure=measure, hints="none").stats["tangled"]
        if best is None or abs(count - target) < abs(best[1] - target):
            best = (mid, count, nodes)
        if count == target:
            break
        if count < target:
            lo = mid
        else:
            hi = mid
    amp, count, nodes = best
    new = conversion.rebuild(data, nodes)
    if data.kind == "fem":
        mesh_obj.FemMesh = new
    else:
        mesh_obj.Mesh = new
    return amp, count


def make_torus_example(doc, size=1.13, target=73, seed=1):
    """The paper's torus example: Part torus (R=10, r=4), a first-order Gmsh FEM mesh of it
    (characteristic length ``size``: about 1600 nodes and 3200 triangles at 1.13), perturbed
    in (u,v) until about ``target`` elements are tangled. Returns a dict with the objects."""
    tor = make_torus(doc)
    mesh = make_gmsh_mesh(doc, tor, size, name="TorusMesh")
    amp, count = tangle_to(mesh, tor.Shape, target=target, seed=seed)
    mesh.Label = "TorusMesh (tangled)"
    doc.recompute()
    return {"shape": tor, "mesh": mesh, "amplitude": amp, "tangled": count}
