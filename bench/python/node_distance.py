"""The largest distance of mesh nodes to their CAD shape, measured by OpenCASCADE through
FreeCAD's Part module (``Shape.distToShape`` of a vertex per node): the distance half of the
judge of bench/peers.py, independent of SurfMesh's own CAD recovery and of Gmsh.

    SURFMESH_DIST_JOB=job.json freecadcmd bench/python/node_distance.py

job.json: a list of {"key", "shape" (.brep/.step/.iges), "nodes" (.npy, N×3 float64)}. Every
node of each file is measured (bench/peers.py samples the nodes it writes there). The answer
is written to job.json + ".out.json": {key: {"max": largest distance, "nodes": nodes measured,
"seconds": time taken}} or {key: {"error": text}}. All meshes are measured in one process and
each shape is read once.
"""

import json
import os
import time

import numpy as np

import FreeCAD
import Part


def main():
    job_path = os.environ["SURFMESH_DIST_JOB"]
    with open(job_path) as f:
        job = json.load(f)
    shapes = {}
    out = {}
    for item in job:
        t0 = time.perf_counter()
        try:
            if item["shape"] not in shapes:
                shape = Part.Shape()
                shape.read(item["shape"])
                shapes[item["shape"]] = shape
            shape = shapes[item["shape"]]
            xyz = np.load(item["nodes"])
            worst = 0.0
            for p in xyz:
                d = shape.distToShape(Part.Vertex(FreeCAD.Vector(*map(float, p))))[0]
                worst = max(worst, d)
            out[item["key"]] = {"max": worst, "nodes": int(len(xyz)),
                                "seconds": time.perf_counter() - t0}
        except Exception as err:  # noqa: BLE001 - reported to the driver, which decides
            out[item["key"]] = {"error": f"{type(err).__name__}: {err}"}
    with open(job_path + ".out.json", "w") as f:
        json.dump(out, f, indent=1)


main()
