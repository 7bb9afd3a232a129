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


class PreferencePage:
    """Edit > Preferences > SurfMesh: the measure of *Measure quality* and *Select tangled
    elements* (also set by the Optimize panel's last run), and the Optimize panel's settings
    back to the optimizer's defaults."""

    def __init__(self, parent=None):
        from PySide import QtGui

        self.form = QtGui.QWidget(parent)
        self.form.setObjectName("SurfMeshPreferences")
        self.form.setWindowTitle("SurfMesh")
        lay = QtGui.QFormLayout(self.form)
        self.measure = QtGui.QComboBox()
        self.measure.setObjectName("measure")
        self.measure.addItems(api.measure_names())
        self.measure.setToolTip("Distortion measure of Measure quality and Select tangled "
                                "elements (the Optimize panel sets it to the one it ran with)")
        lay.addRow("Quality measure", self.measure)
        self.reset = QtGui.QCheckBox("Reset the Optimize panel to the optimizer's defaults")
        self.reset.setObjectName("reset")
        self.reset.setToolTip("The panel opens with the settings of its last run; check this "
                              "and press OK or Apply to start again from the defaults")
        lay.addRow(self.reset)

    def loadSettings(self):
        names = api.measure_names()
        cur = measure()
        self.measure.setCurrentIndex(names.index(cur) if cur in names else 0)
        self.reset.setChecked(False)

    def saveSettings(self):
        set_measure(self.measure.currentText())
        if self.reset.isChecked():
            set_optimize_settings({name: _default(name) for name in _OPTIMIZE_SETTINGS})
            self.reset.setChecked(False)
