#!/usr/bin/python3
"""SurfMesh vs Gmsh 4.8.4 (Laplace2D niter=10, Relocate2D) on the same perturbed meshes.

    /usr/bin/python3 bench/gmsh_compare.py --bench-dir BUILD/bench [--cases torus,part,part10,part100]
        [--part FILE.step|.brep] [--size H] [--seed S] [--amp A] [--tangle-fraction F]

For every case: the shape is built or read by Gmsh (OCC kernel) and meshed by Gmsh; interior
surface nodes are moved in (u,v) and put back ON the surface (x = φ(u,v) with
gmsh.model.getValue, gmsh.model.mesh.setNode with the parametric coordinates) until some
elements are tangled; the shape (BREP) and the perturbed mesh are written once, and then:
  * Gmsh: the perturbed nodes are restored and gmsh.model.mesh.optimize(method) is timed;
  * SurfMesh: bench_cad optimize (CadMesh recovery timed separately from the optimization).
Every output is measured by the same code (bench_cad measure: SurfMesh's shape quality, the
tangled count, the largest node distance to the shape).

The CAD part is by default the engine block of Gmsh's own benchmarks (../shared/data/cad, GPL:
read from there, never copied into this repository); --part takes any STEP or BREP file, meshed
with the size --size (default: the bounding-box diagonal / 21, which is 4.0 on the engine block)
and h/√10, h/10 for part10 and part100. The perturbation is random (--seed) with amplitude
--amp × h and stops once --tangle-fraction of the triangles (at least 20) are tangled.
"""
import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import time

import numpy as np
import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "cad"))


def sorted_nodes():
    """All nodes of the current model: their tags, sorted, and their coordinates (N, 3) in
    that order (a node's 0-based index is its tag's place, np.searchsorted)."""
    tags, coord, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    return tags[order], coord.reshape(-1, 3)[order]


def mesh_arrays():
    """All nodes (tags → 0-based) and the triangles of the current model."""
    tags, xyz = sorted_nodes()
    etypes, _, enodes = gmsh.model.mesh.getElements(2)
    tris = []
    for t, nodes in zip(etypes, enodes):
        if t != 2:
            raise RuntimeError("only linear triangles are compared")
        tris.append(nodes.reshape(-1, 3))
    tris = np.concatenate(tris)
    idx = np.searchsorted(tags, tris.reshape(-1)).reshape(-1, 3).astype(np.int32)
    return tags, xyz, idx


def write_dump(path, xyz, tris):
    """bench_cad's binary mesh: node and element counts, coordinates, connectivity. Rows of 4
    (quads, and triangles with −1 last) are marked by a negative element count."""
    count = tris.shape[0] if tris.shape[1] == 3 else -tris.shape[0]
    with open(path, "wb") as f:
        np.array([xyz.shape[0], count], dtype=np.int64).tofile(f)
        np.ascontiguousarray(xyz, dtype=np.float64).tofile(f)
        np.ascontiguousarray(tris, dtype=np.int32).tofile(f)


def face_nodes():
    """{surface tag: (node tags, (u,v) array)} of the nodes strictly inside each surface."""
    out = {}
    for _, tag in gmsh.model.getEntities(2):
        nt, _, par = gmsh.model.mesh.getNodes(2, tag, includeBoundary=False,
                                              returnParametricCoord=True)
        if len(nt):
            out[tag] = (np.array(nt), np.array(par).reshape(-1, 2))
    return out


def tangled_count(tris_by_face, owners_by_face=None):
    """Triangles wound against the majority of their surface (per surface): the triangle's
    normal against the sum of the surface normals at its corners. With `owners_by_face` (per
    surface, the element each triangle belongs to: the corner triangles of quads), the
    elements with such a triangle."""
    tags, coord, _ = gmsh.model.mesh.getNodes()
    pos = np.zeros((int(tags.max()) + 1, 3))
    pos[tags] = coord.reshape(-1, 3)
    nrm = np.zeros_like(pos)
    total = 0
    for tag, tri in tris_by_face.items():
        nt, _, par = gmsh.model.mesh.getNodes(2, tag, includeBoundary=True,
                                              returnParametricCoord=True)
        if len(par) != 2 * len(nt):
            continue
        nrm[nt] = np.array(gmsh.model.getNormal(tag, list(par))).reshape(-1, 3)
        p = pos[tri]
        c = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        n = nrm[tri].sum(axis=1)
        s = np.sign(np.einsum("ij,ij->i", c, n))
        major = 1.0 if (s > 0).sum() >= (s < 0).sum() else -1.0
        if owners_by_face is None:
            total += int((s != major).sum())
        else:
            total += len(np.unique(owners_by_face[tag][s != major]))
    return total


