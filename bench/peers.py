#!/usr/bin/python3
"""Every peer on the same inputs, judged by one judge (issue #45): bench/peers.sh runs this.

    /usr/bin/python3 bench/peers.py [quick|medium|full] [--json OUT.json] [--work DIR]
        [--plots DIR] [--cap N] [--only REGEX]
    python3 bench/peers.py gmsh-only --manifest WORK/manifest.json --label trixie   (in a root)

Cases: each is one CAD shape file and one mesh file, written once by Gmsh (this process); every
tool starts from that same pair of files.
  * torus: the paper's torus (OCC addTorus R=10 r=4, size 1.07), interior nodes moved in (u,v)
    on the surface until ≥ 73 triangles are tangled (gmsh_compare.perturb);
  * parts of ../shared/data/cad (read from there, never copied here), size = bounding-box
    diagonal / 21 and / 42, volumes removed (high_order_peers.raw_mesh): order 1 as meshed,
    order 1 perturbed (amplitude 1.2 × the size until 0.1 % of the triangles, at least 20, are
    tangled), orders 2 and 3 raw (setOrder without Gmsh's high-order optimization);
  * spheres (radius 1) of about 10³, 10⁴, 10⁵, 10⁶ triangles, perturbed as the parts;
  * FreeCAD's own FEM examples with a surface mesh (femexamples: the cantilever's quad4, quad8,
    tria3 and tria6 plates, mystran_plate, rc_wall_2d, the buckling plate, the five-face
    bending beam, the twisted square pipe, the I-beam, the two contact tubes), as FreeCAD
    builds them (bench/python/fem_examples.py, one freecadcmd) and perturbed in (u, v) of their
    faces (bench/fem_cases.py: the mesh classified on the shape's entities with its (u, v) in
    a .msh 4.1, so Gmsh's optimizers can run on it; second-order side nodes follow their
    corners).
quick: the torus, occt_bottle.brep at diagonal / 15 order 2 raw, a 10³ sphere. medium: the
torus, three parts at diagonal / 21 (all four kinds), spheres 10³–10⁵, the FEM examples raw and
perturbed. full: every part at both sizes, spheres up to 10⁶, the FEM examples.
--only REGEX keeps the cases whose name matches it (e.g. --only fem, --only '/21 o[23] raw'); the
JSON then goes to bench/out/peers-MODE-only-REGEX.json (REGEX's other characters than letters
and digits as _) and the plots to bench/out/ unless told.

Peers, each from the case's files (a peer that cannot run on this machine gets a note line):
  * SurfMesh: `surfmesh optimize --threads 1` (boundary fixed; curved elements: the default
    --high-order reference); time = the report's optimization seconds;
  * Gmsh of this Python (4.8.4 on bookworm): Laplace2D (niter 10) and Relocate2D for order 1,
    HighOrder, HighOrderElastic, HighOrderFastCurving for orders 2-3, on the shape with the
    mesh merged into it (its (u,v) saved), one process per run; an exception is the row's
    outcome; time = optimize() alone;
  * Gmsh 4.13 / 4.15: the same runs inside the trixie / sid roots of scripts/debian-root.sh
    (this script in gmsh-only mode there), when /var/cache/surfmesh-roots/<suite> exists and
    this runs as root;
  * Netgen's OCC surface optimizer (netgen_surface_opt.py, needs netgen-headers and
    libnglib-dev; "smsmSmSm", no node removal) for order 1;
  * Mesquite (bench/mesquite/driver.cpp, built once per run by bench/mesquite/build.sh), on
    the spheres only, when MESQUITE_DIR is set to an installed Mesquite (a note otherwise, or
    when the driver does not build): UntangleWrapper then ShapeImprover with the nodes on a
    SphericalDomain (center 0, radius 1), no node fixed, two runs capped at SurfMesh's time on
    the case and at 10 × it (Mesquite's CPU-time criteria); time = the driver's wall seconds
    of both wrappers;
Judge, the same for every mesh: `surfmesh measure --metrics jacobian_ratio` (invalid elements:
tangled, or for curved ones not proven valid, the certificate; min / mean shape quality; min /
mean scaled Jacobian ratio); a mesh it refuses (nodes off the shape) is measured again with
--tolerance = 5 % of the diagonal and the row says so. The largest distance of the nodes to the
shape is measured by OCC through FreeCAD (bench/python/node_distance.py, all meshes in one
freecadcmd; at most --cap nodes per mesh, the moved ones first) and checked against the judge's
own (its bridge's max_distance: OCC's may not exceed it).

Output: a Markdown table on stdout (case, tool, elements, invalid before → after, min / mean
quality, min / mean Jacobian ratio, max distance to the CAD, seconds, time ratio to the fastest
run of the case leaving at most as many invalid elements); raw JSON (--json); in medium and
full mode PNG plots (--plots: quality against time per case, time against elements on the
spheres). Exit status 1 when the suite itself is broken (SurfMesh or the judge fails, a row is
missing, a run crashes in quick mode), never on a peer's speed or results.
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import gmsh

import fem_cases
import gmsh_compare as gc
import high_order_peers as hop

try:  # Netgen's OCC surface optimizer, where Debian's netgen can be built against
    import netgen_surface_opt as ngopt
except Exception:  # noqa: BLE001 - optional peer
    ngopt = None

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
SURFMESH = os.environ.get("SURFMESH_BIN") or shutil.which("surfmesh") or "surfmesh"
ROOTS = os.environ.get("SURFMESH_ROOTS_DIR", "/var/cache/surfmesh-roots")
ALL_PARTS = sorted(f for f in os.listdir(gc.SHARED) if f.endswith((".step", ".brep"))) \
    if os.path.isdir(gc.SHARED) else []
MEDIUM_PARTS = ["occt_bottle.brep", "occt_crankarm.brep", "nist_pmi_1.step"]
GMSH_METHODS = {1: [("Laplace2D", 10), ("Relocate2D", 1)],
                2: [("HighOrder", 1), ("HighOrderElastic", 1), ("HighOrderFastCurving", 1)]}
TIMEOUT = {"quick": 120, "medium": 300, "full": 1800}


def case_list(mode):
    """The cases of a mode: dicts with name, source (torus, sphere or a part file), div (size =
    diagonal / div), order, kind (raw or perturbed) and, for spheres, the triangle target."""
    cases = [dict(name="torus perturbed", source="torus", order=1, kind="perturbed")]
    if mode == "quick":
        parts, divs, kinds, spheres = ["occt_bottle.brep"], [15], [(2, "raw")], [1000]
    elif mode == "medium":
        parts, divs, spheres = MEDIUM_PARTS, [21], [1000, 10000, 100000]
        kinds = [(1, "raw"), (1, "perturbed"), (2, "raw"), (3, "raw")]
    else:
        parts, divs, spheres = ALL_PARTS, [21, 42], [1000, 10000, 100000, 1000000]
        kinds = [(1, "raw"), (1, "perturbed"), (2, "raw"), (3, "raw")]
    for part in parts:
        for div in divs:
            for order, kind in kinds:
                stem = part.rsplit(".", 1)[0]
                cases.append(dict(name=f"{stem} /{div} o{order} {kind}", source=part, div=div,
                                  order=order, kind=kind))
    for n in spheres:
        cases.append(dict(name=f"sphere 1e{round(math.log10(n))} perturbed", source="sphere",
                          order=1, kind="perturbed", target=n))
    if mode != "quick":
        cases += fem_cases.cases()
    return cases


def file_stem(case):
    return "".join(c if c.isalnum() else "_" for c in case["name"])


def write_case(case, work, seed=5):
    """Meshes one case with Gmsh and writes its shape (.brep) and mesh (.msh with the nodes'
    (u,v)); returns (shape path, mesh path, tangled triangles after the perturbation or None,
    meshing seconds). Needs gmsh initialized. A FEM example: fem_cases.write_case (its shape
    is FreeCAD's .brep)."""
    if case["source"] == "fem":
        return fem_cases.write_case(case, work, os.path.join(work, file_stem(case)), seed)
    gmsh.clear()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
    t0 = time.perf_counter()
    target = amp = None
    if case["source"] == "torus":
        target, amp, _ = gc.build_case("torus", None, None)  # sets gc.H_LOCAL
    elif case["source"] == "sphere":
        gmsh.model.occ.addSphere(0, 0, 0, 1.0)
        gmsh.model.occ.synchronize()
        # a Frontal-Delaunay triangle is about 0.5 h² on a sphere of area 4π
        h = math.sqrt(4 * math.pi / (0.5 * case["target"]))
        gc.set_mesh_size(h)
        gmsh.model.mesh.generate(2)
        gc.H_LOCAL = h
    else:
        hop.raw_mesh(os.path.join(gc.SHARED, case["source"]), 1, case["div"])
        gc.H_LOCAL = gc.bbox_diagonal() / case["div"]
    tangled = None
    if case["kind"] == "perturbed":
        ntri = len(gmsh.model.mesh.getElementsByType(2)[0])
        if target is None:
            target, amp = max(20, int(1e-3 * ntri)), 1.2
        tangled = gc.perturb(target, amp, seed=seed)
    if case["order"] > 1:
        gmsh.model.mesh.setOrder(case["order"])
    seconds = time.perf_counter() - t0
    stem = os.path.join(work, file_stem(case))
    gmsh.option.setNumber("Mesh.SaveParametric", 1)
    gmsh.write(stem + ".brep")
    gmsh.write(stem + ".msh")
    gmsh.option.setNumber("Mesh.SaveParametric", 0)
    return stem + ".brep", stem + ".msh", tangled, seconds


def gmsh_run(shape, mesh, method, niter, out, threads=1):
    """One Gmsh optimizer run on a case's files, in this process (the gmsh-run worker): the
    shape opened, the mesh merged into it, optimize(method) timed. Returns a dict."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", threads)
    gmsh.open(shape)
    gmsh.merge(mesh)
    res = {"gmsh": gmsh_version()}
    t0 = time.perf_counter()
    try:
        gmsh.model.mesh.optimize(method, niter=niter)
        res["seconds"] = time.perf_counter() - t0
        gmsh.write(out)
        res["output"] = out
    except Exception as err:  # noqa: BLE001 - Gmsh aborts some runs: the row's outcome
        res["error"] = (str(err).strip().splitlines() or ["?"])[0]
    gmsh.finalize()
    return res


def gmsh_peer(shape, mesh, method, niter, out, timeout, python=sys.executable):
    """gmsh_run in a process of its own (a crash or a hang is that run's, not the suite's)."""
    cmd = [python, os.path.abspath(__file__), "gmsh-run", shape, mesh, method, str(niter), out]
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s", "crash": False}
    for line in reversed(run.stdout.splitlines()):
        if line.startswith("PEERS_JSON "):
            return json.loads(line[len("PEERS_JSON "):])
    return {"error": f"crashed (exit {run.returncode}): {last_line(run)}", "crash": True}


def surfmesh_peer(shape, mesh, out, report, timeout, extra=()):
    cmd = [SURFMESH, "optimize", shape, mesh, "-o", out, "--report", report, "--threads", "1",
           *extra]
    t0 = time.perf_counter()
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s", "crash": True}
    wall = time.perf_counter() - t0
    if run.returncode != 0 or not os.path.exists(report):
        return {"error": f"exit {run.returncode}: {last_line(run)}", "crash": True}
    with open(report) as f:
        r = json.load(f)
    return {"seconds": r["seconds"], "wall_seconds": wall, "sweeps": r.get("sweeps"),
            "reason": r.get("reason"), "output": out}


def last_line(run):
    """The last line a finished subprocess wrote (stderr first), cut to 200 characters."""
    tail = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["no output"]
    return tail[0][:200]


def case_arrays(first, *merged, faces=None):
    """(nodes, 0-based triangles, faces(triangles) or None) of a case's files opened in Gmsh
    (`first` opened, `merged` merged into it), Gmsh initialized around the reading: the suite
    finalizes it once the cases are written."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(first)
        for f in merged:
            gmsh.merge(f)
        _, xyz, tris = gc.mesh_arrays()
        return xyz, tris, faces(tris) if faces else None
    finally:
        gmsh.finalize()


def netgen_peer(shape, mesh, out):
    """Netgen's OCC surface optimizer on an order-1 case (bench/netgen_surface_opt.py)."""
    import flips_compare as fc

    xyz, tris, faces = case_arrays(shape, mesh, faces=fc.triangle_faces)
    t0 = time.perf_counter()
    nx, nt = ngopt.optimize(shape, xyz, tris, faces, sched="smsmSmSm")
    seconds = time.perf_counter() - t0
    write_msh_tri3(out, nx, nt)
    return {"seconds": seconds, "output": out, "note": "time includes the helper's setup"}


def mesquite_available(work):
    """(driver path, '') when the Mesquite peer can run, else (None, why not): MESQUITE_DIR set
    and bench/mesquite/build.sh building the driver against it (once per suite run)."""
    mdir = os.environ.get("MESQUITE_DIR")
    if not mdir:
        return None, "MESQUITE_DIR is not set to a built Mesquite"
    exe = os.path.join(work, "mesquite_driver")
    run = subprocess.run(["sh", os.path.join(HERE, "mesquite", "build.sh"), exe],
                         capture_output=True, text=True)
    if run.returncode != 0 or not os.path.exists(exe):
        return None, (f"MESQUITE_DIR={mdir} is set, but bench/mesquite/build.sh failed "
                      f"(exit {run.returncode}): {last_line(run)}")
    return exe, ""


def mesquite_input(mesh, path):
    """The driver's input (bench/mesquite/driver.cpp): "N T", N lines x y z, T lines of
    0-based i j k, from a linear triangle mesh file (gmsh initialized around the reading)."""
    xyz, tris, _ = case_arrays(mesh)
    with open(path, "w") as f:
        f.write("%d %d\n" % (len(xyz), len(tris)))
        np.savetxt(f, xyz, fmt="%.17g")
        np.savetxt(f, tris, fmt="%d")


def mesquite_peer(exe, inp, out, seconds, timeout):
    """The Mesquite driver on a sphere case's input (mesquite_input), capped at `seconds`, in a
    process of its own; its moved nodes written as a Gmsh file for the judge."""
    txt = out[:-4] + ".txt"
    cmd = [exe, inp, txt, repr(seconds)]
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + seconds)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout + seconds:.0f} s", "cap_seconds": seconds}
    res = None
    for line in reversed(run.stdout.splitlines()):
        if line.startswith("{"):
            res = json.loads(line)
            break
    if res is None or not os.path.exists(txt):
        return {"error": f"crashed (exit {run.returncode}): {last_line(run)}",
                "cap_seconds": seconds}
    with open(txt) as f:
        n, t = (int(v) for v in f.readline().split())
        data = np.loadtxt(f)
    write_msh_tri3(out, data[:n], data[n:n + t].astype(np.int64))
    return {**res, "cap_seconds": seconds, "output": out}


