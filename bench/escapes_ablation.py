#!/usr/bin/python3
"""Ablation of the sweeps' escapes (OptimizeOptions::escapes): on Gmsh meshes of the CAD parts
of ../shared/data/cad, perturbed until 2 % of the triangles are tangled, SurfMesh runs with
every escape, with each one turned off (BENCH_WITHOUT=name), and with none.

    /usr/bin/python3 bench/escapes_ablation.py --bench-dir BUILD/bench [--seeds 1,2,3]
        [--parts a.step,b.brep] [--amp 1.2] [--threads 1]

Prints one row per part and escape turned off: the tangled elements left over the seeds (and
those with a node that may move), the lowest minimum quality, the mean of the mean quality,
and the total time and its ratio to the run with every escape. The same code (bench_cad
measure) measures every result. Parts are read from ../shared/data/cad, never copied.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import gmsh

import gmsh_compare as gc

DEFAULT_PARTS = "occt_crankarm.brep,occt_housing_bottom.brep,occt_bottle.brep,occt_screw.step"
def escape_names(bench_dir):
    """The escapes' names as the core lists them (kEscapeNames, through bench_cad)."""
    out = subprocess.run([os.path.join(bench_dir, "bench_cad"), "escapes"], capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout)


def run(bench_dir, brep, inp, out, threads, without):
    """bench_cad optimize with the escapes `without` (comma-separated names) off, then the
    measure of its result."""
    if without:
        os.environ["BENCH_WITHOUT"] = without
    try:
        opt = gc.run_bench_cad(bench_dir, "optimize", brep, inp, out, threads)
    finally:
        os.environ.pop("BENCH_WITHOUT", None)
    if "error" in opt:
        sys.exit(f"bench_cad optimize failed (BENCH_WITHOUT={without}): {opt['error']}")
    return opt, gc.run_bench_cad(bench_dir, "measure", brep, out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench-dir", required=True)
    ap.add_argument("--parts", default=DEFAULT_PARTS)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--amp", type=float, default=1.2, help="perturbation in mesh sizes")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    cad = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data",
                       "cad")
    variants = ([("", "every escape")] +
                [(e, f"without {e}") for e in escape_names(args.bench_dir)] + [("all", "none")])
    gmsh.initialize()
    print("| part | escapes | tangled left (movable) | min q | mean q | s | time ratio |")
    print("|---|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as work:
        for part in args.parts.split(","):
            path = os.path.join(cad, part)
            if not os.path.exists(path):
                print(f"| {part} | (missing) | | | | | |")
                continue
            cases = []
            for seed in args.seeds.split(","):
                gc.build_case("part", path, None)
                _, _, tris = gc.mesh_arrays()
                gc.perturb(max(20, int(0.02 * tris.shape[0])), args.amp, seed=int(seed))
                brep = os.path.join(work, f"{part}_{seed}.brep")
                gmsh.write(brep)
                _, xyz, tris = gc.mesh_arrays()
                inp = os.path.join(work, f"{part}_{seed}_in.bin")
                gc.write_dump(inp, xyz, tris)
                cases.append((brep, inp))
            base_s = None
            for without, label in variants:
                left = movable = 0
                mins, means, secs = [], [], 0.0
                for k, (brep, inp) in enumerate(cases):
                    out = os.path.join(work, f"out_{k}.bin")
                    opt, m = run(args.bench_dir, brep, inp, out, args.threads, without)
                    left += int(m.get("tangled", 0))
                    movable += int(m.get("tangled", 0)) - int(opt.get("tangled_unmovable", 0))
                    mins.append(float(m.get("min", 0.0)))
                    means.append(float(m.get("mean", 0.0)))
                    secs += float(opt.get("seconds", 0.0))
                if base_s is None:
                    base_s = secs
                print(f"| {part} | {label} | {left} ({movable}) | {min(mins):.3f} | "
                      f"{sum(means) / len(means):.4f} | {secs:.2f} | "
                      f"{secs / base_s if base_s else float('nan'):.2f} |", flush=True)
    gmsh.finalize()


if __name__ == "__main__":
    main()
