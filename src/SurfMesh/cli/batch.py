"""``surfmesh batch MANIFEST --out DIR``: many parts, each row in a FreeCAD process of its own.

The manifest is a CSV file with a header: ``shape`` and ``mesh`` (paths, relative to the
manifest's folder), optionally ``id`` (default: the row's number, 1 for the first data row),
``command`` (``optimize``, the default, or ``measure``), ``output`` (the optimized mesh, relative
to DIR; default ``DIR/meshes/<id><the mesh's extension>``), ``timeout`` (seconds, this row's
instead of ``--timeout``) and any option of the command, named
as on the command line without the dashes (``boundary``, ``measure``, ``max_sweeps`` or
``max-sweeps``, ``faces``, ``no_monotone`` = true …). Empty cells take the command's defaults;
blank lines and lines starting with ``#`` are skipped.

Each row runs ``surfmesh <command> …`` in a process of its own, so a crash, a hang (``--timeout``)
or a bad file costs that row only. ``DIR/results.jsonl`` gets one JSON record per row as it
ends (``id``, ``shape``, ``mesh``, ``status`` ok / error / timeout, ``error``, ``before`` and
``after`` statistics, ``seconds``, ``output``, …); ``DIR/reports/<id>.json`` holds the command's
full report and ``DIR/logs/<id>.log`` its output. ``--resume`` skips the rows already recorded.

Rows run on a local pool of ``--jobs`` processes (default: the cores), or on an existing Dask
distributed cluster (``--dask tcp://host:port``), whose workers run the same per-row process.

Exit status: 0 when every row of the manifest is recorded ok, 1 when some is not, 2 for a bad
manifest or command line, 3 when stopped (Ctrl-C).

This module needs neither FreeCAD nor SurfMesh's compiled module: only the rows' processes do.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import os
import re
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)
import surfmesh_rowrun as rowrun  # noqa: E402  (the per-row function; standard library only)

STATUSES = ("ok", "error", "timeout")
COMMANDS = ("optimize", "measure")
# Columns of the manifest that are not options of the command.
BASE_COLUMNS = ("id", "shape", "mesh", "command", "output", "timeout")
# Options the batch sets itself for every row.
_BATCH_SET = {"report", "output", "help"}
_TRUE = {"1", "true", "yes", "on", "y", "t"}
_FALSE = {"0", "false", "no", "off", "n", "f", ""}


class ManifestError(ValueError):
    """The manifest cannot be read as a whole (no row runs)."""


def _cli_module():
    """The command line's own module (its parser is the one source of the options), loaded
    from its file under another name: importing it as ``surfmesh_cli`` would run it."""
    mod = sys.modules.get("_surfmesh_cli_for_batch")
    if mod is None:
        spec = importlib.util.spec_from_file_location(
            "_surfmesh_cli_for_batch", os.path.join(_HERE, "surfmesh_cli.py"))
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules["_surfmesh_cli_for_batch"] = mod
    return mod


class _RowError(ValueError):
    pass


def _raise_error(self, message):  # argparse.ArgumentParser.error, raising instead of exiting
    raise _RowError(message)


def command_parsers():
    """{command: its argparse sub-parser} of the ``surfmesh`` command line, made to raise."""
    parser = _cli_module().build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = {}
    for name in COMMANDS:
        sp = subs.choices[name]
        sp.error = _raise_error.__get__(sp)
        out[name] = sp
    return out


def option_columns(parsers):
    """{column: (command, option string, takes a value)} for every option of the commands."""
    cols = {}
    for name, sp in parsers.items():
        for act in sp._actions:
            if not act.option_strings or act.dest in _BATCH_SET:
                continue
            flag = max(act.option_strings, key=len)
            takes = act.nargs != 0
            cols.setdefault(act.dest, {})[name] = (flag, takes)
    return cols


def _column_name(header):
    return header.strip().lower().replace("-", "_").replace(" ", "_")


def _safe(text):
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._") or "row"


def read_manifest(path, columns):
    """[(line number, {column: value})] of the manifest's data rows; ``columns`` are the
    commands' options (option_columns). Raises ManifestError when the file cannot be read, has
    no ``shape``/``mesh`` column, an unknown column or ids twice."""
    if not os.path.isfile(path):
        raise ManifestError(f"manifest {path} does not exist")
    known = set(BASE_COLUMNS) | set(columns)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            lines = [(n, ln) for n, ln in enumerate(fh, 1)
                     if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise ManifestError(f"cannot read the manifest {path}: {exc}") from None
    if not lines:
        raise ManifestError(f"manifest {path} is empty: it needs a header line "
                            "'shape,mesh' and one line per part")
    reader = csv.reader([ln for _, ln in lines])
    try:
        rows = list(reader)
    except csv.Error as exc:
        raise ManifestError(f"manifest {path}: {exc}") from None
    header = [_column_name(h) for h in rows[0]]
    for need in ("shape", "mesh"):
        if need not in header:
            raise ManifestError(f"manifest {path}, line {lines[0][0]}: no '{need}' column "
                                f"(the header is {','.join(rows[0])!r}; it needs shape,mesh)")
    unknown = [h for h in header if h not in known]
    if unknown:
        raise ManifestError(
            f"manifest {path}, line {lines[0][0]}: unknown column(s) {', '.join(unknown)}; "
            f"known: {', '.join(sorted(known))}")
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise ManifestError(f"manifest {path}: column(s) {', '.join(sorted(dup))} given twice")
    out, seen = [], {}
    for k, cells in enumerate(rows[1:], 1):
        line = lines[k][0]
        if len(cells) > len(header):
            raise ManifestError(f"manifest {path}, line {line}: {len(cells)} cells for "
                                f"{len(header)} columns")
        row = {h: (cells[i].strip() if i < len(cells) else "") for i, h in enumerate(header)}
        row["id"] = row.get("id") or str(len(out) + 1)
        if row["id"] in seen:
            raise ManifestError(f"manifest {path}, line {line}: id {row['id']!r} is also the "
                                f"id of line {seen[row['id']]}")
        seen[row["id"]] = line
        out.append((line, row))
    if not out:
        raise ManifestError(f"manifest {path} has a header but no rows")
    return out


def _abs(path, base):
    """``path`` (relative to ``base``) made absolute; None and "" stay."""
    if not path:
        return path
    path = os.path.expanduser(path)
    return os.path.normpath(path if os.path.isabs(path) else os.path.join(base, path))


def make_task(line, row, *, manifest_dir, out_dir, program, timeout, threads, parsers, cols):
    """The task of one manifest row for :func:`surfmesh_rowrun.run_row`. Raises _RowError for a row
    whose options the command refuses (the record of that row says why)."""
    rid = row["id"]
    safe = _safe(rid)
    command = (row.get("command") or "optimize").lower()
    if command not in COMMANDS:
        raise _RowError(f"command {row.get('command')!r} is not one of {', '.join(COMMANDS)}")

    if not row.get("shape") or not row.get("mesh"):
        raise _RowError("the shape and the mesh must both be given")
    shape, mesh = _abs(row["shape"], manifest_dir), _abs(row["mesh"], manifest_dir)
    if row.get("timeout"):
        try:
            timeout = float(row["timeout"])
        except ValueError:
            timeout = -1.0
        if not timeout > 0:
            raise _RowError(f"timeout {row['timeout']!r} is not a positive number of seconds")
    report = os.path.join(out_dir, "reports", f"{safe}.json")
    argv = [program, command, shape, mesh]
    output = None
    if command == "optimize":
        if row.get("output"):
            output = _abs(row["output"], out_dir)
        else:
            ext = os.path.splitext(mesh)[1].lower()
            ext = ".msh" if ext in ("", ".bdf", ".fcstd") else ext
            output = os.path.join(out_dir, "meshes", safe + ext)
        os.makedirs(os.path.dirname(output), exist_ok=True)
        argv += ["-o", output]
    argv += ["--report", report]
    for col, value in row.items():
        if col in BASE_COLUMNS or value == "":
            continue
        spec = cols[col].get(command)
        if spec is None:
            raise _RowError(f"column {col} is not an option of '{command}'")
        flag, takes = spec
        if takes:
            argv += [flag, value]
        elif value.lower() in _TRUE:
            argv.append(flag)
        elif value.lower() not in _FALSE:
            raise _RowError(f"column {col}: {value!r} is neither true nor false")
    if "threads" in cols and cols["threads"].get(command) and not row.get("threads") and threads:
        argv += [cols["threads"][command][0], str(threads)]
    parsers[command].parse_args(argv[2:])  # the command's own checks of names and values
    return {"id": rid, "row": line, "shape": shape, "mesh": mesh, "command": command,
            "output": output, "argv": argv, "report": report,
            "log": os.path.join(out_dir, "logs", f"{safe}.log"), "timeout": timeout}


def read_results(path):
    """{id: last record} of a results.jsonl (a last line cut short by a stop is ignored)."""
    done = {}
    if not os.path.exists(path):
        return done
    with open(path, encoding="utf-8") as fh:
        for ln in fh:
            try:
                rec = json.loads(ln)
            except ValueError:
                continue
            if isinstance(rec, dict) and "id" in rec:
                done[str(rec["id"])] = rec
    return done


def _invalid(stats):
    """"N invalid (T tangled, A standing across)" of a report's statistics (older reports:
    "T tangled")."""
    if "invalid" in stats:
        return (f"{stats['invalid']} invalid ({stats.get('tangled')} tangled, "
                f"{stats.get('across', 0)} standing across)")
    return f"{stats.get('tangled')} tangled"


class _Progress:
    """A bar on a terminal (stderr), a line per row otherwise (stdout)."""

    def __init__(self, total, skipped, stream=None):
        self.total, self.skipped = total, skipped
        self.counts = dict.fromkeys(STATUSES, 0)
        self.t0 = time.monotonic()
        self.tty = (stream or sys.stderr).isatty()
        self.stream = stream or (sys.stderr if self.tty else sys.stdout)
        self.lock = threading.Lock()
        self._stop = threading.Event()
        if self.tty and total:
            threading.Thread(target=self._tick, daemon=True).start()

    def _tick(self):  # redraws the bar each second, so that a long row shows time passing
        while not self._stop.wait(1.0):
            with self.lock:
                self._bar()

    def _bar(self):
        n = sum(self.counts.values())
        width = 30
        fill = int(width * n / max(self.total, 1))
        el = time.monotonic() - self.t0
        left = f", ~{el / n * (self.total - n):.0f} s left" if n else ""
        self.stream.write(
            f"\r[{'#' * fill}{'.' * (width - fill)}] {n}/{self.total}  "
            f"ok {self.counts['ok']}  error {self.counts['error']}  "
            f"timeout {self.counts['timeout']}  {el:.0f} s{left} \033[K")
        self.stream.flush()

    def close(self):
        self._stop.set()
        if self.tty and self.total:
            with self.lock:
                self._bar()
                self.stream.write("\n")
                self.stream.flush()

    def done(self, rec):
        with self.lock:
            self.counts[rec["status"]] = self.counts.get(rec["status"], 0) + 1
            if self.tty:
                self._bar()
            else:
                n = sum(self.counts.values())
                msg = f"[{n}/{self.total}] {rec['id']}: {rec['status']}"
                if rec["status"] == "ok" and rec.get("after"):
                    a, b = rec["after"], rec.get("before") or {}
                    msg += (f", {_invalid(b)} -> {_invalid(a)}, "
                            f"min {b.get('min', float('nan')):.3g} -> {a.get('min', float('nan')):.3g}")
                elif rec["status"] == "ok" and rec.get("before"):
                    b = rec["before"]
                    msg += f", {_invalid(b)}, min {b.get('min', float('nan')):.3g}"
                elif rec.get("error"):
                    msg += f": {rec['error']}"
                self.stream.write(f"{msg} ({rec.get('seconds', 0):.1f} s)\n")
                self.stream.flush()


def _local_pool(tasks, jobs, sink):
    """Runs the tasks on ``jobs`` at once, each in its own process; sink(record) as each ends."""
    running = set()  # the rows' processes (set.add/discard are atomic under the GIL)
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        pending = {pool.submit(rowrun.run_row, t, running): t for t in tasks}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for f in done:
                    t = pending.pop(f)
                    try:
                        rec = f.result()
                    except Exception as exc:  # noqa: BLE001
                        rec = _failed(t, f"the row's runner failed: {exc}")
                    sink(rec)
        except BaseException:
            for f in pending:
                f.cancel()
            for proc in list(running):  # so that the pool's threads end now
                rowrun.kill_group(proc)
            raise


def _dask_client(address):
    """A client of the Dask distributed scheduler at ``address`` (ManifestError if none), with
    the per-row module (surfmesh_rowrun, standard library only) sent to the cluster."""
    try:
        import cloudpickle
        from distributed import Client
    except ImportError as exc:
        raise ManifestError(f"--dask needs Dask distributed (Debian: python3-distributed): {exc}")
    try:
        # Dask before 2024 pickles the task's function with cloudpickle: by value, the
        # workers need SurfMesh's command only, not its modules.
        cloudpickle.register_pickle_by_value(rowrun)
    except (AttributeError, ValueError):
        pass
    try:
        client = Client(address, timeout="30s")
    except OSError as exc:
        raise ManifestError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    try:
        # Later Dask unpickles tasks on the scheduler too, by reference: the module goes to the
        # scheduler and every worker (also those that join later), importable there.
        client.upload_file(rowrun.__file__)
    except Exception as exc:  # noqa: BLE001
        client.close()
        raise ManifestError(f"cannot send surfmesh_rowrun.py to the Dask cluster at {address}: "
                            f"{exc}") from None
    return client


def _dask(tasks, client, sink):
    """Sends the tasks to the Dask scheduler of ``client``; its workers run each row's process
    (surfmesh_rowrun.run_row). sink(record) as each ends."""
    from distributed import as_completed

    futures = {}
    try:
        for t in tasks:
            f = client.submit(rowrun.run_row, t, pure=False,
                              key=f"surfmesh-row-{_safe(t['id'])}-{os.getpid()}-{time.time_ns()}")
            futures[f.key] = (f, t)
        for f in as_completed([f for f, _ in futures.values()]):
            t = futures[f.key][1]
            try:
                rec = f.result()
            except Exception as exc:  # noqa: BLE001  (a worker lost, KilledWorker, …)
                rec = _failed(t, f"the Dask task failed: {type(exc).__name__}: {exc}")
            sink(rec)
    except BaseException:
        client.cancel([f for f, _ in futures.values()])
        raise


def _failed(task, error, status="error"):
    rec = {k: task.get(k) for k in ("id", "row", "shape", "mesh", "command", "output")}
    rec.update(status=status, error=error, exit_code=None, before=None, after=None,
               seconds=0.0)
    return rec


def build_parser(prog="surfmesh batch"):
    p = argparse.ArgumentParser(
        prog=prog, description="Run surfmesh on every row of a CSV manifest, each row in a "
        "process of its own; one JSON record per row in DIR/results.jsonl.")
    p.add_argument("manifest", help="CSV file: shape,mesh[,id,command,output,<option>…]")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder of results.jsonl, the optimized meshes, reports and logs")
    p.add_argument("--jobs", type=int, default=None,
                   help="rows at once on the local pool (default: the cores)")
    p.add_argument("--timeout", type=float, default=None, metavar="S",
                   help="seconds a row may take before its process is killed (default: none)")
    p.add_argument("--resume", action="store_true",
                   help="skip the rows already recorded in DIR/results.jsonl")
    p.add_argument("--retry-failed", action="store_true",
                   help="with --resume: run again the rows recorded as error or timeout")
    p.add_argument("--dask", metavar="ADDRESS",
                   help="run the rows on this Dask distributed scheduler (tcp://host:port) "
                   "instead of the local pool")
    return p


def run(argv, program):
    args = build_parser().parse_args(argv)
    if args.jobs is not None and args.jobs < 1:
        raise ManifestError(f"--jobs must be at least 1, got {args.jobs}")
    if args.timeout is not None and not args.timeout > 0:
        raise ManifestError(f"--timeout must be a positive number of seconds, got {args.timeout}")
    if args.dask and args.jobs is not None:
        raise ManifestError("--jobs sets the local pool: with --dask, the cluster's workers "
                            "decide how many rows run at once")
    manifest = os.path.abspath(args.manifest)
    parsers = command_parsers()
    cols = option_columns(parsers)
    rows = read_manifest(manifest, cols)
    out_dir = os.path.abspath(args.out)
    os.makedirs(out_dir, exist_ok=True)
    results = os.path.join(out_dir, "results.jsonl")
    if args.retry_failed and not args.resume:
        raise ManifestError("--retry-failed goes with --resume")
    previous = read_results(results) if args.resume else {}
    if args.retry_failed:
        previous = {k: r for k, r in previous.items() if r.get("status") == "ok"}
    if not args.resume and os.path.exists(results) and os.path.getsize(results) > 0:
        raise ManifestError(f"{results} exists: pass --resume to skip the rows it records, or "
                            "choose another --out")
    cores = os.cpu_count() or 1
    jobs = args.jobs or cores
    # The optimizer's result does not depend on its thread count: share the cores out.
    threads = None if args.dask else max(1, cores // jobs)
    for sub in ("reports", "logs"):
        os.makedirs(os.path.join(out_dir, sub), exist_ok=True)
    tasks, bad = [], []
    mdir = os.path.dirname(manifest)
    for line, row in rows:
        if row["id"] in previous:
            continue
        try:
            tasks.append(make_task(line, row, manifest_dir=mdir,
                                   out_dir=out_dir, program=program, timeout=args.timeout,
                                   threads=threads, parsers=parsers, cols=cols))
        except _RowError as exc:
            bad.append(_failed({"id": row["id"], "row": line,
                                "shape": _abs(row.get("shape"), mdir),
                                "mesh": _abs(row.get("mesh"), mdir),
                                "command": row.get("command") or "optimize"},
                               f"manifest line {line}: {exc}"))
    skipped = len(rows) - len(tasks) - len(bad)
    todo = len(tasks) + len(bad)
    where = f"Dask scheduler {args.dask}" if args.dask else f"{jobs} local process(es)"
    print(f"surfmesh batch: {len(rows)} row(s) in {args.manifest}; {todo} to run on {where}"
          + (f", {skipped} already recorded" if skipped else ""), flush=True)
    client = _dask_client(args.dask) if args.dask and tasks else None
    progress = _Progress(todo, skipped)
    records = dict(previous)
    lock = threading.Lock()
    with open(results, "a", encoding="utf-8") as fh:

        def sink(rec):
            with lock:
                fh.write(json.dumps(rec, sort_keys=True) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
                records[str(rec["id"])] = rec
            progress.done(rec)

        try:
            for rec in bad:
                sink(rec)
            if tasks:
                if client is not None:
                    _dask(tasks, client, sink)
                else:
                    _local_pool(tasks, jobs, sink)
        finally:
            progress.close()
            if client is not None:
                client.close()
    ids = [row["id"] for _, row in rows]
    final = [records.get(i) for i in ids]
    counts = {s: sum(1 for r in final if r and r["status"] == s) for s in STATUSES}
    missing = sum(1 for r in final if r is None)
    print(f"surfmesh batch: {len(rows)} row(s): {counts['ok']} ok, {counts['error']} error, "
          f"{counts['timeout']} timeout" + (f", {missing} not run" if missing else "")
          + f"; results in {results}")
    for r in final:
        if r and r["status"] != "ok":
            print(f"  {r['id']}: {r['status']}: {r.get('error')}")
    return 0 if counts["ok"] == len(rows) else 1


def _terminate(signum, frame):  # a batch system's stop: end as on Ctrl-C, rows killed
    raise KeyboardInterrupt


def main(argv, program):
    """Entry of ``surfmesh batch``; ``program`` is the ``surfmesh`` command each row runs."""
    import signal

    signal.signal(signal.SIGTERM, _terminate)
    try:
        return run(argv, program)
    except SystemExit as exc:  # argparse: usage errors (2) and --help (0)
        return int(exc.code or 0)
    except ManifestError as exc:
        print(f"surfmesh: error: {exc}", file=sys.stderr, flush=True)
        return 2
    except KeyboardInterrupt:
        print("surfmesh: batch stopped; rerun with --resume to go on", file=sys.stderr,
              flush=True)
        return 3
    except Exception as exc:  # noqa: BLE001
        import traceback

        traceback.print_exc()
        print(f"surfmesh: error: {exc}", file=sys.stderr, flush=True)
        return 1