def perturb(target, amp, seed, max_rounds=60, fraction=0.02, count=None):
    """Moves random interior nodes in (u,v) by `amp` local sizes until ≥ target triangles are
    tangled (nodes stay inside their trimmed face and exactly on its surface). `count`, when
    given, counts the tangled elements instead (a mesh of other elements than triangles)."""
    rng = random.Random(seed)
    fn = face_nodes()
    tris_by_face = {}
    for _, tag in gmsh.model.getEntities(2):
        et, _, en = gmsh.model.mesh.getElements(2, tag)
        if len(et) and count is None:
            tris_by_face[tag] = np.array(en[0]).reshape(-1, 3)
    candidates = [(tag, k) for tag, (nt, _) in fn.items() for k in range(len(nt))]
    rounds = 0
    tangled = 0
    while tangled < target and rounds < max_rounds:
        rounds += 1
        pick = rng.sample(candidates, max(1, int(fraction * len(candidates))))
        by_face = {}
        for tag, k in pick:
            by_face.setdefault(tag, []).append(k)
        for tag, ks in by_face.items():
            nt, par = fn[tag]
            uv = par[ks]
            d = np.array(gmsh.model.getDerivative(2, tag, uv.reshape(-1).tolist())).reshape(-1, 6)
            hu = np.linalg.norm(d[:, 0:3], axis=1)
            hv = np.linalg.norm(d[:, 3:6], axis=1)
            # local size: the mesh size asked from Gmsh
            new = uv.copy()
            for j in range(len(ks)):
                h = H_LOCAL
                new[j, 0] += amp * h / max(hu[j], 1e-12) * rng.uniform(-1, 1)
                new[j, 1] += amp * h / max(hv[j], 1e-12) * rng.uniform(-1, 1)
            for j, k in enumerate(ks):
                if not inside_face(tag, new[j].tolist()):
                    continue
                x = gmsh.model.getValue(2, tag, new[j].tolist())
                gmsh.model.mesh.setNode(int(nt[k]), list(x), new[j].tolist())
                par[k] = new[j]
        tangled = count() if count else tangled_count(tris_by_face)
    return tangled


H_LOCAL = 1.0


def inside_face(tag, uv):
    """Whether the point of parameters uv lies inside surface `tag`: Gmsh 4.8's isInside takes
    parametric coordinates, later versions take (x, y, z) unless parametric=True."""
    try:
        return gmsh.model.isInside(2, tag, uv, parametric=True) > 0
    except TypeError:
        return gmsh.model.isInside(2, tag, uv) > 0


def snapshot_nodes():
    """(tag, coord, parametric coord) of every surface-interior node, to restore the input."""
    snap = []
    for _, tag in gmsh.model.getEntities(2):
        nt, c, p = gmsh.model.mesh.getNodes(2, tag, includeBoundary=False,
                                            returnParametricCoord=True)
        snap.append((np.array(nt), np.array(c).reshape(-1, 3), np.array(p).reshape(-1, 2)))
    return snap


def restore(snap):
    for nt, c, p in snap:
        for k in range(len(nt)):
            gmsh.model.mesh.setNode(int(nt[k]), c[k].tolist(), p[k].tolist())


def run_bench_cad(bench_dir, *args):
    out = subprocess.run([os.path.join(bench_dir, "bench_cad"), *map(str, args)],
                         capture_output=True, text=True)
    try:
        return json.loads(out.stdout.strip().splitlines()[-1])
    except Exception:
        return {"error": (out.stdout + out.stderr)[-300:]}


def bbox_diagonal():
    """Diagonal of the current model's bounding box."""
    box = gmsh.model.getBoundingBox(-1, -1)
    return float(np.linalg.norm(np.subtract(box[3:], box[:3])))


def set_mesh_size(h):
    """Uniform size h (no curvature refinement), Frontal-Delaunay 2-D algorithm."""
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)


def build_case(name, part, size):
    global H_LOCAL
    gmsh.clear()
    gmsh.option.setNumber("General.Terminal", 0)
    if name == "torus":
        gmsh.model.occ.addTorus(0, 0, 0, 10, 4)
        gmsh.model.occ.synchronize()
        h = 1.07  # ~1600 nodes, ~3200 triangles: the paper's torus
        target, amp = 73, 1.2
    else:
        gmsh.model.occ.importShapes(part)
        gmsh.model.occ.synchronize()
        factor = {"part": 1.0, "part10": 10 ** -0.5, "part100": 0.1}[name]
        if size is None:
            size = bbox_diagonal() / 21.0
        h = size * factor  # engine block: bbox diagonal 84, h = 4.0
        target, amp = None, None  # set by the caller
    set_mesh_size(h)
    t0 = time.perf_counter()
    gmsh.model.mesh.generate(2)
    t_mesh = time.perf_counter() - t0
    H_LOCAL = h
    return target, amp, t_mesh


