"""The options of SurfMesh's runs: their defaults and their checks.

The optimizer's defaults have one source, the core's ``OptimizeOptions``: the binding gives them
(``SurfaceMesh.optimize_defaults()``) and :func:`optimize_defaults` is them by the keyword names
of :func:`SurfMesh.optimize` (``SurfMesh.OPTIMIZE_DEFAULTS``). Every other default of the Python
side (the GUI's preferences and task panel, the command line, the document functions) reads
them here. What each option means: docs/python-api.md (the table of ``**options``).

The compiled core is loaded on the first use of the defaults, not on import.

This module never imports FreeCADGui.
"""

from __future__ import annotations

import numpy as np

from SurfMesh.app.native import core

BOUNDARY_MODES = ("fixed", "slide")
#: How curved elements are optimized (OptimizeOptions::highOrder): against their
#: straight-sided counterpart on the surface, or by the paper's integral measure alone.
HIGH_ORDER_MODES = ("reference", "integral")
#: Whether a run may change the connectivity (OptimizeOptions::topology): node motion only, or
#: edge flips between the smoothing runs.
TOPOLOGY_MODES = ("none", "flip")
#: The boundary mode of a run when none is given.
DEFAULT_BOUNDARY = BOUNDARY_MODES[0]
#: The quality measure when none is given (the core's OptimizeOptions::measure, checked by
#: test_surfmesh_api: a signature's default cannot wait for the core to load).
DEFAULT_MEASURE = "shape"

_defaults = None


def optimize_defaults() -> dict:
    """The options of :func:`SurfMesh.optimize` that map to the core's OptimizeOptions, with
    the core's defaults (max_sweeps, rel_tol, move_tol, inner_iterations, max_line_search,
    over_relaxation, delta_policy, delta_epsilon, delta, monotone, threads, high_order,
    topology).

    The same dict object on every call (``SurfMesh.OPTIMIZE_DEFAULTS``): copy it to change it.
    """
    global _defaults
    if _defaults is None:
        bound = dict(core().SurfaceMesh.optimize_defaults())
        bound.pop("measure")  # an argument of its own, not one of the **options
        _defaults = bound
    return _defaults


def measure_names():
    """Names of the distortion measures the core provides ("shape", "oddy", …)."""
    return list(core().measure_names())


def check_measure(name):
    names = measure_names()
    if not isinstance(name, str) or name not in names:
        raise ValueError(f"unknown measure {name!r}; known measures: {', '.join(names)}")
    return name


def check_boundary(boundary):
    if boundary not in BOUNDARY_MODES:
        raise ValueError(f"unknown boundary mode {boundary!r}; use 'fixed' or 'slide'")
    return boundary


def resolve_options(options):
    """The optimizer's options of a run: the defaults updated with ``options``, checked."""
    defaults = optimize_defaults()
    unknown = sorted(set(options) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown option(s) {', '.join(unknown)}; known: {', '.join(defaults)}"
        )
    opts = dict(defaults)
    opts.update(options)
    check_options(opts)
    return opts


def check_options(o):
    """Checks the optimizer's options ``o`` (every key of :func:`optimize_defaults`); makes
    ``o["monotone"]`` a bool."""
    def positive_int(k):
        v = o[k]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{k} must be a positive integer, got {v!r}")

    def positive_float(k):
        v = o[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0) or v == np.inf:
            raise ValueError(f"{k} must be a positive number, got {v!r}")

    for k in ("max_sweeps", "inner_iterations", "max_line_search"):
        positive_int(k)
    for k in ("rel_tol", "move_tol", "delta_epsilon", "delta"):
        positive_float(k)
    w = o["over_relaxation"]
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not (1 <= w < 2):
        raise ValueError(f"over_relaxation must be a number in [1, 2), got {w!r}")
    if o["delta_policy"] not in ("auto", "fixed"):
        raise ValueError(f"delta_policy must be 'auto' or 'fixed', got {o['delta_policy']!r}")
    if o["high_order"] not in HIGH_ORDER_MODES:
        raise ValueError(
            f"high_order must be 'reference' or 'integral', got {o['high_order']!r}"
        )
    if o["topology"] not in TOPOLOGY_MODES:
        raise ValueError(f"topology must be 'none' or 'flip', got {o['topology']!r}")
    t = o["threads"]
    if isinstance(t, bool) or not isinstance(t, (int, np.integer)) or t < 0:
        raise ValueError(f"threads must be an integer ≥ 0, got {t!r}")
    if not isinstance(o["monotone"], (bool, np.bool_)):
        raise ValueError(f"monotone must be True or False, got {o['monotone']!r}")
    o["monotone"] = bool(o["monotone"])


def check_prepare_arguments(boundary, tolerance, collapsed, duplicates):
    """Checks the arguments of reading a mesh on its shape (see :func:`SurfMesh.app.api.prepare`)
    that need neither."""
    check_boundary(boundary)
    if tolerance is not None and (isinstance(tolerance, bool)
                                  or not isinstance(tolerance, (int, float, np.floating,
                                                                np.integer))
                                  or not (tolerance > 0 and np.isfinite(tolerance))):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    if collapsed not in ("skip", "error"):
        raise ValueError(f"collapsed must be 'skip' or 'error', got {collapsed!r}")
    if duplicates not in ("glue", "error"):
        raise ValueError(f"duplicates must be 'glue' or 'error', got {duplicates!r}")


HINT_MODES = ("auto", "tolerance", "all", "none", "given")


def check_hints(hints):
    if hints not in HINT_MODES:
        raise ValueError(
            f"unknown hints mode {hints!r}; use 'auto', 'tolerance', 'all', 'none' or 'given'"
        )
