#!/usr/bin/python3
"""SurfMesh on Gmsh meshes made with settings the other benchmarks do not use, each result
measured again from the file it wrote.

    /usr/bin/python3 bench/mesher_settings.py [--cli surfmesh] [--seed 1] [--meshes 20]
        [--parts a.step,b.brep] [--work DIR]

For ``--meshes`` meshes drawn at random (``--seed``) from the parts of ../shared/data/cad and
Gmsh's settings — algorithm MeshAdapt, Delaunay or Frontal-Delaunay; size diagonal / 8, 12,
17 or 25; sizes from curvature (12 elements per 2π) or not; order 1 or 2 — the command line
optimizes each mesh as meshed, fixed and sliding, with and without edge flips (order 1), one
thread. Every result is measured again with ``surfmesh measure`` from the mesh it wrote, and
each row is flagged where:

* REMEASURE: the written mesh measures other invalid / left-out counts than the report says;
* REMIN: its minimum quality differs from the report's;
* VALID->INVALID, MIN DOWN, SJ DOWN: on a valid input, the result has invalid elements, a
  lower minimum quality, or a lower minimum scaled Jacobian (``--metrics scaled_jacobian``,
  over the elements measured in both);
* MORE INVALID: on an invalid input, the result has more invalid elements.

A mesh Gmsh does not make within ``--mesh-timeout`` seconds is skipped (the u-joint with
curvature-based sizes can take longer than 10 minutes). The parts are read from
../shared/data/cad, never copied into this repository. Prints one row per run and the flags'
counts; bench/history/2026-12.md records what the first runs found.
"""
import argparse
import csv
import json
import os
import random
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.join(os.path.dirname(os.path.dirname(HERE)), "shared", "data", "cad")

MESHER = r"""
import gmsh, sys, math
part, div, alg, order, curv, out = sys.argv[1:7]
gmsh.initialize(); gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.occ.importShapes(part); gmsh.model.occ.synchronize()
b = gmsh.model.getBoundingBox(-1, -1)
gmsh.option.setNumber("Mesh.MeshSizeMax", math.dist(b[3:], b[:3]) / float(div))
gmsh.option.setNumber("Mesh.MeshSizeMin", 0)
gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", int(curv))
gmsh.option.setNumber("Mesh.Algorithm", int(alg))
gmsh.model.mesh.generate(2)
if int(order) > 1:
    gmsh.model.mesh.setOrder(int(order))
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1); gmsh.option.setNumber("Mesh.SaveAll", 0)
gmsh.write(out + ".msh"); gmsh.write(out + ".brep")
gmsh.finalize()
"""


def measure(cli, brep, msh, tag, work):
    """(the measure report, {element id: scaled Jacobian}) of ``msh``, or (None, None)."""
    rep, table = os.path.join(work, tag + ".json"), os.path.join(work, tag + ".csv")
    r = subprocess.run([cli, "measure", brep, msh, "--metrics", "scaled_jacobian", "--report",
                        rep, "--csv", table], capture_output=True, text=True, timeout=1800)
    if r.returncode:
        return None, None
    with open(table) as f:
        sj = {int(row["element_id"]): float(row["scaled_jacobian"]) for row in csv.DictReader(f)
              if row["scaled_jacobian"] not in ("", "nan")}
    with open(rep) as f:
        return json.load(f), sj


