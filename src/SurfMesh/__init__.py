"""SurfMesh: measure, smooth and untangle surface meshes lying on CAD (OpenCASCADE) surfaces.

Headless API (freecadcmd or the GUI)::

    import SurfMesh
    rep = SurfMesh.measure(mesh, shape, measure="shape")     # .quality .tangled .stats
    res = SurfMesh.optimize(mesh, shape, measure="shape", boundary="fixed")
    res.mesh, res.before, res.after, res.sweeps, res.seconds
    m = SurfMesh.metrics(mesh, shape)      # {"aspect_ratio": array per element, …}

Document functions (colors, stored stats, undo)::

    SurfMesh.measure_object(obj)          SurfMesh.optimize_object(obj)
    SurfMesh.clear_colors(obj)

See SurfMesh.app.api for the options. Importing this package never imports FreeCADGui.
"""

from SurfMesh.app.api import (  # noqa: F401
    BOUNDARY_MODES,
    Cancelled,
    OptimizeResult,
    QualityReport,
    measure,
    measure_names,
    metrics,
    optimize,
)
from SurfMesh.app.metric_report import color_by_metric  # noqa: F401
from SurfMesh.app.metrics import METRIC_NAMES, METRICS  # noqa: F401
from SurfMesh.app.document import (  # noqa: F401
    apply_colors,
    clear_colors,
    measure_object,
    optimize_object,
    stats_of,
)

__version__ = "0.1.0"


def __getattr__(name):
    # OPTIMIZE_DEFAULTS (SurfMesh.app.api's): read from the compiled core when first asked for,
    # so that importing SurfMesh does not load it.
    if name == "OPTIMIZE_DEFAULTS":
        from SurfMesh.app import options

        return options.optimize_defaults()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
