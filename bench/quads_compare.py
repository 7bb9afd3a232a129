#!/usr/bin/python3
"""SurfMesh vs Gmsh 4.8.4's Laplace2D on Gmsh's perturbed quadrilateral meshes of CAD parts.

    /usr/bin/python3 bench/quads_compare.py --bench-dir BUILD/bench [--parts a.step,b.brep]
        [--algos 6,5] [--recombine 0,1] [--amps 0.3,0.5,0.7] [--seeds 1] [--div 21]
        [--boundary fixed,slide] [--threads 1] [--work DIR]

Each part is meshed by Gmsh with Mesh.RecombineAll = 1 (2-D algorithm --algos: 6
Frontal-Delaunay, 5 Delaunay; Mesh.RecombinationAlgorithm --recombine: 0 simple, 1 Blossom;
size = bounding-box diagonal / --div, as parts_compare.py), then perturbed as parts_compare.py
perturbs triangles (gmsh_compare.perturb: random interior nodes moved in (u,v) by amp × h
until ≥ 0.1 % of the elements, at least 20, are tangled; a quadrilateral counts as tangled when
one of its corner triangles is). Gmsh Laplace2D (niter 10) and SurfMesh (bench_cad, with each
--boundary mode) start from the same mesh; one code measures every result. Prints one row per
run: tangled before → after (in brackets: SurfMesh's left with no movable node), min and mean
quality, time; and the ids of the tangled elements left with a movable node. Gmsh 4.8.4
crashes with Algorithm 8 and aborts with RecombinationAlgorithm 2 and 3. The parts are read
from ../shared/data/cad, never copied into this repository.
"""
import argparse
import os
import tempfile
import time

import numpy as np
import gmsh

import gmsh_compare as gc

DEFAULT_PARTS = "gmsh_solid56.step,occt_housing_bottom.brep,occt_bottle.brep,occt_crankarm.brep"


def mixed_arrays():
    """All nodes (tags → 0-based) and the elements of the current model as rows of 4 ids
    (−1 last for a triangle)."""
    tags, xyz = gc.sorted_nodes()
    etypes, _, enodes = gmsh.model.mesh.getElements(2)
    rows = []
    for t, nodes in zip(etypes, enodes):
        if t == 2:
            tri = np.searchsorted(tags, nodes).reshape(-1, 3)
            rows.append(np.hstack([tri, -np.ones((tri.shape[0], 1), dtype=tri.dtype)]))
        elif t == 3:
            rows.append(np.searchsorted(tags, nodes).reshape(-1, 4))
        else:
            raise RuntimeError(f"element type {t}: only linear triangles and quads")
    return tags, xyz, np.concatenate(rows).astype(np.int32)


def corner_triangles(types, nodes):
    """Per 2-D element type's node array: (corner triangles as node tags (K, 3), element index
    of each). A quad (a, b, c, d) gives (a, b, d), (b, c, a), (c, d, b), (d, a, c)."""
    tris, owner = [], []
    start = 0
    for t, nd in zip(types, nodes):
        if t == 2:
            e = nd.reshape(-1, 3)
            tris.append(e)
            owner.append(start + np.arange(len(e)))
        elif t == 3:
            q = nd.reshape(-1, 4)
            for a, b, c in ((0, 1, 3), (1, 2, 0), (2, 3, 1), (3, 0, 2)):
                tris.append(q[:, [a, b, c]])
                owner.append(start + np.arange(len(q)))
            e = q
        else:
            raise RuntimeError(f"element type {t}")
        start += len(e)
    return np.concatenate(tris), np.concatenate(owner)


def tangled_elements():
    """Elements (triangles, quads) with a corner triangle wound against the majority of its
    surface's corner triangles (the normal against the sum of the surface normals at its
    corners), as gmsh_compare.tangled_count counts triangles."""
    tris, owners = {}, {}
    for _, tag in gmsh.model.getEntities(2):
        et, _, en = gmsh.model.mesh.getElements(2, tag)
        if len(et):
            tris[tag], owners[tag] = corner_triangles(et, [np.array(x) for x in en])
    return gc.tangled_count(tris, owners)


def mesh_part(path, algo, recombine, div):
    gmsh.clear()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.importShapes(path)
    gmsh.model.occ.synchronize()
    h = gc.bbox_diagonal() / div
    gc.set_mesh_size(h)
    gmsh.option.setNumber("Mesh.Algorithm", algo)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", recombine)
    gmsh.model.mesh.generate(2)
    gc.H_LOCAL = h
    return h


