#!/usr/bin/python3
"""SurfMesh vs Gmsh 4.8.4 on every CAD part of ../shared/data/cad, several random perturbations.

    /usr/bin/python3 bench/parts_compare.py --bench-dir BUILD/bench [--parts a.step,b.brep]
        [--seeds 1,2] [--cases part,part10] [--amp 1.0] [--threads 2]

For each part, size (part: h = bounding-box diagonal / 21; part10: h/√10) and seed, the same
procedure as gmsh_compare.py (Gmsh meshes the part, interior surface nodes are moved in (u,v) on
their surface until ≥ 0.1 % of the triangles are tangled; Gmsh Laplace2D niter=10, Relocate2D
and SurfMesh then start from the same mesh; one code measures every result). Prints one row per
run and a summary. "tangled" counts every tangled element; in brackets, those of SurfMesh's
that have no movable node (all three nodes on CAD edges or vertices with the boundary fixed:
Gmsh's own mesh has them, no node motion can repair them). The parts are read from
../shared/data/cad, never copied into this repository.
"""
import argparse
import os
import tempfile

import gmsh

import gmsh_compare as gc

DEFAULT_PARTS = ("gmsh_engine_block.step,gmsh_crankshaft.step,gmsh_solid56.step,"
                 "gmsh_u_joint.step,gmsh_rod_revolution.brep,occt_bottle.brep,"
                 "occt_crankarm.brep,occt_housing_bottom.brep,occt_propeller.brep,"
                 "occt_screw.step,nist_pmi_1.step,nist_pmi_2.step")


def fmt(m, key, spec):
    return "-" if "error" in m else format(m[key], spec)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench-dir", required=True)
    ap.add_argument("--parts", default=DEFAULT_PARTS)
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--cases", default="part,part10")
    ap.add_argument("--amp", type=float, default=1.0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="surfmesh_parts_")
    gmsh.initialize()
    print("| part | case | seed | elements | input tangled | Laplace2D: tangled, min, mean "
          "| Relocate2D: tangled, min, mean | SurfMesh: tangled (no movable node), min, mean "
          "| SurfMesh time / Laplace2D |")
    print("|---|---|---:|---:|---:|---|---|---|---:|")
    runs = fixable_left = min_ge = mean_ge = errors = with_lap = 0
    lap_left = 0
    ratios = []
    for part in a.parts.split(","):
        path = part if os.path.isabs(part) else os.path.join(gc.SHARED, part)
        name = os.path.splitext(os.path.basename(path))[0]
        for seed in (int(s) for s in a.seeds.split(",")):
            for case in a.cases.split(","):
                wdir = os.path.join(work, f"{name}_{case}_{seed}")
                os.makedirs(wdir, exist_ok=True)
                try:
                    rows = gc.run_case(case, path, None, seed, a.amp, 1e-3, a.bench_dir,
                                       [a.threads], wdir, verbose=False)
                except Exception as ex:  # a part Gmsh cannot mesh
                    print(f"| {name} | {case} | {seed} | - | - | - | - | - | {ex} |")
                    errors += 1
                    continue
                by = {tool.split()[1] if tool.startswith("Gmsh") else tool.split()[0]: (t, m)
                      for _, tool, t, m, _ in rows}
                ne = rows[0][4]
                m_in = by["input"][1]
                (tl, ml), (_, mr), (ts, ms) = by["Laplace2D"], by["Relocate2D"], by["SurfMesh"]
                if "error" in m_in or "error" in ms:
                    err = (m_in.get("error") or ms.get("error"))[:90]
                    print(f"| {name} | {case} | {seed} | {ne} | - | - | - | - | {err} |")
                    errors += 1
                    continue
                runs += 1
                stuck = ms.get("tangled_unmovable") or 0
                fixable_left += ms["tangled"] - stuck
                if "error" not in ml:
                    with_lap += 1
                    min_ge += ms["min"] >= ml["min"] - 1e-9
                    mean_ge += ms["mean"] >= ml["mean"] - 1e-9
                    lap_left += ml["tangled"]
                ratio = ts / tl if ts and tl else float("nan")
                ratios.append(ratio)

                def cell(m):
                    if "error" in m:
                        return "error: " + m["error"][:40]
                    return f"{m['tangled']}, {m['min']:.3f}, {m['mean']:.3f}"

                print(f"| {name} | {case} | {seed} | {ne} | {m_in['tangled']} | {cell(ml)} | "
                      f"{cell(mr)} | {ms['tangled']} ({stuck}), {ms['min']:.3f}, "
                      f"{ms['mean']:.3f} | {ratio:.2f} |", flush=True)
    gmsh.finalize()
    ratios.sort()
    med = ratios[len(ratios) // 2] if ratios else float("nan")
    print(f"\n{runs} runs ({errors} not comparable: an input Gmsh's checks or ours reject). "
          f"SurfMesh: {fixable_left} tangled elements left that have a movable node "
          f"(Laplace2D: {lap_left} tangled in all); minimum quality ≥ Laplace2D's in {min_ge}, "
          f"mean ≥ in {mean_ge} of the {with_lap} runs Laplace2D's output could be measured in; time / Laplace2D median {med:.2f}, "
          f"max {max(ratios) if ratios else float('nan'):.2f}.")


if __name__ == "__main__":
    main()
