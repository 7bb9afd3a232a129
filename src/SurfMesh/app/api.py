"""SurfMesh's headless Python API: measure and optimize a mesh lying on a CAD shape.

    import SurfMesh
    rep = SurfMesh.measure(mesh, shape, measure="shape")
    rep.quality   # numpy float64, one value per element, in [0, 1], 0 for tangled
    rep.tangled   # numpy bool, one per element
    rep.stats     # dict: min, max, mean, std, tangled, elements (+ skipped)
    res = SurfMesh.optimize(mesh, shape, measure="shape", boundary="fixed")  # or "slide"
    res.mesh      # a NEW Mesh.Mesh / Fem.FemMesh; the input is untouched
    res.before, res.after, res.sweeps, res.seconds

``mesh`` is a ``Mesh.Mesh``, a ``Fem.FemMesh`` or a document object holding one; ``shape`` a
``Part.Shape`` or a document object with ``.Shape``.  Element order, element ids and (FEM)
node ids and node order are preserved.  Precision of the results: FEM meshes store doubles, so
their optimized nodes lie on the CAD surfaces to double precision; ``Mesh.Mesh`` stores float32
points, so there the nodes lie on the surfaces to float32 rounding (~1e-7 × model size).

Bad input raises ``ValueError`` with a message naming the problem; a run cancelled through the
``progress`` callback raises :class:`Cancelled` and changes nothing.

The work is done in SurfMesh.app.options (the options' defaults, from the core, and their
checks), SurfMesh.app.preparing (the mesh and the shape read and given to the CAD bridge),
SurfMesh.app.running (measure, metrics, optimize), SurfMesh.app.results (the result objects)
and SurfMesh.app.messages (the words of the warnings, and the core's messages in the user's
ids); this module is their public face.

This module never imports FreeCADGui.
"""

from __future__ import annotations

# The public names (and the two private ones other modules and tests use).
from SurfMesh.app.messages import id_list as _id_list  # noqa: F401
from SurfMesh.app.messages import volume_mesh_refusal  # noqa: F401
from SurfMesh.app.native import core  # noqa: F401
from SurfMesh.app.options import (  # noqa: F401
    BOUNDARY_MODES,
    measure_names,
    optimize_defaults,
)
from SurfMesh.app.preparing import core_shape as _core_shape  # noqa: F401
from SurfMesh.app.preparing import prepare  # noqa: F401
from SurfMesh.app.results import Cancelled, OptimizeResult, QualityReport  # noqa: F401
from SurfMesh.app.running import face_list, measure, metrics, optimize  # noqa: F401


def __getattr__(name):
    # OPTIMIZE_DEFAULTS: the options of optimize() that map to the core's OptimizeOptions, with
    # the core's defaults (SurfMesh.app.options.optimize_defaults), read from the compiled core
    # when first asked for (importing SurfMesh does not load it).
    if name == "OPTIMIZE_DEFAULTS":
        return optimize_defaults()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
