"""Writes the shapes of built_shapes.py as <name>.brep into $SURFMESH_BUILT_DIR (default
build/built_shapes) and prints their paths, for the Gmsh comparison on them:

    SURFMESH_BUILT_DIR=/tmp/built freecadcmd bench/python/write_built_shapes.py
    /usr/bin/python3 bench/parts_compare.py --bench-dir build/bench \\
        --parts $(ls /tmp/built/*.brep | paste -sd,)
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import built_shapes  # noqa: E402

target = built_shapes.write(os.environ.get("SURFMESH_BUILT_DIR")
                            or os.path.join("build", "built_shapes"))
print("\n".join(sorted(os.path.join(target, f) for f in os.listdir(target))))
