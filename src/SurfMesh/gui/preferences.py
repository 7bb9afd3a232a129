"""User preferences of SurfMesh (last used measure, boundary mode, optimizer settings)."""

from __future__ import annotations

import FreeCAD

PATH = "User parameter:BaseApp/Preferences/Mod/SurfMesh"


def params():
    return FreeCAD.ParamGet(PATH)


def measure() -> str:
    return params().GetString("Measure", "shape")


def set_measure(name: str):
    params().SetString("Measure", name)