def write_msh_tri3(path, xyz, tris):
    """A Gmsh 2.2 ASCII file of linear triangles (0-based connectivity)."""
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(xyz))
        for i, p in enumerate(np.asarray(xyz, float)):
            f.write("%d %.17g %.17g %.17g\n" % (i + 1, p[0], p[1], p[2]))
        f.write("$EndNodes\n$Elements\n%d\n" % len(tris))
        for i, t in enumerate(np.asarray(tris, np.int64) + 1):
            f.write("%d 2 0 %d %d %d\n" % (i + 1, t[0], t[1], t[2]))
        f.write("$EndElements\n")


class SuiteError(RuntimeError):
    """The suite itself is broken (not a peer's result)."""


# The rows whose failure means the suite is broken (a peer's failure is the peer's row).
OURS = ("input", "SurfMesh")


def judge(shape, mesh, report, diag):
    """`surfmesh measure` on one mesh: a dict of the judge's numbers; a refused mesh (nodes off
    the shape) is measured with a 5 % tolerance and marked off_shape. SuiteError otherwise."""
    def measure(*extra):
        cmd = [SURFMESH, "measure", shape, mesh, "--metrics", "jacobian_ratio", "--report",
               report, *extra]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=600)

    if os.path.exists(report):
        os.remove(report)
    run = measure()
    off = None
    if run.returncode == 2 and "farther than the tolerance" in run.stderr:
        off = run.stderr.strip().splitlines()[-1][:200]
        run = measure("--tolerance", repr(0.05 * diag))
    if run.returncode != 0 or not os.path.exists(report):
        raise SuiteError(f"judge failed on {mesh} (exit {run.returncode}): {last_line(run)}")
    with open(report) as f:
        r = json.load(f)
    s, jr = r["stats"], r["metrics"]["jacobian_ratio"]
    return {"elements": s["elements"], "invalid": s["invalid"], "tangled": s["tangled"],
            "skipped": s.get("skipped", 0),
            "min_q": s["min"], "mean_q": s["mean"], "min_jr": jr["min"], "mean_jr": jr["mean"],
            "judge_max_distance": r["bridge"]["max_distance"], "off_shape": off}


