"""One row of a ``surfmesh batch``: run the ``surfmesh`` command in a process of its own, with a
timeout, and turn what it left (exit status, JSON report, messages) into one result record.

Standard library only, and no import of SurfMesh or FreeCAD: the same function runs in the
batch driver's local pool and, pickled by value, on the workers of a Dask cluster.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

# What a record carries of the command's JSON report (``before``/``after`` are the statistics).
REPORT_KEYS = ("sweeps", "reason", "moved_nodes", "threads", "tangled_unmovable",
               "tangled_movable")


def _command(argv):
    """argv with its program resolved on this host: the driver's path when it exists here (a
    shared install), else ``surfmesh`` on PATH (a cluster node with its own install)."""
    prog = argv[0]
    if not os.path.exists(prog):
        found = shutil.which("surfmesh")
        if found is None:
            raise FileNotFoundError(
                f"{prog} does not exist on {socket.gethostname()} and no 'surfmesh' command is "
                "on its PATH: install SurfMesh there (scripts/install.sh)")
        prog = found
    return [prog] + list(argv[1:])


def kill_group(proc):
    """Kills a row's process and every process it started (its own process group)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _error_line(stderr, code):
    """The command's own error message (its last 'surfmesh: …' line), else the last line."""
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    for ln in reversed(lines):
        if ln.startswith("surfmesh: "):
            return ln[len("surfmesh: "):].removeprefix("error: ")
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"the process was killed by {name}" + (f" ({lines[-1]})" if lines else "")
    if lines:
        return lines[-1]
    return f"exit status {code} and no message"


def run_row(task, running=None):
    """Run one row. ``task`` is a dict: ``id``, ``argv`` (the command, program first),
    ``report`` (the JSON report the command writes), ``log`` (where its output goes, or None),
    ``timeout`` (seconds, or None), plus fields copied into the record (``shape``, ``mesh``,
    ``command``, ``output``). ``running``, when given, is a set-like registry (``add`` and
``discard``) of the row processes running, so that a stopping driver can kill them. Never raises
for a failing row: the record says what happened."""
    rec = {k: task.get(k) for k in ("id", "row", "shape", "mesh", "command", "output")}
    rec.update(status="error", error=None, exit_code=None, before=None, after=None,
               host=socket.gethostname())
    if "distributed" in sys.modules:  # on a Dask worker: which one
        try:
            rec["worker"] = sys.modules["distributed"].get_worker().address
        except (ValueError, AttributeError):
            pass
    t0 = time.monotonic()
    timeout = task.get("timeout")
    report = task["report"]
    try:
        if os.path.exists(report):
            os.remove(report)  # a report left by an earlier run must not pass for this one's
        argv = _command(task["argv"])
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, errors="replace",
                                start_new_session=True)  # its own group: a timeout kills all
    except OSError as exc:
        rec["error"] = f"could not start the command: {exc}"
        rec["seconds"] = time.monotonic() - t0
        return rec
    timed_out = False
    if running is not None:
        running.add(proc)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        kill_group(proc)
        out, err = proc.communicate()
    except BaseException:  # the driver is stopping (Ctrl-C): leave no process behind
        kill_group(proc)
        proc.wait()
        raise
    finally:
        if running is not None:
            running.discard(proc)
    rec["seconds"] = time.monotonic() - t0
    rec["exit_code"] = proc.returncode
    if task.get("log"):
        try:
            os.makedirs(os.path.dirname(task["log"]), exist_ok=True)
            with open(task["log"], "w") as fh:
                fh.write(f"$ {' '.join(argv)}\n{out}")
                if err:
                    fh.write(f"--- stderr\n{err}")
        except OSError:
            pass
    if timed_out:
        rec["status"] = "timeout"
        rec["error"] = f"timed out after {timeout:g} s (the process was killed)"
        return rec
    if proc.returncode != 0:
        rec["error"] = _error_line(err, proc.returncode)
        return rec
    try:
        with open(report) as fh:
            data = json.load(fh)
    except (OSError, ValueError) as exc:
        rec["error"] = f"the command exited 0 but its report {report} is unreadable: {exc}"
        return rec
    rec["status"] = "ok"
    if task.get("command") == "measure":
        rec["before"] = data.get("stats")
    else:
        rec["before"] = data.get("before")
        rec["after"] = data.get("after")
        rec["optimize_seconds"] = data.get("seconds")
        for k in REPORT_KEYS:
            if k in data:
                rec[k] = data[k]
    warnings = list((data.get("bridge") or {}).get("warnings", [])) + list(
        data.get("warnings", []))
    if warnings:
        rec["warnings"] = warnings
    return rec
