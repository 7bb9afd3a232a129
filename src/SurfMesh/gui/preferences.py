"""User preferences of SurfMesh: the last measure used, and the Optimize panel's last settings
(boundary mode, curved elements, edge flips, tolerances, sweeps, monotone mode, over-relaxation,
threads), stored in
FreeCAD's parameters (Tools > Edit parameters: Preferences/Mod/SurfMesh)."""

from __future__ import annotations

import math

import FreeCAD

from SurfMesh.app import options

PATH = "User parameter:BaseApp/Preferences/Mod/SurfMesh"

# The Optimize panel's settings: name → parameter type ("shape tolerance" is per shape: not kept).
_OPTIMIZE_SETTINGS = {
    "boundary": "String",
    "rel_tol": "Float",
    "max_sweeps": "Int",
    "monotone": "Bool",
    "over_relaxation": "Float",
    "threads": "Int",
    "high_order": "String",
    "topology": "String",
}


def params():
    return FreeCAD.ParamGet(PATH)


def measure() -> str:
    return params().GetString("Measure", options.DEFAULT_MEASURE)


def set_measure(name: str):
    params().SetString("Measure", name)


def _default(name):
    """The optimizer's default of a setting (SurfMesh.app.options: the core's)."""
    return options.DEFAULT_BOUNDARY if name == "boundary" else options.optimize_defaults()[name]


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
        if name == "boundary" and value not in options.BOUNDARY_MODES:
            value = d
        if name == "high_order" and value not in options.HIGH_ORDER_MODES:
            value = d
        if name == "topology" and value not in options.TOPOLOGY_MODES:
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


def color_by() -> str:
    """What *Measure quality* colors a mesh by: "quality" (the measure) or a metric's name."""
    from SurfMesh.app import metrics

    name = params().GetString("ColorBy", "quality")
    return name if name == "quality" or name in metrics.METRICS else "quality"


def set_color_by(name: str):
    params().SetString("ColorBy", name)


def metric_threshold(name):
    """The threshold last set for metric ``name`` (None: never set)."""
    p = params()
    key = "Threshold_" + name
    if key not in p.GetFloats():
        return None
    value = p.GetFloat(key)
    return value if math.isfinite(value) else None


def set_metric_threshold(name, value):
    params().SetFloat("Threshold_" + name, float(value))


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
        self.measure.addItems(options.measure_names())
        self.measure.setToolTip("Distortion measure of Measure quality and Select tangled "
                                "elements (the Optimize panel sets it to the one it ran with)")
        lay.addRow("Quality measure", self.measure)
        from SurfMesh.app import metrics

        self.color_by = QtGui.QComboBox()
        self.color_by.setObjectName("colorBy")
        self.color_by.addItem("Quality (the measure above)", "quality")
        for name in metrics.METRIC_NAMES:
            self.color_by.addItem(metrics.METRICS[name]["label"], name)
        self.color_by.setToolTip("What Measure quality colors a mesh by: its quality, or an "
                                 "element metric with a threshold (red beyond it)")
        lay.addRow("Color by", self.color_by)
        self.threshold = QtGui.QDoubleSpinBox()
        self.threshold.setObjectName("threshold")
        self.threshold.setDecimals(4)
        self.threshold.setRange(-1e12, 1e12)
        self.threshold.setToolTip("Elements worse than this are red (e.g. aspect ratio above 10)")
        lay.addRow("Threshold", self.threshold)
        self.color_by.currentIndexChanged.connect(self._show_threshold)
        self.reset = QtGui.QCheckBox("Reset the Optimize panel to the optimizer's defaults")
        self.reset.setObjectName("reset")
        self.reset.setToolTip("The panel opens with the settings of its last run; check this "
                              "and press OK or Apply to start again from the defaults")
        lay.addRow(self.reset)

    def _show_threshold(self, *_):
        from SurfMesh.app import metric_report

        name = self.color_by.currentData()
        self.threshold.setEnabled(name != "quality")
        if name != "quality":
            t = metric_threshold(name)
            self.threshold.setValue(metric_report.default_threshold(name) if t is None else t)

    def loadSettings(self):
        names = options.measure_names()
        cur = measure()
        self.measure.setCurrentIndex(names.index(cur) if cur in names else 0)
        self.color_by.setCurrentIndex(max(self.color_by.findData(color_by()), 0))
        self._show_threshold()
        self.reset.setChecked(False)

    def saveSettings(self):
        set_measure(self.measure.currentText())
        set_color_by(self.color_by.currentData())
        if self.color_by.currentData() != "quality":
            set_metric_threshold(self.color_by.currentData(), self.threshold.value())
        if self.reset.isChecked():
            set_optimize_settings({name: _default(name) for name in _OPTIMIZE_SETTINGS})
            self.reset.setChecked(False)