def mesh_nodes(mesh):
    """Node tags and coordinates of a mesh file (a clean Gmsh model)."""
    gmsh.clear()
    gmsh.open(mesh)
    tags, xyz = gc.sorted_nodes()
    return tags, xyz


def sample_nodes(mesh, base, cap, path, rng):
    """Writes at most `cap` nodes of `mesh` to `path` (.npy): those moved from the case's input
    (same tag, other position) first, the rest at random."""
    tags, xyz = mesh_nodes(mesh)
    order = rng.permutation(len(tags))
    if base is not None and len(tags) > cap:
        btags, bxyz = base
        pos = np.searchsorted(btags, tags)
        ok = (pos < len(btags)) & (btags[np.minimum(pos, len(btags) - 1)] == tags)
        moved = np.zeros(len(tags), bool)
        moved[ok] = np.any(bxyz[pos[ok]] != xyz[ok], axis=1)
        order = np.concatenate([order[moved[order]], order[~moved[order]]])
    np.save(path, xyz[order[:cap]])
    return min(cap, len(tags))


def occ_distances(items, work):
    """bench/python/node_distance.py over every (key, shape, nodes.npy), in one freecadcmd."""
    job = os.path.join(work, "distance_job.json")
    with open(job, "w") as f:
        json.dump([{"key": k, "shape": s, "nodes": n} for k, s, n in items], f)
    env = dict(os.environ, SURFMESH_DIST_JOB=job)
    run = subprocess.run(["freecadcmd", os.path.join(HERE, "python", "node_distance.py")],
                         capture_output=True, text=True, env=env, timeout=3600)
    if not os.path.exists(job + ".out.json"):
        tail = (run.stderr or run.stdout).strip().splitlines()[-3:]
        raise SuiteError("node_distance.py wrote nothing: " + " / ".join(tail))
    with open(job + ".out.json") as f:
        return json.load(f)


