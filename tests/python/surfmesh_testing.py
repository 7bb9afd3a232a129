"""Shared helpers of the SurfMesh Python suites (not a suite itself).

Independent references used by the suites:
* the quality of a linear triangle on a surface equals the planar shape quality of the
  triangle in its own plane, 4√3·A / Σ l² (Verdict's tri_shape; paper section 6.1), with the
  sign given by the triangle's normal against the surface normal FreeCAD reports
  (Face.normalAt at Surface.parameter of the centroid);
* node positions are checked with FreeCAD's own geometry queries (Surface.parameter / value,
  Shape.distToShape).
"""

from __future__ import annotations

import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.environ.get("SURFMESH_REPO") or os.path.dirname(os.path.dirname(HERE))


def data_dir():
    return os.environ.get("SURFMESH_TEST_DATA_DIR") or os.path.join(REPO, "tests", "data")


def shared_data_dir():
    return os.environ.get("SURFMESH_SHARED_DATA_DIR") or os.path.join(
        os.path.dirname(REPO), "shared", "data", "cad"
    )


def find_part(name):
    """Path of a CAD part in tests/data or the shared data directory (None if absent)."""
    for d in (data_dir(), shared_data_dir()):
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    return None


def output_dir():
    d = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.join(REPO, "build", "test-output")
    os.makedirs(d, exist_ok=True)
    return d


def cli_path():
    import SurfMesh.paths

    return SurfMesh.paths.cli_script()


# ---- references --------------------------------------------------------------------------------


def reference_tri_quality(nodes, tris, face):
    """(quality, tangled) of linear triangles on a single FreeCAD face, computed without
    SurfMesh: planar shape quality 4√3·A/Σl², tangled when the triangle's normal points
    against the face's outward normal (FreeCAD's Face.normalAt)."""
    import FreeCAD

    x0, x1, x2 = nodes[tris[:, 0]], nodes[tris[:, 1]], nodes[tris[:, 2]]
    cross = np.cross(x1 - x0, x2 - x0)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    l2 = (np.sum((x1 - x0) ** 2, axis=1) + np.sum((x2 - x1) ** 2, axis=1)
          + np.sum((x0 - x2) ** 2, axis=1))
    q = 4.0 * np.sqrt(3.0) * area / l2
    surf = face.Surface
    tangled = np.zeros(len(tris), dtype=bool)
    for e in range(len(tris)):
        c = (x0[e] + x1[e] + x2[e]) / 3.0
        u, v = surf.parameter(FreeCAD.Vector(*map(float, c)))
        n = face.normalAt(u, v)
        tangled[e] = float(np.dot(cross[e], (n.x, n.y, n.z))) <= 0.0
    q[tangled] = 0.0
    return q, tangled


def reference_across(nodes, tris, faces, shape, which=None):
    """Per triangle (of those indexed by ``which``, default all): whether it stands across its
    face, computed without SurfMesh: its normal (x1 − x0) × (x2 − x0) points along the face's
    outward normal (FreeCAD's Face.normalAt at each corner's Surface.parameter) at some
    corners and against it at others. ``faces``: per triangle, its face's index in
    shape.Faces."""
    import FreeCAD

    which = np.arange(len(tris)) if which is None else np.asarray(which)
    normal = {}  # (node, face) → the face's normal there

    def normal_at(k, f):
        if (k, f) not in normal:
            face = shape.Faces[f]
            u, v = face.Surface.parameter(FreeCAD.Vector(*map(float, nodes[k])))
            n = face.normalAt(u, v)
            normal[k, f] = (n.x, n.y, n.z)
        return normal[k, f]

    out = np.zeros(len(which), dtype=bool)
    for j, e in enumerate(which):
        t = tris[e]
        c = np.cross(nodes[t[1]] - nodes[t[0]], nodes[t[2]] - nodes[t[0]])
        signs = [float(np.dot(c, normal_at(int(k), int(faces[e])))) > 0.0 for k in t]
        out[j] = any(signs) and not all(signs)
    return out


def standard_mesh_with_cracks(shape, **options):
    """A MeshPart standard mesh of ``shape`` (``options`` as for MeshPart.meshFromShape) with
    cracks: FreeCAD 0.20's mesher meshes some faces apart, so nodes along their CAD edges come
    twice (twin nodes at the same position); 1.x's merges them. When the mesher left no crack,
    every face's facets get their own copy of the nodes they use (twins along every CAD edge
    between faces), as the 0.20 mesher does for the faces it meshes apart."""
    import Mesh
    import MeshPart

    mesh = MeshPart.meshFromShape(Shape=shape, Segments=True, **options)
    pts = [(p.x, p.y, p.z) for p in mesh.Points]
    if coincident_groups(np.array(pts)):
        return mesh
    import FreeCAD

    facets = [f.PointIndices for f in mesh.Facets]
    new_pts, new_facets = [], []
    for k in range(mesh.countSegments()):
        index = {}
        for f in mesh.getSegment(k):
            tri = []
            for p in facets[f]:
                if p not in index:
                    index[p] = len(new_pts)
                    new_pts.append(FreeCAD.Vector(*pts[p]))
                tri.append(index[p])
            new_facets.append(tuple(tri))
    out = Mesh.Mesh()
    out.addFacets((new_pts, new_facets))  # keeps the twins (a list of triangles would merge them)
    return out


