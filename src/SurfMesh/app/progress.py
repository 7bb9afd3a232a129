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


class StopRuleProgress:
    """How far a run is, judged against its stopping rule rather than its sweep limit (a run
    converging at sweep 48 of 100 ends at 100 %, not at 48 %), for a progress bar.

    Untangling counts for the first half when the mesh starts tangled: 1 − tangled /
    tangled at the start. Once untangled, the run stops when a sweep lowers the objective by
    less than ``rel_tol`` (relative): with r0 the first such decrease measured and r the last
    one, the rest is log(r0 / r) / log(r0 / rel_tol) (the decrease shrinks about geometrically
    as the run converges). The fraction never drops, and is at least sweep / max_sweeps (the
    other way the run stops). An estimate: the core's rule also watches the quality deficit
    and how far nodes move."""

    def __init__(self, rel_tol, max_sweeps):
        import math

        self._log = math.log
        self.rel_tol = float(rel_tol)
        self.max_sweeps = max(int(max_sweeps), 1)
        self.tangled0 = None
        self.base = 0.0  # the share untangling took
        self.prev = None  # the objective after the previous untangled sweep
        self.r0 = None
        self.fraction = 0.0

    def update(self, info):
        """The fraction done (0 … 1) after the sweep described by ``info`` (the core's
        progress dict: sweep, max_sweeps, objective, tangled, …)."""
        tangled = int(info.get("tangled", 0))
        sweep = int(info.get("sweep", 0))
        total = max(int(info.get("max_sweeps", self.max_sweeps)), 1)
        objective = info.get("objective")
        if self.tangled0 is None:
            self.tangled0 = tangled
            self.base = 0.5 if tangled > 0 else 0.0
        p = 0.0
        if tangled > 0:
            p = 0.5 * (1.0 - tangled / self.tangled0) if self.tangled0 else 0.0
            self.prev = None
        else:
            p = self.base
            if objective is not None and self.prev is not None and self.prev > 0:
                r = max((self.prev - float(objective)) / self.prev, 1e-300)
                if self.r0 is None:
                    self.r0 = max(r, self.rel_tol * 10.0)
                span = self._log(self.r0 / self.rel_tol)
                done = 1.0 if r <= self.rel_tol else self._log(self.r0 / r) / span
                p = self.base + (1.0 - self.base) * min(max(done, 0.0), 1.0)
            if objective is not None:
                self.prev = float(objective)
        self.fraction = min(1.0, max(self.fraction, p, sweep / total))
        return self.fraction