def flags(before, after, again, sj_in, sj_out):
    out = []
    if again is None:
        return ["REMEASURE failed"]
    s = again["stats"]
    if s["invalid"] != after["invalid"] or s["skipped"] != after["skipped"]:
        out.append(f"REMEASURE {s['invalid']}/{s['skipped']} vs {after['invalid']}/"
                   f"{after['skipped']}")
    if abs(s["min"] - after["min"]) > 1e-9:
        out.append(f"REMIN {s['min']:.4g} vs {after['min']:.4g}")
    if before["invalid"] == 0:
        if after["invalid"]:
            out.append(f"VALID->INVALID {after['invalid']}")
        if after["min"] < before["min"] - 1e-12:
            out.append(f"MIN DOWN {before['min']:.4g}->{after['min']:.4g}")
        common = [e for e in sj_in if e in sj_out]
        if common:
            a0, a1 = min(sj_in[e] for e in common), min(sj_out[e] for e in common)
            if a1 < a0 - 1e-9:
                out.append(f"SJ DOWN {a0:.4g}->{a1:.4g}")
    elif after["invalid"] > before["invalid"]:
        out.append(f"MORE INVALID {before['invalid']}->{after['invalid']}")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", default="surfmesh")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--meshes", type=int, default=20)
    ap.add_argument("--parts", default=None)
    ap.add_argument("--mesh-timeout", type=float, default=300)
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="surfmesh_settings_")
    os.makedirs(work, exist_ok=True)
    parts = (a.parts.split(",") if a.parts else
             sorted(p for p in os.listdir(SHARED) if p.endswith((".brep", ".step"))))
    rng = random.Random(a.seed)
    counts = {}
    runs = 0
    print("| mesh (part_div_algorithm_order_curvature) | run | elements | invalid before -> after "
          "| min q | mean q | s | flags |")
    print("|---|---|---:|---|---|---|---:|---|")
    for _ in range(a.meshes):
        part = rng.choice(parts)
        div, alg = rng.choice([8, 12, 17, 25]), rng.choice([1, 5, 6])
        order, curv = rng.choice([1, 1, 2]), rng.choice([0, 0, 12])
        name = f"{os.path.splitext(part)[0]}_{div}_{alg}_{order}_{curv}"
        base = os.path.join(work, name)
        if not os.path.exists(base + ".msh"):
            try:
                r = subprocess.run([sys.executable, "-c", MESHER, os.path.join(SHARED, part),
                                    str(div), str(alg), str(order), str(curv), base],
                                   capture_output=True, text=True, timeout=a.mesh_timeout)
            except subprocess.TimeoutExpired:
                print(f"| {name} | - | - | Gmsh took over {a.mesh_timeout:g} s | | | | |")
                continue
            if r.returncode:
                print(f"| {name} | - | - | Gmsh failed | | | | |")
                continue
        _, sj_in = measure(a.cli, base + ".brep", base + ".msh", name + "_in", work)
        if sj_in is None:
            print(f"| {name} | - | - | measure failed | | | | |")
            continue
        for boundary in ("fixed", "slide"):
            for topology in (("none", "flip") if order == 1 else ("none",)):
                tag = f"{name}_{boundary}_{topology}"
                out, rep = os.path.join(work, tag + ".msh"), os.path.join(work, tag + "_run.json")
                r = subprocess.run([a.cli, "optimize", base + ".brep", base + ".msh", "-o", out,
                                    "--report", rep, "--boundary", boundary, "--topology",
                                    topology, "--threads", "1"],
                                   capture_output=True, text=True)
                if r.returncode:
                    print(f"| {name} | {boundary} {topology} | - | failed: "
                          f"{r.stderr.strip()[-120:]} | | | | |")
                    counts["FAILED"] = counts.get("FAILED", 0) + 1
                    continue
                with open(rep) as f:
                    o = json.load(f)
                again, sj_out = measure(a.cli, base + ".brep", out, tag + "_out", work)
                b, af = o["before"], o["after"]
                found = flags(b, af, again, sj_in, sj_out or {})
                runs += 1
                for fl in found:
                    key = fl.split(" ")[0]
                    counts[key] = counts.get(key, 0) + 1
                print(f"| {name} | {boundary} {topology} | {b['elements'] + b['skipped']} | "
                      f"{b['invalid']} -> {af['invalid']} | {b['min']:.4f} -> {af['min']:.4f} | "
                      f"{b['mean']:.4f} -> {af['mean']:.4f} | {o['seconds']:.2f} | "
                      f"{'; '.join(found)} |", flush=True)
    print(f"\n{runs} runs; flags: " + (", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
                                     or "none"))


if __name__ == "__main__":
    main()
