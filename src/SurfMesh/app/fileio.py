"""Reading shapes and meshes from files and writing optimized meshes, with existing readers:

* shapes: STEP / IGES / BREP through FreeCAD's Part; FCStd through FreeCAD documents;
* meshes: Gmsh .msh (v2 and v4) through Gmsh's own API, run in a process of its own
  (gmsh_worker.py: Gmsh can end the process it runs in on some inputs; node and element tags,
  entities and physical groups are kept on write-back); .unv / .inp / .vtk / .vtu / .med / .z88
  through FreeCAD's FEM readers and writers, Nastran .bdf read only and .dat written only
  (FreeCAD 0.20 has no writer, resp. no reader, for them); .stl / .obj / .ply / .off / .ast /
  .bms through FreeCAD's Mesh; anything else meshio reads, through meshio.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile

import numpy as np

from SurfMesh.app import conversion

SHAPE_EXTS = {".step", ".stp", ".iges", ".igs", ".brep", ".brp", ".rle", ".fcstd"}
GMSH_EXTS = {".msh"}
FEM_EXTS = {".unv", ".inp", ".vtk", ".vtu", ".med", ".z88", ".dat", ".bdf"}
# What FreeCAD 0.20's FEM module cannot do with some of them.
_FEM_NO_READER = {".dat"}
_FEM_NO_WRITER = {".bdf"}
_FEM_WRITABLE = sorted(FEM_EXTS - _FEM_NO_WRITER)
# Formats written through meshio (double precision) rather than FreeCAD's FEM writer.
_DOUBLE_EXTS = {".vtk", ".vtu"}
MESH_EXTS = {".stl", ".obj", ".ply", ".off", ".ast", ".bms"}

# Gmsh element type codes ↔ SurfMesh element names (complete Lagrange triangles, quad4, quad8).
GMSH_TYPES = {2: "tri3", 3: "quad4", 9: "tri6", 21: "tri10", 23: "tri15", 25: "tri21",
              16: "quad8"}
GMSH_CODES = {name: code for code, name in GMSH_TYPES.items()}
_GMSH_OTHER = {10: "quad9", 20: "tri9 (incomplete)", 22: "tri12 (incomplete)"}


def _ext(path):
    return os.path.splitext(path)[1].lower()


def _check_file(path, what):
    if not os.path.exists(path):
        raise ValueError(f"{what} file not found: {path}")
    if not os.path.isfile(path):
        raise ValueError(f"{what} path is not a file: {path}")
    if os.path.getsize(path) == 0:
        raise ValueError(f"{what} file is empty: {path}")


# ---- shapes ----------------------------------------------------------------------------------


def read_shape(path, object_name=None):
    """Part.Shape from a STEP / IGES / BREP file, or from an object of an FCStd document
    (``object_name``; default: the only object with faces that no other such object uses)."""
    import Part

    _check_file(path, "shape")
    ext = _ext(path)
    if ext not in SHAPE_EXTS:
        raise ValueError(
            f"unknown shape format {ext!r} ({path}); use STEP, IGES, BREP or FCStd"
        )
    if ext == ".fcstd":
        return _shape_from_fcstd(path, object_name)
    try:
        if ext in (".brep", ".brp", ".rle"):
            shape = Part.Shape()
            shape.importBrep(path)
        else:
            shape = Part.read(path)
    except Exception as exc:
        raise ValueError(f"cannot read shape from {path}: {exc}") from exc
    if shape.isNull() or not shape.Faces:
        raise ValueError(f"{path} holds no faces")
    return shape


def _open_fcstd(path):
    import FreeCAD

    for doc in FreeCAD.listDocuments().values():
        if os.path.abspath(doc.FileName) == os.path.abspath(path):
            return doc
    try:
        return FreeCAD.openDocument(path, True)  # hidden
    except TypeError:
        return FreeCAD.openDocument(path)
    except Exception as exc:
        raise ValueError(f"cannot open FreeCAD document {path}: {exc}") from exc


def _shape_from_fcstd(path, object_name):
    doc = _open_fcstd(path)
    if object_name:
        obj = doc.getObject(object_name) or next(iter(doc.getObjectsByLabel(object_name)), None)
        if obj is None or not hasattr(obj, "Shape") or obj.Shape.isNull():
            raise ValueError(f"{path} has no shape object named {object_name!r}")
        return obj.Shape
    cands = [
        o
        for o in doc.Objects
        if hasattr(o, "Shape")
        and "FemMesh" not in o.PropertiesList
        and not o.Shape.isNull()
        and o.Shape.Faces
    ]
    roots = [o for o in cands if not any(p in cands for p in o.InList)]
    if len(roots) != 1:
        names = ", ".join(o.Name for o in roots) or "none"
        raise ValueError(
            f"{path}: cannot tell which shape to use ({names}); name one with --shape-object"
        )
    return roots[0].Shape


# ---- meshes ----------------------------------------------------------------------------------


@dataclasses.dataclass
class MeshFile:
    """A mesh read from a file: its arrays, and what is needed to write it back."""

    path: str
    fmt: str  # "gmsh", "fem", "mesh", "meshio"
    data: conversion.MeshData
    msh_version: float = 0.0  # Gmsh input: 2.2 or 4.1
    fem: object = None  # Fem.FemMesh for FEM inputs
    mesh: object = None  # Mesh.Mesh for Mesh inputs
    meshio_mesh: object = None


def read_mesh(path, object_name=None) -> MeshFile:
    """Reads a surface mesh file (see the module doc for the formats)."""
    _check_file(path, "mesh")
    ext = _ext(path)
    if ext in GMSH_EXTS:
        return _read_gmsh(path)
    if ext in _FEM_NO_READER:
        raise ValueError(f"cannot read {path}: FreeCAD 0.20 writes {ext} meshes but cannot read "
                         "them; give the mesh as .msh, .unv, .inp, .med, .vtk or .bdf")
    if ext in FEM_EXTS:
        import Fem

        try:
            fem = Fem.read(path)
        except Exception as exc:
            raise ValueError(f"cannot read FEM mesh {path}: {exc}") from exc
        return MeshFile(path, "fem", conversion.read_mesh(fem), fem=fem)
    if ext in MESH_EXTS:
        import Mesh

        try:
            mesh = Mesh.Mesh(path)
        except Exception as exc:
            raise ValueError(f"cannot read mesh {path}: {exc}") from exc
        if mesh.CountFacets == 0:
            raise ValueError(f"{path} holds no triangles")
        return MeshFile(path, "mesh", conversion.read_mesh(mesh), mesh=mesh)
    if ext == ".fcstd":
        doc = _open_fcstd(path)
        objs = [o for o in doc.Objects if ("FemMesh" in o.PropertiesList or (
            "Mesh" in o.PropertiesList and o.TypeId.startswith("Mesh::")))]
        if object_name:
            objs = [o for o in objs if object_name in (o.Name, o.Label)]
        if len(objs) != 1:
            names = ", ".join(o.Name for o in objs) or "none"
            raise ValueError(f"{path}: cannot tell which mesh to use ({names}); use --mesh-object")
        inner = conversion.mesh_of(objs[0])
        data = conversion.read_mesh(inner)
        if data.kind == "fem":
            return MeshFile(path, "fem", data, fem=inner)
        return MeshFile(path, "mesh", data, mesh=inner)
    return _read_meshio(path)


_gmsh_ready = False


def _gmsh():
    """Gmsh's Python API in *this* process, initialized once (quiet, no user configuration
    files). Not used by this module's readers and writers (they run Gmsh in a process of its own,
    :func:`_run_gmsh`): left for the test suites that build meshes with Gmsh."""
    global _gmsh_ready
    import gmsh

    if not _gmsh_ready:
        try:
            gmsh.initialize(readConfigFiles=False)
        except TypeError:  # older signature
            gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        _gmsh_ready = True
    return gmsh


# ---- Gmsh in a process of its own -------------------------------------------------------------
# Gmsh's C++ code can end the process it runs in on some inputs (an uncaught exception: abort),
# and FreeCAD with it. Every Gmsh call of this module runs in a child process (gmsh_worker.py,
# under a Python that can import gmsh), which exchanges files with this one in a temporary folder.

_WORKER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "gmsh_worker.py")
_GMSH_TIMEOUT = 1800.0  # seconds (SURFMESH_GMSH_TIMEOUT)
_gmsh_python = None  # the interpreter that ran the worker last


class GmshProcessError(ValueError):
    """Gmsh failed on a file in its own process (an error, an abort, a timeout), or no Python
    here can run Gmsh. The process that asked (a FreeCAD session) is unaffected."""


def _python_candidates():
    """Interpreters to run the worker with, best first. FreeCAD's ``sys.executable`` may be
    freecadcmd or FreeCAD itself: only a Python is taken. ``SURFMESH_GMSH_PYTHON`` names one."""
    given = os.environ.get("SURFMESH_GMSH_PYTHON")
    if given:
        return [given]
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    cands = [_gmsh_python] if _gmsh_python else []
    if re.fullmatch(r"python[0-9.]*", os.path.basename(sys.executable or "")):
        cands.append(sys.executable)
    cands += [os.path.join(sys.prefix, "bin", "python3"), os.path.join(sys.prefix, "bin", version),
              "/usr/bin/python3", shutil.which("python3")]
    return [c for c in dict.fromkeys(cands) if c and os.path.isfile(c) and os.access(c, os.X_OK)]


def _gmsh_timeout():
    try:
        value = float(os.environ.get("SURFMESH_GMSH_TIMEOUT", _GMSH_TIMEOUT))
    except ValueError:
        return _GMSH_TIMEOUT
    return value if value > 0 else _GMSH_TIMEOUT


def _log_tail(path, lines=8, chars=1500):
    """The last lines Gmsh (and the worker) printed, joined on one line."""
    try:
        with open(path, "rb") as fh:
            fh.seek(max(0, os.path.getsize(path) - 64 * 1024))
            text = fh.read().decode("utf-8", "replace")
    except OSError:
        return ""
    tail = " | ".join([ln.strip() for ln in text.splitlines() if ln.strip()][-lines:])
    return tail if len(tail) <= chars else "…" + tail[-chars:]


def _how_it_ended(code, timed_out, timeout):
    if timed_out:
        return (f"it did not finish within {timeout:g} s and was stopped "
                "(SURFMESH_GMSH_TIMEOUT sets the limit, in seconds)")
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"its process was killed by {name}" + (" (Gmsh aborted)" if name == "SIGABRT"
                                                      else "")
    if code:
        return f"its process exited with status {code}"
    return "its process gave no answer"


def _run_gmsh(op, what, request, arrays=None, source=None):
    """Runs gmsh_worker.py ``op`` with ``request`` (JSON) and ``arrays`` (npz); returns its
    (result dict, arrays dict). ``what`` names the work for messages ("reading x.msh").
    Raises GmshProcessError when the worker fails, is killed or times out, and ValueError
    "Gmsh cannot read ``source``" when Gmsh refused to open that .msh."""
    global _gmsh_python
    if not os.path.isfile(_WORKER):
        raise GmshProcessError(f"cannot run Gmsh for {what}: {_WORKER} is missing (reinstall "
                               "SurfMesh: scripts/install.sh)")
    timeout = _gmsh_timeout()
    with tempfile.TemporaryDirectory(prefix="surfmesh-gmsh-") as tmp:
        with open(os.path.join(tmp, "request.json"), "w") as fh:
            json.dump(request, fh)
        if arrays is not None:
            np.savez(os.path.join(tmp, "request.npz"), **arrays)
        log = os.path.join(tmp, "gmsh.log")
        started = os.path.join(tmp, "started")
        tried = []
        for python in _python_candidates():
            timed_out = False
            with open(log, "wb") as out:
                try:
                    proc = subprocess.Popen([python, _WORKER, op, tmp], cwd=tmp,
                                            stdin=subprocess.DEVNULL, stdout=out,
                                            stderr=subprocess.STDOUT)
                except OSError as exc:
                    tried.append(f"{python}: {exc}")
                    continue
                try:
                    code = proc.wait(timeout=timeout)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    code = proc.wait()
                    timed_out = True
                except BaseException:  # interrupted: leave no Gmsh behind
                    proc.kill()
                    proc.wait()
                    raise
            if os.path.exists(started):
                _gmsh_python = python
                break
            if timed_out:  # stopped while still importing (a loaded machine): a timeout
                break
            # This Python cannot run Gmsh (no gmsh or numpy module): try the next one.
            tried.append(f"{python}: {_log_tail(log, lines=1, chars=300) or f'exit {code}'}")
        else:
            raise GmshProcessError(
                f"cannot run Gmsh for {what}: no Python here imports Gmsh's Python module "
                f"({'; '.join(tried) or 'no Python interpreter found'}); install python3-gmsh, "
                "or set SURFMESH_GMSH_PYTHON to a Python that imports gmsh and numpy")
        result_path = os.path.join(tmp, "result.json")
        if code != 0 or timed_out or not os.path.exists(result_path):
            said = _log_tail(log)
            raise GmshProcessError(
                f"Gmsh failed {what}: {_how_it_ended(code, timed_out, timeout)}; the FreeCAD "
                "session is unaffected (Gmsh runs in a process of its own). "
                + (f"Gmsh said: {said}" if said else "Gmsh said nothing."))
        with open(result_path) as fh:
            result = json.load(fh)
        if "open_error" in result:
            raise ValueError(f"Gmsh cannot read {source}: {result['open_error']}")
        got = {}
        if os.path.exists(os.path.join(tmp, "result.npz")):
            with np.load(os.path.join(tmp, "result.npz")) as npz:
                got = {k: npz[k] for k in npz.files}
        return result, got


def _msh_version(path):
    with open(path, "rb") as fh:
        head = fh.read(256).decode("latin-1", "replace").split()
    if len(head) >= 2 and head[0] == "$MeshFormat":
        try:
            return float(head[1])
        except ValueError:
            pass
    raise ValueError(f"{path} is not a Gmsh .msh file (no $MeshFormat header)")


_SURFACE_CODES = set(GMSH_TYPES) | set(_GMSH_OTHER)
_GMSH_ORDER = {2: 1, 3: 1, 9: 2, 10: 2, 16: 2, 20: 3, 21: 3, 22: 4, 23: 4, 25: 5}


def _msh_surface_type_counts(path, version):
    """{Gmsh type code: count} of the surface elements an ASCII .msh file declares (None for
    a binary file or one this light scan cannot follow), to check what Gmsh returns against."""
    counts = {}
    try:
        with open(path, "r", encoding="latin-1") as fh:
            fmt = fh.read(256).split()
            if len(fmt) < 3 or fmt[2] != "0":  # binary
                return None
            fh.seek(0)
            for line in fh:
                if line.startswith("$Elements"):
                    break
            else:
                return None
            header = fh.readline().split()
            if version < 4:
                for _ in range(int(header[0])):
                    t = int(fh.readline().split()[1])
                    if t in _SURFACE_CODES:
                        counts[t] = counts.get(t, 0) + 1
            else:
                for _ in range(int(header[0])):
                    dim, _tag, t, n = (int(x) for x in fh.readline().split()[:4])
                    for _ in range(n):
                        fh.readline()
                    if dim == 2:
                        counts[t] = counts.get(t, 0) + n
    except (ValueError, IndexError, OSError):
        return None
    return counts


def _read_gmsh(path) -> MeshFile:
    version = _msh_version(path)
    declared = _msh_surface_type_counts(path, version)
    if declared and len({_GMSH_ORDER.get(t, t) for t in declared}) > 1:
        # Gmsh itself keeps one order per entity and silently drops the others: refuse here.
        parts = ", ".join(
            f"{GMSH_TYPES.get(t, _GMSH_OTHER.get(t, t))} ({n} elements)"
            for t, n in sorted(declared.items())
        )
        raise ValueError(
            f"{path} mixes element orders: {parts}; a mesh must have one order "
            "(tri3 and quad4 may be mixed, so may tri6 and quad8)"
        )
    res, got = _run_gmsh("read", f"reading {path}", {"path": os.path.abspath(path)},
                         source=path)
    node_tags, coords = got["node_tags"], got["coords"]
    if len(node_tags) == 0:
        raise ValueError(f"{path} holds no nodes")
    node_tags = np.asarray(node_tags, dtype=np.int64)
    nodes = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(node_tags)
    node_tags, nodes = node_tags[order], nodes[order]
    types = res["types"]
    tags = [got[f"etags_{i}"] for i in range(len(types))]
    conn_tags = [got[f"conn_{i}"] for i in range(len(types))]
    el_types, el_ids, flat = [], [], []
    for t, etags, ntags in zip(types, tags, conn_tags):
        t = int(t)
        if t not in GMSH_TYPES:
            name = _GMSH_OTHER.get(t, res["names"][types.index(t)])
            raise ValueError(
                f"{path}: unsupported element type {name} ({len(etags)} elements); supported: "
                + ", ".join(GMSH_TYPES.values())
            )
        el_types.append(np.full(len(etags), conversion.ELEMENT_TYPES[GMSH_TYPES[t]]))
        el_ids.append(np.asarray(etags, dtype=np.int64))
        flat.append(np.asarray(ntags, dtype=np.int64))
    if not el_types:
        raise ValueError(f"{path} holds no surface (2D) elements")
    el_types = np.concatenate(el_types).astype(np.int64)
    if declared is not None and sum(declared.values()) != len(el_types):
        raise ValueError(
            f"{path} declares {sum(declared.values())} surface elements but Gmsh read "
            f"{len(el_types)}: the file is inconsistent"
        )
    el_ids = np.concatenate(el_ids)
    flat = np.concatenate(flat)
    sizes = np.array(
        [conversion.NODES_PER_TYPE[conversion.ELEMENT_NAMES[int(t)]] for t in el_types],
        dtype=np.int64,
    )
    # element id order, as FEM meshes are
    eorder = np.argsort(el_ids, kind="stable")
    starts = np.concatenate([[0], np.cumsum(sizes)])
    conn_list = [flat[starts[e] : starts[e + 1]] for e in eorder]
    el_types, el_ids, sizes = el_types[eorder], el_ids[eorder], sizes[eorder]
    flat = np.concatenate(conn_list) if conn_list else flat
    pos, missing = conversion.positions_of(node_tags, flat)
    if np.any(missing):
        raise ValueError(f"{path}: an element references an unknown node")
    offsets = np.zeros(len(el_types) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    data = conversion.MeshData(
        kind="arrays",
        nodes=nodes,
        types=el_types,
        offsets=offsets,
        conn=pos.astype(np.int64),
        node_ids=node_tags,
        element_ids=el_ids,
        volume_elements=int(sum(n for _, n in res["volumes"])),
        volume_types=", ".join(f"{name} ({n})" for name, n in res["volumes"]),
    )
    return MeshFile(path, "gmsh", data, msh_version=version)


_MESHIO_TYPES = {"triangle": "tri3", "triangle6": "tri6", "quad": "quad4", "quad8": "quad8",
                 "triangle10": "tri10", "triangle15": "tri15", "triangle21": "tri21"}


# meshio's volume cell types, without their node count suffix (tetra10, hexahedron27, ...).
_MESHIO_VOLUME_TYPES = {"tetra", "hexahedron", "wedge", "pyramid"}


def _read_meshio(path) -> MeshFile:
    try:
        import meshio
    except ImportError as exc:
        raise ValueError(f"unknown mesh format {_ext(path)!r} ({path})") from exc
    try:
        m = meshio.read(path)
    except Exception as exc:
        raise ValueError(f"cannot read mesh {path}: {exc}") from exc
    types, conns = [], []
    for block in m.cells:
        if block.type in _MESHIO_TYPES:
            name = _MESHIO_TYPES[block.type]
            types.append(np.full(len(block.data), conversion.ELEMENT_TYPES[name], np.int64))
            conns.append(np.asarray(block.data, np.int64).reshape(-1))
    if not types:
        raise ValueError(f"{path} holds no surface elements")
    types = np.concatenate(types)
    sizes = np.array([conversion.NODES_PER_TYPE[conversion.ELEMENT_NAMES[int(t)]] for t in types])
    offsets = np.zeros(len(types) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    nodes = np.asarray(m.points, dtype=np.float64)
    if nodes.shape[1] == 2:
        nodes = np.hstack([nodes, np.zeros((len(nodes), 1))])
    volumes = [(b.type, len(b.data)) for b in m.cells
               if b.type.rstrip("0123456789") in _MESHIO_VOLUME_TYPES]
    data = conversion.MeshData(
        kind="arrays", nodes=nodes, types=types, offsets=offsets, conn=np.concatenate(conns),
        node_ids=np.arange(len(nodes), dtype=np.int64),
        element_ids=np.arange(len(types), dtype=np.int64),
        volume_elements=int(sum(n for _, n in volumes)),
        volume_types=", ".join(f"{t} ({n})" for t, n in volumes),
    )
    return MeshFile(path, "meshio", data, meshio_mesh=m)


# ---- writing ---------------------------------------------------------------------------------


def _check_writer(out, ext, what="output mesh"):
    if ext in _FEM_NO_WRITER:
        raise ValueError(f"cannot write the {what} {out}: FreeCAD 0.20 reads {ext} meshes but "
                         f"cannot write them; write {', '.join(_FEM_WRITABLE)} or .msh")


def check_output(out, src: MeshFile = None, what="output mesh"):
    """Raises ValueError when ``out`` cannot be written: its folder is missing or not
    writable, or (a mesh, with ``src``) its extension names no known format or one that cannot
    hold ``src``'s elements. Called before a run, so that a long optimization is not lost."""
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise ValueError(f"cannot write the {what} {out}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"cannot write the {what} {out}: folder {folder} is not writable")
    if os.path.isdir(out):
        raise ValueError(f"cannot write the {what} {out}: it is a folder")
    if src is None:
        return
    ext = _ext(out)
    _check_writer(out, ext, what)
    if ext in GMSH_EXTS | FEM_EXTS | MESH_EXTS:
        _check_format_holds(src.data, ext)
        return
    try:
        import meshio

        known = set(meshio.extension_to_filetypes)
    except ImportError:
        known = set()
    if not ext or ext not in known:
        formats = sorted(GMSH_EXTS | FEM_EXTS | MESH_EXTS | known)
        raise ValueError(f"unknown output mesh format {ext or '(no extension)'!r} for {out}; "
                         f"known: {', '.join(formats)}")


def _check_format_holds(data, ext):
    """Raises ValueError when the mesh format of extension ``ext`` cannot hold ``data``'s
    elements: FreeCAD FEM meshes hold tri3, tri6, quad4 and quad8, triangle meshes (STL/OBJ…)
    tri3."""
    names = set(data.type_names())
    fem = {"tri3", "tri6", "quad4", "quad8"}
    if ext in FEM_EXTS and names - fem:
        raise ValueError(f"FreeCAD FEM meshes cannot hold "
                         f"{', '.join(sorted(names - fem))} elements: "
                         f"write .msh instead of {ext}")
    if ext in MESH_EXTS and names - {"tri3"}:
        raise ValueError(f"{', '.join(sorted(names))} elements cannot be written as a "
                         f"triangle mesh ({ext}): write .msh or a FEM format")


def write_mesh(out, src: MeshFile, new_nodes, msh_version=None, rewired=None):
    """Writes the mesh of ``src`` with node positions ``new_nodes`` to ``out`` (format by
    extension). Ids and element order are kept where the format stores them. ``rewired``: None,
    or (element ids, node id lists) of the elements edge flips gave new node lists (an
    OptimizeResult's ``rewired_elements`` and ``rewired_nodes``, in the input's ids)."""
    new_nodes = np.asarray(new_nodes, dtype=np.float64)
    ext = _ext(out)
    if rewired is not None and len(rewired[0]):
        src = dataclasses.replace(src, data=_with_rewired_ids(src.data, *rewired))
    data = src.data
    _check_writer(out, ext)
    _check_format_holds(data, ext)
    if ext in GMSH_EXTS:
        version = msh_version or (src.msh_version if src.fmt == "gmsh" else 4.1)
        version = 2.2 if float(version) < 3 else 4.1
        _write_gmsh(out, src, new_nodes, version)
    elif ext in _DOUBLE_EXTS:
        # FreeCAD's VTK writer stores points as float with 6 digits (1e-5 off the surface on a
        # part of size 100): meshio writes them as double, in the same node order.
        import meshio

        meshio.write(out, meshio.Mesh(new_nodes, _meshio_cells(data) + _line_cells(src)))
    elif ext in FEM_EXTS:
        fem = conversion.rebuild(data, new_nodes) if src.fmt == "fem" else _fem_from(data, new_nodes)
        try:
            fem.write(out)
        except Exception as exc:
            raise ValueError(f"cannot write {out}: {exc}") from exc
        if ext == ".z88" and os.path.exists(out):
            _z88_full_precision(out, data.node_ids, new_nodes)
    elif ext in MESH_EXTS:
        if src.fmt == "mesh":
            mesh = conversion.rebuild(data, new_nodes)
        else:
            mesh = _mesh_from(data, new_nodes)
        mesh.write(out)
    else:
        import meshio

        cells = _meshio_cells(data)
        meshio.write(out, meshio.Mesh(new_nodes, cells))
    if not os.path.exists(out):
        raise ValueError(f"nothing was written to {out}")
    return out


def _z88_full_precision(path, node_ids, nodes):
    """FreeCAD's Z88 writer keeps 6 decimals (5e-7 off the surface whatever the part's size):
    its node lines ("id dof x y z", after the header line) get the nodes in double precision."""
    with open(path) as f:
        lines = f.read().split("\n")
    at = {int(i): k for k, i in enumerate(node_ids)}
    count = int(lines[0].split()[1])
    for n in range(1, count + 1):
        fields = lines[n].split()
        x, y, z = nodes[at[int(fields[0])]]
        lines[n] = f"{fields[0]} {fields[1]} {float(x)!r} {float(y)!r} {float(z)!r}"
    with open(path, "w") as f:
        f.write("\n".join(lines))


def _with_rewired_ids(data, element_ids, node_lists):
    """``data`` with the elements of ids ``element_ids`` given the node lists ``node_lists``
    (node ids), see conversion.with_rewired."""
    elements, missing = conversion.positions_of(data.element_ids, np.asarray(element_ids))
    if missing.any():
        raise ValueError(f"rewired element(s) not in the mesh: {np.asarray(element_ids)[missing]}")
    lists = []
    for nodes in node_lists:
        pos, miss = conversion.positions_of(data.node_ids, np.asarray(nodes))
        if miss.any():
            raise ValueError(f"rewired node(s) not in the mesh: {np.asarray(nodes)[miss]}")
        lists.append(pos)
    return conversion.with_rewired(data, elements, lists)


def _rewire_msh_text(path, elements):
    """Gives the elements of ``path`` (an ASCII .msh 2.2 or 4.1) whose tags are keys of
    ``elements`` the node tags of their values (Gmsh 4.8 cannot remove elements from a model:
    the file Gmsh wrote is patched). Every key must be found once."""
    with open(path) as fh:
        lines = fh.read().split("\n")
    version = 4.1
    for i, ln in enumerate(lines):
        if ln.strip() == "$MeshFormat":
            version = float(lines[i + 1].split()[0])
            break
    start = lines.index("$Elements") + 1
    end = lines.index("$EndElements", start)
    found = set()
    i = start + 1  # the section's header line
    while i < end:
        f = lines[i].split()
        if version >= 4:
            count = int(f[3])  # block: entity dim, entity tag, element type, element count
            for j in range(i + 1, i + 1 + count):
                tag = int(lines[j].split()[0])
                if tag in elements:
                    lines[j] = " ".join(str(int(x)) for x in [tag, *elements[tag]]) + " "
                    found.add(tag)
            i += 1 + count
        else:
            tag = int(f[0])
            if tag in elements:
                keep = 3 + int(f[2])  # tag, type, number of tags, the tags
                lines[i] = " ".join(f[:keep] + [str(int(x)) for x in elements[tag]])
                found.add(tag)
            i += 1
    if found != set(elements):
        raise ValueError(f"elements {sorted(set(elements) - found)} not found in {path}")
    with open(path, "w") as fh:
        fh.write("\n".join(lines))


def _write_gmsh(out, src, new_nodes, version):
    """Gmsh writes ``out`` (in its own process): ``src``'s .msh with its nodes moved, or a new
    model of one discrete surface for other inputs. Written in a temporary folder, then moved:
    a Gmsh that fails leaves no partial ``out``."""
    data = src.data
    arrays = {"nodes": np.ascontiguousarray(new_nodes, dtype=np.float64)}
    request = {"version": version, "out": None}
    if src.fmt == "gmsh":
        request["source"] = os.path.abspath(src.path)
        arrays["node_tags"] = np.asarray(data.node_ids, dtype=np.int64)
    else:
        # Gmsh tags start at 1: 0-based ids (STL/OBJ inputs, arrays) are shifted by one.
        tags = data.node_ids + 1 if data.node_ids.min() == 0 else data.node_ids
        arrays["node_tags"] = np.asarray(tags, dtype=np.int64)
        request["codes"] = []
        for i, code in enumerate(np.unique(data.types)):
            name = conversion.ELEMENT_NAMES[int(code)]
            sel = np.nonzero(data.types == code)[0]
            request["codes"].append(GMSH_CODES[name])
            arrays[f"conn_{i}"] = np.concatenate([tags[data.element(e)] for e in sel])
            arrays[f"etags_{i}"] = (data.element_ids[sel] + 1 if data.element_ids.min() == 0
                                    else data.element_ids[sel])
    with tempfile.TemporaryDirectory(prefix="surfmesh-msh-") as tmp:
        request["out"] = os.path.join(tmp, os.path.basename(out))
        _run_gmsh("write", f"writing {out}", request, arrays, source=src.path)
        if not os.path.exists(request["out"]):
            raise ValueError(f"Gmsh wrote nothing for {out}")
        if src.fmt == "gmsh" and data.rewired is not None and len(data.rewired):
            # The source's elements, but those edge flips rewired.
            _rewire_msh_text(request["out"], {
                int(data.element_ids[e]): data.node_ids[data.element(e)].tolist()
                for e in data.rewired.tolist()})
        shutil.move(request["out"], out)


def _fem_from(data, nodes):
    import Fem

    fem = Fem.FemMesh()
    ids = data.node_ids if data.node_ids.min() > 0 else data.node_ids + 1
    eids = data.element_ids if data.element_ids.min() > 0 else data.element_ids + 1
    for nid, (x, y, z) in zip(ids.tolist(), nodes.tolist()):
        fem.addNode(x, y, z, int(nid))
    for e in range(data.element_count):  # element types checked by _check_format_holds
        fem.addFace([int(i) for i in ids[data.element(e)]], int(eids[e]))
    return fem


def _mesh_from(data, nodes):
    import FreeCAD
    import Mesh

    vec = FreeCAD.Vector  # element types checked by _check_format_holds
    pts = [vec(float(x), float(y), float(z)) for x, y, z in nodes]
    tris = [tuple(int(i) for i in data.element(e)) for e in range(data.element_count)]
    return Mesh.Mesh((pts, tris))


def _line_cells(src):
    """The edge (line) elements of ``src`` as meshio cells over its node order: a FEM mesh's
    edges (beams, the edge elements of a shell mesh), a Gmsh file's 1D elements; none for other
    inputs. So a mesh written through meshio keeps them, as the FEM and Gmsh writers do."""
    data = src.data
    lines = []  # (node count, node ids)
    if src.fmt == "fem" and src.fem is not None:
        for e in sorted(src.fem.Edges):
            lines.append(tuple(src.fem.getElementNodes(e)))
    elif src.fmt == "gmsh":
        res, got = _run_gmsh("lines", f"reading the 1D elements of {src.path}",
                             {"path": os.path.abspath(src.path)}, source=src.path)
        for j, k in enumerate(res["sizes"]):
            c = got[f"conn_{j}"]
            lines.extend(tuple(int(n) for n in c[i:i + k]) for i in range(0, len(c), k))
    cells = []
    for k, name in ((2, "line"), (3, "line3")):
        ids = [ln for ln in lines if len(ln) == k]
        if ids:
            pos, missing = conversion.positions_of(
                data.node_ids, np.asarray(ids, dtype=np.int64).reshape(-1))
            if not missing.any():
                cells.append((name, np.asarray(pos, dtype=np.int64).reshape(-1, k)))
    return cells


def _meshio_cells(data):
    inverse = {v: k for k, v in _MESHIO_TYPES.items()}
    cells = []
    for code in np.unique(data.types):
        name = conversion.ELEMENT_NAMES[int(code)]
        sel = np.nonzero(data.types == code)[0]
        cells.append((inverse[name], np.array([data.element(e) for e in sel])))
    return cells
