"""SurfMesh command line, run with freecadcmd (after scripts/install.sh):

    freecadcmd <Mod>/SurfMesh/SurfMesh/cli/surfmesh_cli.py -- optimize part.step mesh.msh \\
        -o out.msh --report r.json [--measure shape] [--boundary fixed|slide] [--max-sweeps N]
    freecadcmd .../surfmesh_cli.py -- measure part.step mesh.msh [--measure oddy] [--report r.json]
    freecadcmd .../surfmesh_cli.py -- measures

Shapes: STEP, IGES, BREP, FCStd (--shape-object NAME when it holds several).
Meshes: Gmsh .msh v2/v4 (ids, entities and groups kept), .unv/.inp/.vtk/.vtu/.med/.z88 (FreeCAD
FEM; Nastran .bdf read only, .dat written only), .stl/.obj/.ply/.off (FreeCAD Mesh; float32), FCStd (--mesh-object NAME), other meshio
formats. The output format follows the -o extension (.msh: --msh-version 2 or 4, default: the
input's). The JSON report holds the stats before/after, sweeps, seconds and how the nodes were
put on the shape.

Exit status: 0 success, 2 bad input (message on stderr), 3 cancelled, 1 anything else.
(freecadcmd itself exits 0 on an uncaught exception: every error is caught here.)
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback


def _import_surfmesh():
    try:
        import SurfMesh  # noqa: F401
    except ImportError:
        here = os.path.dirname(os.path.abspath(__file__))
        sys.path.insert(0, os.path.dirname(os.path.dirname(here)))  # .../SurfMesh/..
        import SurfMesh  # noqa: F401
    return sys.modules["SurfMesh"]


def _optimizer_default(option):
    """The optimizer's default of ``option`` as the help gives it (the core's, through
    SurfMesh.app.options); "the optimizer's" when the compiled core is not available."""
    try:
        _import_surfmesh()
        from SurfMesh.app import messages, options

        return messages.number_text(options.optimize_defaults()[option])
    except ImportError:
        return "the optimizer's"


class _HelpFormatter(argparse.HelpFormatter):
    """Puts the optimizer's defaults into the help of the options that give one
    ("{optimizer_default}", for the option named by the action's ``optimizer_option``) when
    the help is shown: building the parser loads neither SurfMesh nor its core (surfmesh batch
    builds it in a process of the standard library only). Not a %-format: Python 3.14's
    argparse checks those when the option is added."""

    def _get_help_string(self, action):
        text = super()._get_help_string(action)
        option = getattr(action, "optimizer_option", None)
        if option is not None and "{optimizer_default}" in text:
            text = text.replace("{optimizer_default}", _optimizer_default(option))
        return text


def build_parser(prog="surfmesh_cli.py"):
    p = argparse.ArgumentParser(
        prog=prog,
        description="Measure, smooth and untangle surface meshes on CAD shapes (SurfMesh).",
    )
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp):
        sp.add_argument("shape", help="CAD shape: .step/.stp/.iges/.igs/.brep/.FCStd")
        sp.add_argument("mesh", help="mesh: .msh/.unv/.inp/.vtk/.stl/.obj/.FCStd/…")
        sp.add_argument("--measure", default="shape", help="quality measure (default: shape)")
        sp.add_argument("--report", metavar="JSON", help="write a JSON report")
        sp.add_argument("--tolerance", type=float, default=None,
                        help="max. node distance to the shape (default: automatic)")
        sp.add_argument("--shape-object", help="object holding the shape in an FCStd file")
        sp.add_argument("--mesh-object", help="object holding the mesh in an FCStd file")
        sp.add_argument("--duplicates", default="glue", choices=["glue", "error"],
                        help="nodes at the same position as another (a crack): move them "
                        "together (glue, default) or stop with an error")
        sp.add_argument("--hints", default="auto", choices=["auto", "tolerance", "none"],
                        help="tolerance: a node within a CAD vertex's or a single CAD edge's "
                        "own tolerance lies on it (FreeCAD's rule for FEM meshes); none: the "
                        "nodes' places follow from the geometry and the elements alone; auto "
                        "(default): tolerance for a FEM mesher's files (Gmsh, FEM formats, "
                        "FCStd FEM meshes), none for triangulations (.stl/.obj/.ply/.off, "
                        "FCStd Mesh objects)")

    m = sub.add_parser("measure", help="quality statistics of a mesh on a shape")
    common(m)
    m.add_argument("--metrics", metavar="LIST", default=None,
                   help="also compute these element quality metrics, comma-separated, or "
                   "'all' (Verdict's names: aspect_ratio, min_angle, max_angle, "
                   "scaled_jacobian, condition, shape, equiangle_skew, warpage, taper, skew, "
                   "stretch; jacobian_ratio, side_node_offset, distance_to_cad)")
    m.add_argument("--csv", metavar="FILE", default=None,
                   help="write the metrics per element as CSV (all of them unless --metrics)")
    m.add_argument("--vtk", metavar="FILE", default=None,
                   help="write the mesh with the metrics as cell data (.vtk or .vtu; all of "
                   "them unless --metrics)")
    o = sub.add_parser("optimize", help="smooth and untangle a mesh on a shape",
                       formatter_class=_HelpFormatter)
    common(o)
    # (the defaults of --measure and --boundary are SurfMesh.app.options's DEFAULT_MEASURE and
    # DEFAULT_BOUNDARY, written here so that building the parser needs no SurfMesh: checked by
    # test_surfmesh_cli; the optimizer's options default to None: the core's defaults)
    o.add_argument("-o", "--output", required=True, help="optimized mesh file")
    o.add_argument("--boundary", default="fixed", choices=["fixed", "slide"])
    o.add_argument("--max-sweeps", type=int, default=None)
    o.add_argument("--rel-tol", type=float, default=None,
                   help="once untangled, stop when a sweep lowers both the objective and the "
                   "quality deficit sum(1 - q) by less than this fraction (default "
                   "{optimizer_default})").optimizer_option = "rel_tol"
    o.add_argument("--over-relaxation", type=float, default=None,
                   help="once untangled, a node first tries this multiple of its Newton step "
                   "(in [1, 2), default {optimizer_default}; 1: plain Gauss-Seidel)"
                   ).optimizer_option = "over_relaxation"
    o.add_argument("--threads", type=int, default=None)
    o.add_argument("--high-order", choices=["reference", "integral"], default=None,
                   help="curved elements: 'reference' measures them against their "
                   "straight-sided counterpart on the surface (corners by the linear measure, "
                   "high-order nodes where interpolating the face puts them), 'integral' by the "
                   "paper's integral measure alone (default {optimizer_default})"
                   ).optimizer_option = "high_order"
    o.add_argument("--topology", choices=["none", "flip"], default=None,
                   help="'flip': edge flips between the smoothing runs (two triangles of one "
                   "face swap their diagonal when that raises the pair's smaller quality or "
                   "makes an invalid pair valid; node ids and element ids kept; quads and "
                   "triangles of order ≥ 3 are not flipped); 'none': node moves alone (default "
                   "{optimizer_default})").optimizer_option = "topology"
    o.add_argument("--no-monotone", action="store_true",
                   help="accept moves that lower a valid mesh's minimum quality")
    o.add_argument("--msh-version", type=float, choices=[2, 2.2, 4, 4.1], default=None)
    o.add_argument("--faces", metavar="LIST", default=None,
                   help="optimize only the elements on these faces of the shape, e.g. "
                   "'Face3,Face7' or '3,7' (FreeCAD's numbering); the nodes of the other "
                   "elements stay")
    o.add_argument("--fixed-nodes", metavar="LIST", default=None,
                   help="ids of nodes to leave where they are (the file's node ids), e.g. "
                   "'12,57,103' or a range '100-200'")
    sub.add_parser("measures", help="list the quality measures")
    return p


def _mesh_summary(mf):
    d = mf.data
    return {"path": mf.path, "format": mf.fmt, "nodes": d.node_count,
            "elements": d.element_count, "types": d.type_names()}


def _bridge_summary(bridge, data):
    keys = ("tolerance", "max_distance", "vertex_nodes", "edge_nodes", "face_nodes",
            "unused_nodes", "pole_nodes", "fixed_nodes", "sliding_nodes", "faces_used",
            "hints_rejected", "flipped_faces", "glued_nodes", "warnings", "diagnostics",
            "summary")
    out = {k: bridge[k] for k in keys if k in bridge}
    # high-order side nodes put on their element's face, by the file's node ids
    out["placed_nodes"] = [int(n) for n in bridge.get("placed_nodes", [])]
    # nodes of no face element (of edge or vertex elements alone), by the file's node ids, with
    # the vertex, edge or face each lies on and the distance to it
    # and the faces' trimming curves that lie off their 3D edges (FreeCAD's names, the gaps)
    for key in ("loose_nodes", "loose_on", "loose_distance", "trim_gaps"):
        if key in bridge:
            out[key] = list(bridge[key])
    return out


def _node_ids(text, option):
    """"12,57,100-200" → [12, 57, 100, …, 200]."""
    ids = []
    for t in (t.strip() for t in text.split(",")):
        if not t:
            continue
        a, sep, b = t.partition("-")
        try:
            if sep:
                lo, hi = int(a), int(b)
                if hi < lo:
                    raise ValueError
                ids.extend(range(lo, hi + 1))
            else:
                ids.append(int(t))
        except ValueError:
            raise ValueError(f"{option}: {t!r} is neither a node id nor a range a-b") from None
    if not ids:
        raise ValueError(f"{option}: no node ids given")
    return ids


def _wanted_metrics(args, fileio):
    """The element metrics `measure` is asked for (--metrics, or all of them for --csv and
    --vtk), checked with the files they go to before anything is read; [] for none."""
    from SurfMesh.app import metrics

    text, csv, vtk = (getattr(args, k, None) for k in ("metrics", "csv", "vtk"))
    if text is None and csv is None and vtk is None:
        return []
    wanted = metrics.metric_names(text or "all")
    if csv:
        fileio.check_output(csv, what="CSV file")
    if vtk:
        if os.path.splitext(vtk)[1].lower() not in (".vtk", ".vtu"):
            raise ValueError(f"--vtk {vtk}: give a .vtk or .vtu file")
        fileio.check_output(vtk, what="VTK file")
    return wanted


def _write_metrics(args, sm, mf, shape, hints, rep, wanted):
    """Computes the element metrics, prints their statistics, writes --csv and --vtk; returns
    the statistics for the JSON report."""
    from SurfMesh.app import metrics

    values = sm.metrics(mf.data, shape, wanted, tolerance=args.tolerance, hints=hints,
                        duplicates=args.duplicates)
    print(metrics.format_statistics(values))
    if args.csv:
        metrics.write_csv(args.csv, values, rep.element_ids, metrics.per_element_types(mf.data),
                          rep.element_faces)
        print(f"wrote {args.csv}")
    if args.vtk:
        metrics.write_vtk(args.vtk, mf.data, values)
        print(f"wrote {args.vtk}")
    return {name: metrics.statistics(v) for name, v in values.items()}


def run(argv, prog="surfmesh_cli.py"):
    args = build_parser(prog).parse_args(argv)
    sm = _import_surfmesh()
    from SurfMesh.app import api, fileio, reports

    if args.command == "measures":
        for name in api.measure_names():
            print(name)
        return 0
    if args.measure not in api.measure_names():
        raise ValueError(
            f"unknown measure {args.measure!r}; known: {', '.join(api.measure_names())}")
    wanted = _wanted_metrics(args, fileio)
    shape = fileio.read_shape(args.shape, args.shape_object)
    mf = fileio.read_mesh(args.mesh, args.mesh_object)
    # What will be written is checked before the run, not after it.
    if args.command == "optimize":
        fileio.check_output(args.output, mf)
    if args.report:
        fileio.check_output(args.report, what="report")
    hints = args.hints
    if hints == "auto":
        hints = "none" if mf.fmt == "mesh" else "tolerance"
    out = {"command": args.command, "shape": os.path.abspath(args.shape),
           "mesh": _mesh_summary(mf), "measure": args.measure, "hints": hints}
    if args.command == "measure":
        rep = sm.measure(mf.data, shape, measure=args.measure, tolerance=args.tolerance,
                         hints=hints, duplicates=args.duplicates)
        print(reports.format_table([(args.measure, os.path.basename(args.mesh), rep.stats)]))
        out["stats"] = rep.stats
        out["bridge"] = _bridge_summary(rep.bridge, mf.data)
        for w in rep.bridge.get("warnings", []):
            print(f"warning: {w}", file=sys.stderr)
        if wanted:
            out["metrics"] = _write_metrics(args, sm, mf, shape, hints, rep, wanted)
    else:
        options = {}
        if args.max_sweeps is not None:
            options["max_sweeps"] = args.max_sweeps
        if args.rel_tol is not None:
            options["rel_tol"] = args.rel_tol
        if args.over_relaxation is not None:
            options["over_relaxation"] = args.over_relaxation
        if args.threads is not None:
            options["threads"] = args.threads
        if args.high_order is not None:
            options["high_order"] = args.high_order
        if args.topology is not None:
            options["topology"] = args.topology
        if args.no_monotone:
            options["monotone"] = False
        if args.faces is not None:
            options["faces"] = api.face_list(args.faces)
        if args.fixed_nodes is not None:
            options["fixed_nodes"] = _node_ids(args.fixed_nodes, "--fixed-nodes")
        res = sm.optimize(mf.data, shape, measure=args.measure, boundary=args.boundary,
                          tolerance=args.tolerance, hints=hints, duplicates=args.duplicates,
                          **options)
        fileio.write_mesh(args.output, mf, res.nodes, msh_version=args.msh_version,
                          rewired=(res.rewired_elements, res.rewired_nodes))
        print(reports.format_table([(args.measure, "Initial", res.before.stats),
                                    (args.measure, "Optimized", res.after.stats)]))
        phases = (" (fixed boundary, then sliding: up to twice --max-sweeps)"
                  if args.boundary == "slide" else "")
        held = f"; {res.held_nodes} node(s) held by --faces/--fixed-nodes" if res.held_nodes else ""
        flips = f"; {res.flips} edge flip(s)" if res.flips else ""
        print(f"{res.sweeps} sweeps{phases}, {res.seconds:.3g} s ({res.reason}){held}{flips}; "
              f"wrote {args.output}")
        a = res.after.stats
        if a.get("moved_nodes"):
            print(f"{a['moved_nodes']} node(s) moved; the farthest from its face: "
                  f"{a['max_distance_to_face']:.3g} (node {a['worst_node_to_face']}), from the "
                  f"shape: {a['max_distance_to_shape']:.3g} (node {a['worst_node_to_shape']})")
        for w in list(res.bridge.get("warnings", [])) + list(res.warnings):
            print(f"warning: {w}", file=sys.stderr)
        out.update(res.to_dict())
        out["output"] = os.path.abspath(args.output)
        out["bridge"] = _bridge_summary(res.bridge, mf.data)
    if args.report:
        reports.write_json(args.report, out)
    return 0


def main(argv=None, prog="surfmesh_cli.py"):
    if argv is None:  # freecadcmd surfmesh_cli.py -- args
        _import_surfmesh()
        from SurfMesh.app.compat import script_args

        argv = script_args()
    elif argv and argv[0] == "--":
        argv = argv[1:]
    try:
        return run(argv, prog)
    except SystemExit as exc:  # argparse: usage errors (2) and --help (0)
        return int(exc.code or 0)
    except ValueError as exc:
        print(f"surfmesh: error: {exc}", file=sys.stderr, flush=True)
        return 2
    except Exception as exc:  # noqa: BLE001
        if type(exc).__name__ == "Cancelled":
            print(f"surfmesh: {exc}", file=sys.stderr, flush=True)
            return 3
        traceback.print_exc()
        print(f"surfmesh: error: {exc}", file=sys.stderr, flush=True)
        return 1


if __name__ in ("__main__", "surfmesh_cli"):  # freecadcmd runs scripts as "surfmesh_cli"
    sys.stdout.flush()
    _code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(_code)