def root_available(suite):
    """'' when Gmsh of the Debian root `suite` can be run, else why not."""
    if os.environ.get("SURFMESH_LANE"):
        return f"inside the {os.environ['SURFMESH_LANE']} root already"
    if not os.path.isdir(os.path.join(ROOTS, suite)):
        return f"{os.path.join(ROOTS, suite)} is absent (scripts/debian-root.sh {suite} makes it)"
    if os.geteuid() != 0:
        return "not root (scripts/debian-root.sh needs it)"
    return ""


def netgen_available():
    if ngopt is None:
        return "netgen_surface_opt.py does not import"
    if not os.path.exists("/usr/include/netgen/include/meshing.hpp") or not os.path.isdir(ngopt.NG):
        return "Debian's netgen-headers / libnglib-dev are not installed"
    return ""


def run_gmsh_only(a):
    """In a Debian root: the Gmsh runs of every case of a manifest, outputs beside the host's."""
    with open(a.manifest) as f:
        man = json.load(f)
    rows = []
    for c in man["cases"]:
        for method, niter in GMSH_METHODS[min(c["order"], 2)]:
            out = c["mesh"][:-4] + f"_{a.label}_{method}.msh"
            r = gmsh_peer(c["shape"], c["mesh"], method, niter, out, man["timeout"])
            rows.append({"case": c["name"], "method": method, **r})
            print(f"{c['name']}: Gmsh {r.get('gmsh', '?')} {method}: "
                  f"{r.get('seconds', r.get('error'))}", flush=True)
    with open(os.path.join(os.path.dirname(a.manifest), f"gmsh-{a.label}.json"), "w") as f:
        json.dump(rows, f, indent=1)


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def table(rows):
    """The Markdown table of the runs (rows of main)."""
    lines = ["| case | tool | elements | invalid before → after | min / mean q "
             "| min / mean Jacobian ratio | max dist to CAD (OCC) | s | ratio |",
             "|---|---|---:|---:|---|---|---:|---:|---:|"]
    for r in rows:
        j = r.get("judge")
        if j is None:
            lines.append(f"| {r['case']} | {r['tool']} | | | {r.get('error', '')} | | | | |")
            continue
        best = [q["seconds"] for q in rows if q["case"] == r["case"] and q.get("judge")
                and q.get("seconds") is not None and q["judge"]["invalid"] <= j["invalid"]]
        ratio = (f"{r['seconds'] / min(best):.2f}" if r.get("seconds") is not None and best
                 and min(best) > 0 else "")
        before = r.get("invalid_before")
        inv = f"{before} → {j['invalid']}" if r["tool"] != "input" else f"{j['invalid']}"
        if j.get("skipped"):  # left out of the measure (folded pairs, collapsed elements)
            inv += f" (+{j['skipped']} left out)"
        dist = fmt(r.get("occ_distance"), ".1e")
        if j.get("off_shape"):
            dist += " (off the shape)"
        lines.append(
            f"| {r['case']} | {r['tool']} | {j['elements']} | {inv} "
            f"| {j['min_q']:.3f} / {j['mean_q']:.3f} | {j['min_jr']:.3f} / {j['mean_jr']:.3f} "
            f"| {dist} | {fmt(r.get('seconds'), '.3f')} | {ratio} |")
    return "\n".join(lines)


