"""Where SurfMesh's resources are, installed (Mod/SurfMesh/resources next to the package
Mod/SurfMesh/SurfMesh) or in a source tree (resources/ two levels above src/SurfMesh)."""

from __future__ import annotations

import os

_PKG = os.path.dirname(os.path.abspath(__file__))


def resources_dir() -> str:
    for cand in (
        os.path.join(os.path.dirname(_PKG), "resources"),  # Mod/SurfMesh/resources
        os.path.join(os.path.dirname(os.path.dirname(_PKG)), "resources"),  # repo/resources
    ):
        if os.path.isdir(os.path.join(cand, "icons")):
            return cand
    return os.path.join(os.path.dirname(_PKG), "resources")


def icon(name: str) -> str:
    """Path of resources/icons/<name>.svg."""
    return os.path.join(resources_dir(), "icons", name + ".svg")


def cli_script() -> str:
    """Path of the command-line entry surfmesh_cli.py (run it with freecadcmd)."""
    return os.path.join(_PKG, "cli", "surfmesh_cli.py")
