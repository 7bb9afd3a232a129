#!/usr/bin/python3
"""The Jacobian certificate (issue #39, point 1) against the sampled check, on Gmsh's own
order-2 and order-3 meshes of CAD parts.

    /usr/bin/python3 bench/certificate_check.py [--parts occt_bottle.brep,nist_pmi_1.step]
        [--orders 2,3] [--div 21] [--repeat 5] [--module-dir build/src/bindings]

Gmsh meshes each part's surfaces (element size = bounding-box diagonal / div), raises the mesh
to order p with setOrder(p) and no high-order optimization (Gmsh's default), and the script
reads every face's triangles (tri6 / tri10, Gmsh node order). The reference normal of an
element is the sum of the CAD face's normals at its three corners, as SurfMesh's measures take
it: each corner's (u, v) on its face from gmsh.model.getParametrization, the normal from
gmsh.model.getNormal (the face's outward normal, orientation included); a corner where the
normal is not finite or is zero (a pole) contributes nothing, and a sum shorter than 1e-6
(kNormalCancelTol) leaves the element with a zero normal (invalid for both checks).

Both checks run in C++ on the same nodes and normals, through the module built here
(_surfmesh): the sampled check (`elements_tangled(..., samples_only=True)`: det S ≤ 0 at a
node or a quadrature point, the quality report's check before it took the certificate) and the
certificate (`certify_elements`: Bernstein coefficients of
det J with subdivision). One Markdown row per part and order: elements, tangled by the sampled
check, proven invalid (non-positive) and undecided by the certificate, elements the sampled
check calls valid but the certificate proves invalid, the reverse, and the time per element
of each check (best of --repeat runs of the whole batch, array conversions included).
The parts are read from ../shared/data/cad, never copied into this repository.
"""
import argparse
import math
import os
import sys
import time

import gmsh
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "cad"))
GMSH_TYPES = {2: (9, "tri6", 6), 3: (21, "tri10", 10)}
NORMAL_CANCEL_TOL = 1e-6


def mesh_part(path, order, div):
    gmsh.clear()
    gmsh.model.occ.importShapes(path)
    gmsh.model.occ.synchronize()
    box = gmsh.model.getBoundingBox(-1, -1)
    diag = math.sqrt(sum((box[i + 3] - box[i]) ** 2 for i in range(3)))
    gmsh.option.setNumber("Mesh.MeshSizeMax", diag / div)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)


def read_elements(order):
    """Nodes (E, k, 3), reference normals (E, 3), (face, element tag) per element."""
    gtype, _, k = GMSH_TYPES[order]
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = np.zeros((int(tags.max()) + 1, 3))
    xyz[tags.astype(np.int64)] = np.asarray(coords).reshape(-1, 3)
    nodes, normals, ids = [], [], []
    for _, face in gmsh.model.getEntities(2):
        etypes, etags, enodes = gmsh.model.mesh.getElements(2, face)
        for t, et, en in zip(etypes, etags, enodes):
            if t != gtype:
                continue
            conn = np.asarray(en, dtype=np.int64).reshape(-1, k)
            x = xyz[conn]  # (E, k, 3)
            corners = x[:, :3, :].reshape(-1, 3)
            uv = gmsh.model.getParametrization(2, face, corners.ravel().tolist())
            nrm = np.asarray(gmsh.model.getNormal(face, uv)).reshape(-1, 3)
            length = np.linalg.norm(nrm, axis=1)
            ok = np.isfinite(length) & (length > 1e-12)
            unit = np.zeros_like(nrm)
            unit[ok] = nrm[ok] / length[ok, None]
            n = unit.reshape(-1, 3, 3).sum(axis=1)
            nl = np.linalg.norm(n, axis=1)
            good = nl >= NORMAL_CANCEL_TOL
            n[good] /= nl[good, None]
            n[~good] = 0.0
            nodes.append(x)
            normals.append(n)
            ids.extend((face, int(tag)) for tag in et)
    if not nodes:
        return np.zeros((0, k, 3)), np.zeros((0, 3)), []
    return np.concatenate(nodes), np.concatenate(normals), ids


def gmsh_det(order, x, n, point):
    """det J = (x_ξ × x_η)·n at `point` from Gmsh's own Lagrange gradients (GradLagrange), for
    an independent check of the certificate's point."""
    gtype, _, k = GMSH_TYPES[order]
    _, grad, _ = gmsh.model.mesh.getBasisFunctions(gtype, [point[0], point[1], 0.0],
                                                   "GradLagrange")
    g = np.asarray(grad).reshape(k, 3)
    xu = g[:, 0] @ x
    xv = g[:, 1] @ x
    return float(np.dot(np.cross(xu, xv), n))