def plots(rows, cases, directory):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("note: matplotlib is not importable: no plots (apt-get install python3-matplotlib)")
        return []
    os.makedirs(directory, exist_ok=True)  # (--plots may name a new directory)
    tools = sorted({r["tool"] for r in rows if r["tool"] != "input"})
    marks = dict(zip(tools, "o s ^ v D P X * h < >".split() * 3))
    timed = [c["name"] for c in cases
             if any(r["case"] == c["name"] and r.get("seconds") and r.get("judge") for r in rows)]
    ncol = 4
    nrow = max(1, math.ceil(len(timed) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 3.2 * nrow), squeeze=False)
    for ax, name in zip(axes.flat, timed):
        for r in rows:
            if r["case"] == name and r.get("seconds") and r.get("judge"):
                ax.scatter(r["seconds"], r["judge"]["mean_jr"] if case_order(cases, name) > 1
                           else r["judge"]["min_q"], marker=marks[r["tool"]], label=r["tool"])
        ax.set_xscale("log")
        ax.set_title(name, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(timed):]:
        ax.axis("off")
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=4, fontsize=8)
    fig.suptitle("quality (order 1: min shape quality; curved: mean Jacobian ratio) "
                 "against seconds", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.97))
    out1 = os.path.join(directory, "peers_quality_time.png")
    fig.savefig(out1, dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for tool in tools:
        pts = sorted((r["judge"]["elements"], r["seconds"]) for r in rows
                     if r["tool"] == tool and r["case"].startswith("sphere") and r.get("judge")
                     and r.get("seconds"))
        if pts:
            ax.plot(*zip(*pts), marker=marks[tool], label=tool)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("triangles (perturbed sphere)")
    ax.set_ylabel("seconds")
    if ax.get_legend_handles_labels()[0]:  # (no sphere among the cases of --only)
        ax.legend(fontsize=8)
    fig.tight_layout()
    out2 = os.path.join(directory, "peers_scaling.png")
    fig.savefig(out2, dpi=80)
    plt.close(fig)
    return [out1, out2]


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "gmsh-run":  # the worker of gmsh_peer
        shape, mesh, method, niter, out = sys.argv[2:7]
        print("PEERS_JSON " + json.dumps(gmsh_run(shape, mesh, method, int(niter), out)))
        return 0
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", nargs="?", default="quick",
                    choices=["quick", "medium", "full", "gmsh-only"])
    ap.add_argument("--json", default=None, help="raw rows (default: bench/out/peers-MODE.json)")
    ap.add_argument("--work", default=None, help="meshes and reports (default: a temp dir)")
    ap.add_argument("--plots", default=None, help="PNG plots here (medium, full; default docs/)")
    ap.add_argument("--cap", type=int, default=None,
                    help="nodes per mesh measured by OCC (default 1500 quick, 2000 otherwise)")
    ap.add_argument("--only", default=None,
                    help="only the cases whose name matches this regular expression (e.g. fem, "
                    "'/21 o[23] raw')")
    ap.add_argument("--manifest", help="gmsh-only: the host's manifest.json")
    ap.add_argument("--label", help="gmsh-only: the root's name")
    a = ap.parse_args()
    if a.mode == "gmsh-only":
        run_gmsh_only(a)
        return 0
    t_start = time.perf_counter()
    mode = a.mode
    cap = a.cap or (1500 if mode == "quick" else 2000)
    timeout = TIMEOUT[mode]
    only = "".join(ch if ch.isalnum() else "_" for ch in a.only) if a.only else ""
    out_json = a.json or os.path.join(HERE, "out", f"peers-{mode}"
                                      + (f"-only-{only}" if only else "") + ".json")
    cases = [c for c in case_list(mode) if not a.only or re.search(a.only, c["name"])]
    if not cases:
        print(f"no case of {mode} mode matches {a.only!r}", file=sys.stderr)
        return 2
    roots = {s: root_available(s) if mode != "quick" else
             "not in quick mode (scripts/test.sh runs the quick suite in each root)"
             for s in ("trixie", "sid")}
    work = a.work
    if work is None and any(v == "" for v in roots.values()):
        work = os.path.join(HERE, "out", f"work-{mode}")  # the roots see the repository
    work = work or tempfile.mkdtemp(prefix="surfmesh_peers_")
    os.makedirs(work, exist_ok=True)
    inside = os.path.realpath(work).startswith(os.path.realpath(REPO) + os.sep)
    for s, why in roots.items():
        if not why and not inside:  # the roots mount the repository only
            roots[s] = (f"the work directory {work} is outside the repository, which is all "
                        "the roots see (use --work bench/out/...)")

    os.makedirs(os.path.dirname(os.path.abspath(out_json)), exist_ok=True)
    gmsh.initialize()
    version = gmsh_version()
    notes = [f"Gmsh {version} (this Python); SurfMesh: {SURFMESH}; work dir {work}"]
    for s, why in roots.items():
        if why:
            notes.append(f"Gmsh of the {s} root skipped: {why}")
    ng = netgen_available()
    if ng:
        notes.append(f"Netgen skipped: {ng}")
    mq_exe, mq = mesquite_available(work)
    if mq:
        notes.append(f"Mesquite skipped: {mq}")
    for n in notes:
        print("note: " + n, flush=True)
    first_notes = len(notes)  # those below are printed after the table

    problems = []
    gmsh.option.setNumber("General.Terminal", 0)
    fem = [c["example"] for c in cases if c["source"] == "fem"]
    if fem:  # FreeCAD builds the examples once (one freecadcmd)
        fem_cases.export(work, sorted(set(fem)))
    manifest = []
    for c in cases:
        c["shape"], c["mesh"], c["perturbed_tangled"], c["mesh_seconds"] = write_case(c, work)
        manifest.append({k: c[k] for k in ("name", "shape", "mesh", "order")})
        gmsh.clear()
        gmsh.open(c["shape"])
        c["diag"] = gc.bbox_diagonal()
    with open(os.path.join(work, "manifest.json"), "w") as f:
        json.dump({"cases": manifest, "timeout": timeout}, f)
    gmsh.finalize()

    root_rows = {}
    for s, why in roots.items():
        if why:
            continue
        cmd = [os.path.join(REPO, "scripts", "debian-root.sh"), s, "bench/peers.sh",
               "gmsh-only", "--manifest", os.path.join(work, "manifest.json"), "--label", s]
        run = subprocess.run(cmd, capture_output=True, text=True)
        try:
            with open(os.path.join(work, f"gmsh-{s}.json")) as f:
                root_rows[s] = json.load(f)
        except OSError:
            problems.append(f"the {s} root's Gmsh runs wrote nothing (exit {run.returncode}): "
                            + " / ".join(run.stderr.strip().splitlines()[-2:]))

    rows = []
    for c in cases:
        stem = c["mesh"][:-4]
        runs = [("input", c["mesh"], {})]
        r = surfmesh_peer(c["shape"], c["mesh"], stem + "_surfmesh.msh",
                          stem + "_surfmesh.json", timeout)
        if r.get("crash"):
            problems.append(f"{c['name']}: SurfMesh {r['error']}")
        runs.append(("SurfMesh", r.get("output"), r))
        for method, niter in GMSH_METHODS[min(c["order"], 2)]:
            r = gmsh_peer(c["shape"], c["mesh"], method, niter, stem + f"_{method}.msh",
                          timeout)
            if r.get("crash"):  # the peer's outcome (its row says so), not the suite's
                notes.append(f"{c['name']}: Gmsh {method} {r['error']}")
            runs.append((f"Gmsh {version} {method}", r.get("output"), r))
        for s, rr in root_rows.items():
            for r in rr:
                if r["case"] == c["name"]:
                    runs.append((f"Gmsh {r.get('gmsh', s)} {r['method']}", r.get("output"), r))
        if c["order"] == 1 and not ng and c.get("quads"):
            notes.append(f"{c['name']}: Netgen not run (its driver takes triangles only)")
        elif c["order"] == 1 and not ng:
            try:
                r = netgen_peer(c["shape"], c["mesh"], stem + "_netgen.msh")
            except Exception as err:  # noqa: BLE001 - a peer's failure is its row
                r = {"error": f"{type(err).__name__}: {str(err)[:200]}"}
                notes.append(f"{c['name']}: Netgen {r['error']}")
            runs.append(("Netgen", r.get("output"), r))
        if c["source"] == "sphere" and mq_exe:
            ours = runs[1][2].get("seconds")
            if ours is None:
                notes.append(f"{c['name']}: Mesquite not run (no SurfMesh time to cap it at)")
            else:
                inp = stem + "_mesquite_in.txt"
                try:
                    mesquite_input(c["mesh"], inp)
                except Exception as err:  # noqa: BLE001 - a peer's failure is its row
                    inp = None
                    bad = {"error": f"no input: {type(err).__name__}: {str(err)[:200]}"}
                for label, factor in (("SurfMesh's time", 1), ("10× time", 10)):
                    r = (mesquite_peer(mq_exe, inp, stem + f"_mesquite_{factor}x.msh",
                                       factor * ours, timeout) if inp else dict(bad))
                    if r.get("error"):  # the peer's outcome (its row), not the suite's
                        notes.append(f"{c['name']}: Mesquite ({label}) {r['error']}")
                    runs.append((f"Mesquite ({label})", r.get("output"), r))
        for tool, mesh, r in runs:
            row = {"case": c["name"], "tool": tool, "mesh": mesh,
                   **{k: v for k, v in r.items() if k not in ("output", "crash")}}
            if mesh is not None:
                try:
                    row["judge"] = judge(c["shape"], mesh, mesh[:-4] + "_judge.json", c["diag"])
                except (SuiteError, subprocess.TimeoutExpired) as err:
                    # the judge must read the input and SurfMesh's result; a peer's output it
                    # cannot read is that peer's row
                    (problems if tool in OURS else notes).append(f"{c['name']}, {tool}: {err}")
                    row["judge_error"] = str(err)[:300]
            rows.append(row)
        inp = rows[-len(runs)]["judge"]["invalid"] if rows[-len(runs)].get("judge") else None
        for row in rows[-len(runs):]:
            row["invalid_before"] = inp
        print(f"{c['name']}: {len(runs)} runs judged ({time.perf_counter() - t_start:.0f} s)",
              file=sys.stderr, flush=True)

    with open(out_json, "w") as f:  # the rows so far, should the distances not end
        json.dump({"mode": mode, "partial": True, "rows": rows}, f, indent=1)
    # the distance half of the judge: OCC, every mesh of the run in one freecadcmd
    rng = np.random.default_rng(1)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    items, base = [], {}
    for k, row in enumerate(rows):
        if row.get("mesh") is None:
            continue
        case = next(c for c in cases if c["name"] == row["case"])
        if row["tool"] == "input":
            base[row["case"]] = mesh_nodes(row["mesh"])
        npy = os.path.join(work, f"nodes_{k}.npy")
        row["occ_nodes"] = sample_nodes(row["mesh"], base.get(row["case"]), cap, npy, rng)
        items.append((str(k), case["shape"], npy))
    gmsh.finalize()
    try:
        dist = occ_distances(items, work)
    except (SuiteError, subprocess.TimeoutExpired) as err:
        problems.append(str(err))
        dist = {}
    for k, row in enumerate(rows):
        if row.get("mesh") is None:
            continue
        d = dist.get(str(k))
        if d is None or "error" in d:
            (problems if row["tool"] in OURS else notes).append(
                f"{row['case']}, {row['tool']}: no OCC distance "
                f"({(d or {}).get('error', 'missing')})")
            continue
        row["occ_distance"] = d["max"]
        j = row.get("judge")
        diag = next(c["diag"] for c in cases if c["name"] == row["case"])
        row["occ_nodes_checked"] = d["nodes"]
        # linear meshes: every node is a corner, which the judge measures to the trimmed shape
        # as OCC does (a curved element's side node may be on its face's surface outside the
        # trimmed face: the judge measures it to the surface, OCC to the face)
        if (j and not j["off_shape"] and case_order(cases, row["case"]) == 1
                and d["max"] > j["judge_max_distance"] + 1e-7 * diag):
            (problems if row["tool"] in OURS else notes).append(
                f"{row['case']}, {row['tool']}: OCC distance {d['max']:.3e} above "
                f"the judge's {j['judge_max_distance']:.3e}")

    expected = sum(1 for _ in cases)  # every case has its input and SurfMesh rows at least
    for c in cases:
        for tool in ("input", "SurfMesh"):
            if not any(r["case"] == c["name"] and r["tool"] == tool and r.get("judge")
                       for r in rows):
                problems.append(f"{c['name']}: no judged {tool} row")
    wall = time.perf_counter() - t_start
    print()
    print(table(rows))
    print()
    result = {"mode": mode, "date": time.strftime("%Y-%m-%d"), "revision": revision(),
              "wall_seconds": wall, "notes": notes, "problems": problems, "cap": cap,
              "cases": [{k: v for k, v in c.items()} for c in cases], "rows": rows}
    if mode != "quick":
        result["plots"] = plots(rows, cases, a.plots or (
            os.path.join(HERE, "out") if a.only else os.path.join(REPO, "docs")))
    with open(out_json, "w") as f:
        json.dump(result, f, indent=1)
    print(f"{len(rows)} rows, {expected} cases, {wall:.0f} s; raw JSON in {out_json}")
    for n in notes[first_notes:]:
        print("NOTE: " + n)
    for p in problems:
        print("PROBLEM: " + p)
    return 1 if problems else 0


def case_order(cases, name):
    return next(c["order"] for c in cases if c["name"] == name)


def gmsh_version():
    """Gmsh's own version (the Python module's __version__ may say 4.8.0 for 4.8.4)."""
    try:
        return gmsh.option.getString("General.Version")
    except Exception:  # noqa: BLE001 - gmsh not initialized
        return gmsh.__version__


def revision():
    """The repository's revision, "?" where git is not at hand (a Debian root has none)."""
    try:
        run = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True)
    except OSError:
        return "?"
    return run.stdout.strip() or "?"


if __name__ == "__main__":
    sys.exit(main())