def coincident_groups(points):
    """Index arrays of the points that share one position exactly (groups of two or more)."""
    _, group, counts = np.unique(points, axis=0, return_inverse=True, return_counts=True)
    group = np.asarray(group).reshape(-1)
    return [np.nonzero(group == g)[0] for g in np.nonzero(counts > 1)[0]]


def distance_to_surface(face, points):
    """Distance of each point to the (untrimmed) surface of ``face``: |p − φ(parameter(p))|."""
    import FreeCAD

    surf = face.Surface
    out = np.empty(len(points))
    for i, p in enumerate(points):
        v = FreeCAD.Vector(*map(float, p))
        u, w = surf.parameter(v)
        out[i] = (surf.value(u, w) - v).Length
    return out


def distance_to_shape(shape, points):
    """Distance of each point to the shape (Shape.distToShape with a vertex)."""
    import FreeCAD
    import Part

    return np.array([shape.distToShape(Part.Vertex(FreeCAD.Vector(*map(float, p))))[0]
                     for p in points])


def perturbed_on_torus(points, seed, du, dv, R=10.0, r=4.0):
    """Points of the torus of radii R, r around z moved in its own angles (closed form, not a
    face's parameters): u by ``du`` and v by ``dv`` times standard normal draws of a generator
    seeded with ``seed`` (all u draws first, then all v). Used to tangle test meshes."""
    xyz = np.asarray(points, dtype=float).reshape(-1, 3)
    u = np.arctan2(xyz[:, 1], xyz[:, 0])
    v = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]) - R)
    rng = np.random.default_rng(seed)
    u = u + du * rng.standard_normal(len(u))
    v = v + dv * rng.standard_normal(len(v))
    return np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u),
                     r * np.sin(v)], axis=1)


def torus_distance(points, R=10.0, r=4.0):
    """Exact distance of points to the torus of radii R, r around z (closed form)."""
    p = np.asarray(points, dtype=float)
    rho = np.hypot(p[:, 0], p[:, 1])
    return np.abs(np.hypot(rho - R, p[:, 2]) - r)


# ---- fixtures -------------------------------------------------------------------------------------

_cache = {}


def torus_fem(doc, tangled=True):
    """(torus object, FEM mesh object) in ``doc``: the demo's Gmsh mesh of the paper's torus,
    tangled as the demo does (cached node positions are reused across tests)."""
    from SurfMesh.app import conversion, examples

    tor = examples.make_torus(doc)
    key = ("torus", tangled)
    if key not in _cache:
        mesh = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
        if tangled:
            examples.tangle_to(mesh, tor.Shape, target=20, seed=1)
        _cache[key] = mesh.FemMesh.copy()
        return tor, mesh
    mesh = doc.addObject("Fem::FemMeshObject", "TorusMesh")
    mesh.FemMesh = _cache[key].copy()
    return tor, mesh


def torus_mesh(doc, deflection=0.1):
    """(torus object, Mesh::Feature) meshed by MeshPart (float32 points)."""
    import MeshPart

    from SurfMesh.app import examples

    tor = examples.make_torus(doc)
    m = doc.addObject("Mesh::Feature", "TorusMesh")
    m.Mesh = MeshPart.meshFromShape(Shape=tor.Shape, LinearDeflection=deflection)
    return tor, m


def fem_snapshot(fem):
    """Everything observable of a FemMesh: nodes, and element id → node ids for all elements."""
    nodes = {k: (v.x, v.y, v.z) for k, v in fem.Nodes.items()}
    elems = {e: tuple(fem.getElementNodes(e)) for e in list(fem.Edges) + list(fem.Faces)}
    return nodes, elems


def mesh_snapshot(mesh):
    pts, tris = mesh.Topology
    return [(p.x, p.y, p.z) for p in pts], [tuple(t) for t in tris]


def gmsh_second_order(part, msh, options):
    """Gmsh's raw second-order surface mesh of the part (no high-order optimization) with the
    given options, written to msh (Gmsh's other options are restored afterwards)."""
    from SurfMesh.app import fileio

    gmsh = fileio._gmsh()
    gmsh.clear()
    gmsh.model.occ.importShapes(part)
    gmsh.model.occ.synchronize()
    opts = dict({"Mesh.HighOrderOptimize": 0, "Mesh.SaveAll": 0, "Mesh.MshFileVersion": 4.1},
                **options)
    saved = {k: gmsh.option.getNumber(k) for k in opts}
    try:
        for k, v in opts.items():
            gmsh.option.setNumber(k, v)
        gmsh.model.mesh.generate(2)
        gmsh.model.mesh.setOrder(2)
        gmsh.write(msh)
    finally:
        for k, v in saved.items():
            gmsh.option.setNumber(k, v)
        gmsh.clear()
    return msh