def best_time(fn, repeat):
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", default="occt_bottle.brep,occt_screw.step,nist_pmi_1.step,"
                    "gmsh_u_joint.step,occt_propeller.brep,occt_crankarm.brep")
    ap.add_argument("--orders", default="2,3")
    ap.add_argument("--div", type=float, default=21)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--module-dir", default=os.path.join(HERE, "..", "build", "src", "bindings"))
    ap.add_argument("--examples", type=int, default=3,
                    help="hidden folds listed per part and order")
    a = ap.parse_args()
    sys.path.insert(0, os.path.abspath(a.module_dir))
    import _surfmesh as sm

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    print(f"Gmsh {gmsh.__version__}, size = diagonal / {a.div:g}, no high-order optimization; "
          "reference normal = sum of the CAD normals at the corners (getNormal)\n")
    print("| part | p | elements | zero normal | sampled: tangled | certificate: non-positive "
          "| undecided | sampled valid, proven invalid | certified valid, sampled tangled "
          "| sampled µs/elt | certificate µs/elt | pieces mean / max |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    totals = {}
    examples = []
    for part in a.parts.split(","):
        path = os.path.join(SHARED, part)
        if not os.path.exists(path):
            print(f"| {part} | missing |")
            continue
        for order in (int(s) for s in a.orders.split(",")):
            mesh_part(path, order, a.div)
            x, n, ids = read_elements(order)
            name = GMSH_TYPES[order][1]
            E = len(ids)
            if E == 0:
                continue
            tangled, ts = best_time(lambda: sm.elements_tangled(name, x, n, samples_only=True),
                                   a.repeat)
            cert, tc = best_time(lambda: sm.certify_elements(name, x, n), a.repeat)
            v = cert["verdict"]
            zero = int(np.sum(np.linalg.norm(n, axis=1) == 0))
            nonpos = int(np.sum(v == 0))
            undec = int(np.sum(v == -1))
            hidden = np.flatnonzero(~tangled & (v != 1))
            reverse = int(np.sum(tangled & (v == 1)))
            pieces = cert["pieces"]
            print(f"| {part} | {order} | {E} | {zero} | {int(tangled.sum())} | {nonpos} | {undec} "
                  f"| {len(hidden)} | {reverse} | {1e6 * ts / E:.2f} | {1e6 * tc / E:.2f} "
                  f"| {pieces.mean():.2f} / {pieces.max()} |")
            t = totals.setdefault(order, np.zeros(9))
            t[:8] += [E, int(tangled.sum()), nonpos, undec, len(hidden), reverse, ts, tc]
            confirmed = sum(gmsh_det(order, x[e], n[e], cert["point"][e]) <= 0 for e in hidden)
            t = totals.setdefault(order, np.zeros(9))
            t[8] += confirmed
            for e in hidden[:a.examples]:
                scale = np.linalg.norm(np.cross(x[e, 1] - x[e, 0], x[e, 2] - x[e, 0]))
                examples.append((part, order, ids[e][0], ids[e][1], cert["point"][e],
                                 cert["value"][e] / scale if scale > 0 else math.nan,
                                 cert["min_sampled"][e] / scale if scale > 0 else math.nan))
    gmsh.finalize()
    print("\n| p | elements | sampled: tangled | certificate: non-positive | undecided "
          "| sampled valid, proven invalid (det J ≤ 0 there by Gmsh's basis) "
          "| certified valid, sampled tangled | sampled µs/elt | certificate µs/elt |")
    print("|---|---|---|---|---|---|---|---|---|")
    for order, t in sorted(totals.items()):
        print(f"| {order} | {int(t[0])} | {int(t[1])} | {int(t[2])} | {int(t[3])} | {int(t[4])} "
              f"({int(t[8])}) | {int(t[5])} | {1e6 * t[6] / t[0]:.2f} | {1e6 * t[7] / t[0]:.2f} |")
    if examples:
        print("\nElements the sampled check calls valid and the certificate proves invalid "
              "(det J relative to the corners' cross product ‖(x1−x0)×(x2−x0)‖):\n")
        print("| part | p | face | element | (ξ, η) | det J there | min det J at the 2(p−1) "
              "lattice |")
        print("|---|---|---|---|---|---|---|")
        for part, order, face, tag, pt, val, ms in examples:
            print(f"| {part} | {order} | {face} | {tag} | ({pt[0]:.3f}, {pt[1]:.3f}) | {val:.3g} "
                  f"| {ms:.3g} |")


if __name__ == "__main__":
    main()
