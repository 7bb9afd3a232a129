"""Loads the compiled core (``SurfMesh._surfmesh``) with a clear message when it is missing."""

from __future__ import annotations

_module = None


def core():
    """The compiled module ``SurfMesh._surfmesh``; ImportError with a hint when not built."""
    global _module
    if _module is None:
        try:
            from SurfMesh import _surfmesh  # noqa: PLC0415
        except ImportError as exc:
            raise ImportError(
                "SurfMesh's compiled core (_surfmesh) is not available: build and install the "
                "workbench with scripts/install.sh "
                f"({exc})"
            ) from exc
        _module = _surfmesh
    return _module