def run(a, path, algo, recombine, amp, seed, wdir):
    mesh_part(path, algo, recombine, a.div)
    _, _, elems = mixed_arrays()
    target = max(20, int(1e-3 * len(elems)))
    gc.perturb(target, amp, seed=seed, count=tangled_elements)
    snap = gc.snapshot_nodes()
    brep = os.path.join(wdir, "part.brep")
    gmsh.write(brep)
    _, xyz, elems = mixed_arrays()
    inp = os.path.join(wdir, "in.bin")
    gc.write_dump(inp, xyz, elems)
    quads = int((elems[:, 3] >= 0).sum())
    m_in = gc.run_bench_cad(a.bench_dir, "measure", brep, inp)
    gc.restore(snap)
    t0 = time.perf_counter()
    gmsh.model.mesh.optimize("Laplace2D", niter=10)
    t_lap = time.perf_counter() - t0
    _, xyz_l, _ = mixed_arrays()
    out = os.path.join(wdir, "laplace.bin")
    gc.write_dump(out, xyz_l, elems)
    m_lap = gc.run_bench_cad(a.bench_dir, "measure", brep, out)
    res = {}
    for boundary in a.boundary.split(","):
        out = os.path.join(wdir, f"surfmesh_{boundary}.bin")
        os.environ["BENCH_BOUNDARY"] = boundary
        r = gc.run_bench_cad(a.bench_dir, "optimize", brep, inp, out, a.threads)
        m = gc.run_bench_cad(a.bench_dir, "measure", brep, out)
        os.environ.pop("BENCH_BOUNDARY", None)
        m.update({k: r.get(k) for k in ("seconds", "sweeps", "tangled_unmovable",
                                          "tangled_movable_ids", "error")})
        res[boundary] = m
    return len(elems), quads, m_in, (t_lap, m_lap), res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench-dir", required=True)
    ap.add_argument("--parts", default=DEFAULT_PARTS)
    ap.add_argument("--algos", default="6,5")
    ap.add_argument("--recombine", default="0,1")
    ap.add_argument("--amps", default="0.3,0.5,0.7")
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--div", type=float, default=21.0)
    ap.add_argument("--boundary", default="fixed,slide")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="surfmesh_quads_")
    gmsh.initialize()
    print("| part | algo | recomb. | amp | seed | elements (quads) | input tangled "
          "| Laplace2D: tangled, min, mean, s | SurfMesh fixed: tangled (no movable node), min, "
          "mean, s | SurfMesh slide: idem | left with a movable node (fixed; slide) |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---|---|---|")
    left = {b: 0 for b in a.boundary.split(",")}
    runs = 0
    for part in a.parts.split(","):
        path = part if os.path.isabs(part) else os.path.join(gc.SHARED, part)
        name = os.path.splitext(os.path.basename(path))[0]
        for algo in (int(x) for x in a.algos.split(",")):
            for rec in (int(x) for x in a.recombine.split(",")):
                for amp in (float(x) for x in a.amps.split(",")):
                    for seed in (int(s) for s in a.seeds.split(",")):
                        wdir = os.path.join(work, f"{name}_a{algo}_r{rec}_{amp}_{seed}")
                        os.makedirs(wdir, exist_ok=True)
                        try:
                            ne, nq, m_in, (tl, ml), res = run(a, path, algo, rec, amp, seed, wdir)
                        except Exception as ex:
                            print(f"| {name} | {algo} | {rec} | {amp} | {seed} | - | - | {ex} |")
                            continue
                        if "error" in m_in:
                            print(f"| {name} | {algo} | {rec} | {amp} | {seed} | {ne} ({nq}) | "
                                  f"{m_in['error'][:120]} |", flush=True)
                            continue
                        runs += 1

                        def cell(m, t):
                            if m.get("error"):
                                return "error: " + m["error"][:60]
                            stuck = m.get("tangled_unmovable")
                            s = f" ({stuck})" if stuck is not None else ""
                            return f"{m['tangled']}{s}, {m['min']:.3f}, {m['mean']:.3f}, {t:.2f}"

                        ids = []
                        for b, m in res.items():
                            if not m.get("error"):
                                left[b] += m["tangled"] - (m.get("tangled_unmovable") or 0)
                            ids.append(str(m.get("tangled_movable_ids") or []))
                        cells = " | ".join(cell(m, m.get("seconds") or 0.0)
                                           for m in res.values())
                        print(f"| {name} | {algo} | {rec} | {amp} | {seed} | {ne} ({nq}) | "
                              f"{m_in['tangled']} | {cell(ml, tl)} | {cells} | "
                              f"{'; '.join(ids)} |", flush=True)
    gmsh.finalize()
    print(f"\n{runs} runs; tangled elements left with a movable node: " +
          ", ".join(f"{b} {n}" for b, n in left.items()) + f" (work dir {work})")


if __name__ == "__main__":
    main()
