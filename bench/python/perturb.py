"""Perturbation of a mesh's Face nodes in (u,v) of their CAD face, shared by the benchmarks
perturbed_fem.py and meshpart_parts.py (run by freecadcmd)."""

import numpy as np

from SurfMesh.app import api, conversion


def local_sizes(data, w):
    """Per node: the smallest mean corner-edge length of its elements."""
    size = np.full(len(data.nodes), np.inf)
    for e in range(len(w.types)):
        nd = w.conn[w.offsets[e]:w.offsets[e + 1]]
        c = data.nodes[nd[:3]]
        le = (np.linalg.norm(c[0] - c[1]) + np.linalg.norm(c[1] - c[2])
              + np.linalg.norm(c[2] - c[0])) / 3.0
        size[nd] = np.minimum(size[nd], le)
    return size


def perturbed(data, shape, kinds, faces, uv, size, amp, seed):
    """Node positions with the Face nodes moved in (u,v) of their face; the moved indices."""
    rng = np.random.default_rng(seed)
    nodes = data.nodes.copy()
    moved = []
    for i in np.nonzero(kinds == 1)[0]:
        f = shape.Faces[int(faces[i])]
        u0, v0 = float(uv[i][0]), float(uv[i][1])
        du, dv = f.derivative1At(u0, v0)
        xi = rng.standard_normal(2)
        u = u0 + amp * size[i] * xi[0] / max(du.Length, 1e-300)
        v = v0 + amp * size[i] * xi[1] / max(dv.Length, 1e-300)
        if not f.isPartOfDomain(u, v):
            continue
        p = f.Surface.value(u, v)
        nodes[i] = (p.x, p.y, p.z)
        moved.append(i)
    return nodes, np.asarray(moved, dtype=np.int64)


def kept_classified(data, shape, nodes, moved, kinds, faces, **prepare_options):
    """``nodes`` with the moved nodes put back that the perturbation took off their face as
    SurfMesh (``api.prepare`` with ``prepare_options``, as the optimization will be called)
    classifies them: a Face node moved within a CAD edge's own tolerance of that edge is an
    Edge node by FreeCAD's node-on-entity rule for FEM meshes, held where it is; the
    benchmark would then optimize another mesh than the one it perturbed. Also returns the
    moved nodes left moved."""
    nodes = nodes.copy()
    moved = np.asarray(moved, dtype=np.int64)
    for _ in range(4):  # putting a node back may reclassify its neighbours' elements
        trial = conversion.MeshData(**{**data.__dict__, "nodes": nodes})
        _, handle = api.prepare(trial, shape, **prepare_options)
        k = np.asarray(handle.node_kinds())
        f = np.asarray(handle.node_faces())
        off = moved[(k[moved] != kinds[moved]) | (f[moved] != faces[moved])]
        if len(off) == 0:
            break
        nodes[off] = data.nodes[off]
        moved = np.setdiff1d(moved, off)
    return nodes, moved
