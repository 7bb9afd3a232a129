#!/usr/bin/python3
"""Edge flips (topology "flip") against node motion alone and Gmsh Laplace2D, on Gmsh meshes
of the CAD parts of ../shared/data/cad.

    /usr/bin/python3 bench/flips_compare.py --bench-dir BUILD/bench [--threads 2]
        [--parts a.step,b.brep] [--sizes 21,40]

For each part and size (h = bounding-box diagonal / size, Frontal-Delaunay, no curvature
refinement; "paper" rows: the paper's Table 3 element counts), Gmsh 4.8.4 meshes the part; the
mesh is smoothed by SurfMesh (shape measure, CAD edges fixed) without and with edge flips,
by Gmsh Laplace2D (niter=10) and, where Debian's Netgen can be driven (netgen_surface_opt.py),
by Netgen's OCC surface optimizer (edge swapping and smoothing, "smsmSmSm": no node removal).
One code measures every result (bench_cad measure, on the
returned connectivity). Columns: min / mean shape quality, the minimum over the elements with a
node inside a face, tangled elements, elements with every corner on one CAD edge left
(needles: neither flips nor moves open them), time, and the time ratio flips / no flips.
Parts are read from ../shared/data/cad, never copied into this repository.
"""
import argparse
import json
import os
import tempfile
import time

import gmsh

import gmsh_compare as gc
import paper_table3 as t3

try:  # Netgen's OCC surface optimizer (bench/netgen_surface_opt.py), where it can be built
    import netgen_surface_opt as ngopt
except Exception:  # noqa: BLE001 - optional peer
    ngopt = None

DEFAULT_PARTS = ("occt_crankarm.brep,occt_housing_bottom.brep,gmsh_crankshaft.step,"
                 "occt_bottle.brep,occt_screw.step,nist_pmi_1.step,gmsh_engine_block.step")
PAPER_TARGETS = {"gmsh_crankshaft.step": 9328, "occt_housing_bottom.brep": 11462}


def mesh_part(path, size):
    if size == "paper":
        return t3.mesh_with_count(path, PAPER_TARGETS[os.path.basename(path)])
    gmsh.clear()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.importShapes(path)
    gmsh.model.occ.synchronize()
    gc.set_mesh_size(gc.bbox_diagonal() / float(size))
    gmsh.model.mesh.generate(2)
    return gc.mesh_arrays()[2].shape[0]


def triangle_faces(tris):
    """The Gmsh surface tag (1-based, the shape's face order) of every triangle of
    gc.mesh_arrays() (which lists them surface by surface)."""
    import numpy as np

    faces = []
    for dim, tag in gmsh.model.getEntities(2):
        types, etags, _ = gmsh.model.mesh.getElements(dim, tag)
        faces += [tag] * sum(len(e) for t, e in zip(types, etags) if t == 2)
    if len(faces) != len(tris):
        raise RuntimeError("triangles and surfaces disagree")
    return np.asarray(faces)


def cells(m, r=None, extra=""):
    if "error" in m:
        return f"{m['error'][:80]} | | | | | | |"
    t = "" if r is None else f"{r.get('seconds', 0):.2f}"
    needles = "" if r is None or "needles" not in r else str(r["needles"])
    flips = "" if r is None or "flips" not in r else str(r["flips"])
    return (f"{m['min']:.3f} | {m['min_with_face_node']:.3f} | {m['mean']:.4f} | "
            f"{m['tangled']} | {flips} | {needles} | {t}{extra} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench-dir", required=True)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--parts", default=DEFAULT_PARTS)
    ap.add_argument("--sizes", default="21,paper")
    ap.add_argument("--work", default=None)
    ap.add_argument("--json", default=None, help="write the raw rows here")
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="surfmesh_flips_")
    os.makedirs(work, exist_ok=True)
    gmsh.initialize()
    rows = []
    print("| part | size | triangles | run | min q | min q (face node) | mean q | tangled | "
          "flips | needles | s |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for part in a.parts.split(","):
        for size in a.sizes.split(","):
            if size == "paper" and part not in PAPER_TARGETS:
                continue
            n = mesh_part(os.path.join(gc.SHARED, part), size)
            stem = os.path.join(work, f"{part.split('.')[0]}_{size}")
            gmsh.write(stem + ".brep")
            _, xyz, tris = gc.mesh_arrays()
            gc.write_dump(stem + "_in.bin", xyz, tris)
            shape = stem + ".brep"
            m0 = gc.run_bench_cad(a.bench_dir, "measure", shape, stem + "_in.bin")
            out = {"part": part, "size": size, "triangles": n, "input": m0}
            print(f"| {part} | {size} | {n} | input | {cells(m0)}")
            for label, topo in (("SurfMesh", "none"), ("SurfMesh + flips", "flip")):
                os.environ["BENCH_TOPOLOGY"] = topo
                r = gc.run_bench_cad(a.bench_dir, "optimize", shape, stem + "_in.bin",
                                     stem + f"_{topo}.bin", a.threads)
                m = gc.run_bench_cad(a.bench_dir, "measure", shape, stem + f"_{topo}.bin")
                out[topo] = {"run": r, "measure": m}
                extra = ""
                if topo == "flip" and "seconds" in out["none"]["run"] and "seconds" in r:
                    extra = f" ({r['seconds'] / max(out['none']['run']['seconds'], 1e-9):.2f}×)"
                print(f"| | | | {label} | {cells(m, r, extra)}")
            os.environ.pop("BENCH_TOPOLOGY", None)
            t0 = time.perf_counter()
            gmsh.model.mesh.optimize("Laplace2D", niter=10)
            t_lap = time.perf_counter() - t0
            gc.write_dump(stem + "_lap.bin", gc.mesh_arrays()[1], tris)
            m2 = gc.run_bench_cad(a.bench_dir, "measure", shape, stem + "_lap.bin")
            out["laplace2d"] = {"seconds": t_lap, "measure": m2}
            print(f"| | | | Gmsh Laplace2D | {cells(m2, {'seconds': t_lap})}")
            if ngopt is not None:
                try:
                    faces = triangle_faces(tris)
                    t0 = time.perf_counter()
                    nx, nt = ngopt.optimize(shape, xyz, tris, faces, sched="smsmSmSm")
                    t_ng = time.perf_counter() - t0
                    gc.write_dump(stem + "_ng.bin", nx, nt.astype("int32"))
                    m3 = gc.run_bench_cad(a.bench_dir, "measure", shape, stem + "_ng.bin")
                except Exception as err:  # noqa: BLE001 - a peer's failure is a row
                    m3, t_ng = {"error": str(err)}, 0.0
                out["netgen"] = {"seconds": t_ng, "measure": m3}
                print(f"| | | | Netgen (OCC surface optimizer) | {cells(m3, {'seconds': t_ng})}")
            rows.append(out)
    gmsh.finalize()
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
