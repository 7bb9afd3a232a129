"""Progress of long runs: FreeCAD's progress indicator plus hooks a GUI may register.

A hook is a callable taking the core's progress dict (sweep, max_sweeps, objective, tangled,
min_quality, delta) and returning False to cancel. A stage hook (``stage_hook``) is called
with the text of each stage a run enters (reading the mesh, placing it on the shape,
optimizing, measuring the result).  The optimize task panel registers one
(progress bar, Cancel button) while it runs a command through ``FreeCADGui.doCommand``, so the
replayable command line needs no callback argument.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import contextlib

_hooks = []
_stage_hooks = []


@contextlib.contextmanager
def _registered(hooks, fn):
    hooks.append(fn)
    try:
        yield fn
    finally:
        hooks.remove(fn)


def hook(fn):
    """Registers ``fn`` for the duration of a ``with`` block."""
    return _registered(_hooks, fn)


def stage_hook(fn):
    """Registers ``fn(text)``, called when a run enters a stage, for a ``with`` block."""
    return _registered(_stage_hooks, fn)


def phase(text):
    """Tells the registered stage hooks that a run enters stage ``text``."""
    for fn in list(_stage_hooks):
        fn(text)


def make_callback(user=None, title="SurfMesh: optimizing", total=100):
    """A progress callback for the core that drives FreeCAD's progress indicator, calls the
    registered hooks and ``user``; any of them returning False cancels.  Returns
    ``(callback, finish)``: call ``finish()`` when the run is over."""
    indicator = None
    try:
        import FreeCAD

        indicator = FreeCAD.Base.ProgressIndicator()
        indicator.start(title, int(total))
    except Exception:
        indicator = None
    state = {"steps": 0}

    def callback(info):
        go_on = True
        if indicator is not None and state["steps"] < total:
            state["steps"] += 1
            try:
                indicator.next()
            except Exception:  # the user aborted through FreeCAD's own progress dialog
                go_on = False
        for fn in list(_hooks):
            if fn(info) is False:
                go_on = False
        if user is not None and user(info) is False:
            go_on = False
        return go_on

    def finish():
        if indicator is not None:
            try:
                indicator.stop()
            except Exception:
                pass

    return callback, finish