def run_case(case, part, size, seed, amp_part, tangle_fraction, bench_dir, thread_counts, work,
             verbose=True):
    """Meshes and perturbs one case, runs Gmsh's two smoothers and SurfMesh with each thread
    count on it; returns rows (case, tool, seconds, measures, elements). Needs gmsh initialized."""
    rows = []
    target, amp, t_mesh = build_case(case, part, size)
    if amp is None:
        amp = amp_part
    _, xyz0, tris = mesh_arrays()
    if target is None:
        target = max(20, int(tangle_fraction * tris.shape[0]))
    perturb(target, amp, seed=seed)
    snap = snapshot_nodes()
    brep = os.path.join(work, f"{case}.brep")
    gmsh.write(brep)
    tags, xyz, tris = mesh_arrays()
    inp = os.path.join(work, f"{case}_in.bin")
    write_dump(inp, xyz, tris)
    m_in = run_bench_cad(bench_dir, "measure", brep, inp)
    if verbose:
        print(f"\n## {case}: {tris.shape[0]} triangles, {xyz.shape[0]} nodes "
              f"(gmsh meshing {t_mesh:.1f} s); perturbed: {m_in}", flush=True)
    rows.append((case, "input", None, m_in, tris.shape[0]))
    for method, niter in (("Laplace2D", 10), ("Relocate2D", 1)):
        restore(snap)
        t0 = time.perf_counter()
        gmsh.model.mesh.optimize(method, niter=niter)
        t = time.perf_counter() - t0
        _, xyzg, _ = mesh_arrays()
        out = os.path.join(work, f"{case}_{method}.bin")
        write_dump(out, xyzg, tris)
        m = run_bench_cad(bench_dir, "measure", brep, out)
        rows.append((case, f"Gmsh {method}" + (f" niter={niter}" if niter > 1 else ""), t, m,
                     tris.shape[0]))
        if verbose:
            print(f"  {method}: {t:.3f} s {m}", flush=True)
    for threads in thread_counts:
        out = os.path.join(work, f"{case}_surfmesh{threads}.bin")
        r = run_bench_cad(bench_dir, "optimize", brep, inp, out, threads)
        m = run_bench_cad(bench_dir, "measure", brep, out)
        for k in ("sweeps", "reason", "bridge_s", "floor_s", "value_floor_s", "mean_sweep_s",
                  "tangled_unmovable"):
            m[k] = r.get(k)
        rows.append((case, f"SurfMesh {threads} thread(s)", r.get("seconds"), m, tris.shape[0]))
        if verbose:
            print(f"  SurfMesh threads={threads}: {r}", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench-dir", required=True)
    ap.add_argument("--cases", default="torus,part,part10,part100")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=None)
    ap.add_argument("--part", default=os.path.join(SHARED, "gmsh_engine_block.step"),
                    help="STEP or BREP file of the part cases (default: the engine block)")
    ap.add_argument("--size", type=float, default=None,
                    help="mesh size of the part case (default: bounding-box diagonal / 21)")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--amp", type=float, default=1.2,
                    help="perturbation amplitude in mesh sizes")
    ap.add_argument("--tangle-fraction", type=float, default=1e-3,
                    help="perturb until this fraction of the triangles is tangled (part cases)")
    a = ap.parse_args()
    if a.work:
        os.makedirs(a.work, exist_ok=True)
    work = a.work or tempfile.mkdtemp(prefix="surfmesh_bench_")
    gmsh.initialize()
    rows = []
    for case in a.cases.split(","):
        rows += run_case(case, a.part, a.size, a.seed, a.amp, a.tangle_fraction, a.bench_dir,
                         sorted({1, a.threads}), work)
    gmsh.finalize()

    print("\n| case | elements | tool | time s | ratio to Laplace2D | min q | mean q | tangled "
          "| valid q < 0.2 | max dist to surface | notes |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|")
    lap = {}
    for case, tool, t, m, ne in rows:
        if tool.startswith("Gmsh Laplace2D"):
            lap[case] = t
    for case, tool, t, m, ne in rows:
        if "error" in m:
            print(f"| {case} | {ne} | {tool} | - | - | - | - | - | - | - | {m['error'][:80]} |")
            continue
        ratio = f"{t / lap[case]:.2f}" if t and lap.get(case) else "-"
        notes = ""
        if tool.startswith("SurfMesh"):
            notes = (f"{m.get('sweeps')} sweeps, {m.get('reason')}; CAD recovery "
                     f"{m.get('bridge_s')} s (not included)")
            if m.get("tangled_unmovable"):
                notes += (f"; {m['tangled_unmovable']} tangled without a movable node "
                          "(all nodes on CAD edges, boundary fixed)")
            if m.get("floor_s") and m.get("mean_sweep_s") and (m.get("sweeps") or 0) > 1:
                notes += f"; later sweeps {m['mean_sweep_s'] / m['floor_s']:.0f}× the floor"
                if m.get("value_floor_s"):
                    notes += f" ({m['mean_sweep_s'] / m['value_floor_s']:.1f}× the value floor)"
        ts = f"{t:.3f}" if t is not None else "-"
        print(f"| {case} | {ne} | {tool} | {ts} | {ratio} | {m['min']:.3f} | {m['mean']:.3f} | "
              f"{m['tangled']} | {m.get('below_0_2', '-')} | {m['max_distance']:.1e} | {notes} |")


if __name__ == "__main__":
    main()
