"""FreeCAD mesh ↔ arrays conversion cost versus the optimization (run with freecadcmd).

    freecadcmd bench/python/bench_conversion.py [-- N_TRIANGLES]

Builds a Mesh.Mesh of about N triangles (default 1M) on a torus (R=10, r=4): a structured
grid with 2 % of its nodes moved by 1.3 cells. Times SurfMesh's conversion of the Mesh.Mesh
to arrays (read_mesh), back (rebuild with every node moved), and SurfMesh.optimize on it: each
part of the call (``OptimizeResult.timings``: reading the mesh, CAD recovery, the two quality
reports, the optimizer, the new mesh) and the whole call. Prints a table.
"""
import math
import sys
import time

import numpy as np

import FreeCAD  # noqa: F401
import Mesh  # noqa: F401
import Part

from SurfMesh.app import api, conversion

n_target = 1_000_000
args = [a for a in sys.argv[1:] if a != "--" and not a.endswith(".py")]
if args:
    n_target = int(float(args[0]))

shape = Part.makeTorus(10, 4)
# A structured grid on the torus (BRepMesh takes tens of minutes at 10⁶ triangles), with 2 % of
# the nodes moved by 1.3 cells in (u,v) as in bench_sweep: a Mesh.Mesh of ~n_target triangles.
aspect = 2.5  # 2π·10 / (2π·4): roughly square cells
nv = max(4, round(math.sqrt(n_target / 2 / aspect)))
nu = max(4, round(n_target / 2 / nv))
rng = np.random.default_rng(7)
uu, vv = np.meshgrid(np.arange(nu) * 2 * math.pi / nu, np.arange(nv) * 2 * math.pi / nv,
                     indexing="ij")
uu, vv = uu.ravel(), vv.ravel()
moved = rng.random(uu.size) < 0.02
uu[moved] += 1.3 * 2 * math.pi / nu * rng.uniform(-1, 1, moved.sum())
vv[moved] += 1.3 * 2 * math.pi / nv * rng.uniform(-1, 1, moved.sum())
pts = np.column_stack([(10 + 4 * np.cos(vv)) * np.cos(uu), (10 + 4 * np.cos(vv)) * np.sin(uu),
                       4 * np.sin(vv)])
ii, jj = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
a00 = (ii * nv + jj).ravel()
a10 = (((ii + 1) % nu) * nv + jj).ravel()
a01 = (ii * nv + (jj + 1) % nv).ravel()
a11 = (((ii + 1) % nu) * nv + (jj + 1) % nv).ravel()
tris = np.concatenate([np.column_stack([a00, a10, a11]), np.column_stack([a00, a11, a01])])
t0 = time.perf_counter()
vecs = [FreeCAD.Vector(*p) for p in pts.tolist()]
mesh = Mesh.Mesh((vecs, [tuple(t) for t in tris.tolist()]))
t_mesh = time.perf_counter() - t0
n_el = mesh.CountFacets

t0 = time.perf_counter()
data = conversion.read_mesh(mesh)
t_read = time.perf_counter() - t0

shifted = data.nodes * (1.0 + 1e-9)
t0 = time.perf_counter()
new_mesh = conversion.rebuild(data, shifted)
t_write = time.perf_counter() - t0

t0 = time.perf_counter()
res = api.optimize(mesh, shape)
t_opt_call = time.perf_counter() - t0

tm = res.timings
print(f"# conversion vs optimization, torus Mesh.Mesh, {n_el} triangles, "
      f"{mesh.CountPoints} points (built from arrays in {t_mesh:.1f} s)")
print("| step | seconds | per element (µs) |")
print("|---|---:|---:|")
rows = (
    ("Mesh.Mesh → arrays (read_mesh)", t_read),
    ("arrays → new Mesh.Mesh (rebuild, every node moved)", t_write),
    ("SurfMesh.optimize: read the mesh", tm["read"]),
    ("SurfMesh.optimize: CAD recovery (checks, nodes on the shape, SurfaceMesh)",
     tm["recovery"]),
    ("SurfMesh.optimize: quality reports (before + after)", tm["before"] + tm["after"]),
    (f"SurfMesh.optimize: optimizer ({res.sweeps} sweeps, {res.reason}, {res.threads} threads; "
     f"core {res.seconds:.2f} s)", tm["optimize"]),
    ("SurfMesh.optimize: new Mesh.Mesh (rebuild)", tm["rebuild"]),
    ("SurfMesh.optimize call, end to end", t_opt_call),
)
for name, t in rows:
    print(f"| {name} | {t:.2f} | {1e6 * t / n_el:.2f} |")
print(f"| conversion (read + rebuild) / optimizer | {(t_read + t_write) / res.seconds:.2f} | |")
