"""FreeCAD mesh ↔ arrays conversion cost versus the optimization (run with freecadcmd).

    freecadcmd bench/python/bench_conversion.py [-- N_TRIANGLES]

Meshes a torus (R=10, r=4) with BRepMesh to about N triangles (default 1M), then times
SurfMesh's conversion of the Mesh.Mesh to arrays (read_mesh), back (rebuild with every node
moved), and SurfMesh.optimize on the same mesh with the nodes perturbed (the optimizer's own
seconds and the whole call). Prints a table.
"""
import math
import sys
import time

import numpy as np

import FreeCAD  # noqa: F401
import Mesh  # noqa: F401
import MeshPart
import Part

from SurfMesh.app import api, conversion

n_target = 1_000_000
args = [a for a in sys.argv[1:] if a != "--" and not a.endswith(".py")]
if args:
    n_target = int(float(args[0]))

shape = Part.makeTorus(10, 4)
# Torus area 4π²Rr; equilateral triangles of side h have area √3/4 h²; BRepMesh's sag
# deflection d ≈ h²/(8 r) on the minor circle.
area = 4 * math.pi**2 * 10 * 4
h = math.sqrt(area / n_target * 4 / math.sqrt(3))
defl = h * h / (8 * 4) * 1.5
t0 = time.perf_counter()
mesh = MeshPart.meshFromShape(Shape=shape, LinearDeflection=defl, AngularDeflection=h / 4,
                              Relative=False)
t_mesh = time.perf_counter() - t0
n_el = mesh.CountFacets

t0 = time.perf_counter()
data = conversion.read_mesh(mesh)
t_read = time.perf_counter() - t0

moved = data.nodes * (1.0 + 1e-9)
t0 = time.perf_counter()
new_mesh = conversion.rebuild(data, moved)
t_write = time.perf_counter() - t0

t0 = time.perf_counter()
res = api.optimize(mesh, shape, max_sweeps=20)
t_opt_call = time.perf_counter() - t0

print(f"# conversion vs optimization, torus Mesh.Mesh, {n_el} triangles, "
      f"{mesh.CountPoints} points (BRepMesh {t_mesh:.1f} s)")
print("| step | seconds | per element (µs) |")
print("|---|---:|---:|")
for name, t in (("Mesh.Mesh → arrays (read_mesh)", t_read),
                ("arrays → new Mesh.Mesh (rebuild, every node moved)", t_write),
                (f"optimizer ({res.sweeps} sweeps, {res.reason}, {res.threads} threads)",
                 res.seconds),
                ("SurfMesh.optimize call (recovery, 2× measure, optimizer, rebuild)", t_opt_call)):
    print(f"| {name} | {t:.2f} | {1e6 * t / n_el:.2f} |")
print(f"| conversion (read + rebuild) / optimizer | {(t_read + t_write) / res.seconds:.2f} | |")
