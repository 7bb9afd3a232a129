"""User preferences of SurfMesh: the last measure used, and the Optimize panel's last settings
(boundary mode, tolerances, sweeps, monotone mode, over-relaxation, threads), stored in
FreeCAD's parameters (Tools > Edit parameters: Preferences/Mod/SurfMesh)."""

from __future__ import annotations

import math

import FreeCAD

from SurfMesh.app import api

PATH = "User parameter:BaseApp/Preferences/Mod/SurfMesh"

# The Optimize panel's settings: name → parameter type ("shape tolerance" is per shape: not kept).
_OPTIMIZE_SETTINGS = {
    "boundary": "String",
    "rel_tol": "Float",
    "max_sweeps": "Int",
    "monotone": "Bool",
    "over_relaxation": "Float",
    "threads": "Int",
}


def params():
    return FreeCAD.ParamGet(PATH)


def measure() -> str:
    return params().GetString("Measure", "shape")


def set_measure(name: str):
    params().SetString("Measure", name)


def _default(name):
    return "fixed" if name == "boundary" else api.OPTIMIZE_DEFAULTS[name]


def _param_name(name):
    return "Optimize" + "".join(w.capitalize() for w in name.split("_"))


def optimize_settings() -> dict:
    """The Optimize panel's settings last applied (the optimizer's defaults before that, or
    where a stored value is not usable)."""
    p = params()
    out = {}
    for name, kind in _OPTIMIZE_SETTINGS.items():
        d = _default(name)
        value = getattr(p, "Get" + kind)(_param_name(name), d)
        if name == "boundary" and value not in api.BOUNDARY_MODES:
            value = d
        if kind == "Float" and not math.isfinite(value):
            value = d
        out[name] = value
    return out


def set_optimize_settings(settings: dict):
    """Stores the panel's settings (those of `settings` that it has)."""
    p = params()
    for name, kind in _OPTIMIZE_SETTINGS.items():
        if name in settings:
            value = settings[name]
            value = {"String": str, "Float": float, "Int": int, "Bool": bool}[kind](value)
            getattr(p, "Set" + kind)(_param_name(name), value)
