"""Gmsh's Python API in a process of its own: SurfMesh reads and writes Gmsh .msh files through
this script, never through Gmsh in the FreeCAD process (Gmsh's C++ code can end the whole process
on some inputs: an uncaught exception, an abort). See ``fileio._run_gmsh``.

    python3 gmsh_worker.py OP FOLDER

``FOLDER`` holds ``request.json`` (and ``request.npz``, arrays); the script leaves there
``started`` once numpy and gmsh are imported, then ``result.json`` (and ``result.npz``). OP:

* ``read``:  open ``path``; the nodes (tags, coordinates), the 2D elements by type (code, name,
  tags, node tags) and the 3D ones (name, count);
* ``lines``: open ``path``; its 1D elements by type (nodes per element, node tags);
* ``write``: open ``source`` and move its nodes (``node_tags``, ``nodes``), or build a model of
  one discrete surface (``node_tags``, ``nodes``, ``codes``, ``etags_<i>``, ``conn_<i>``);
  write ``out`` (ASCII, all elements, version ``version``).

Standard library, numpy and gmsh only (no FreeCAD, no SurfMesh): it runs under a bare Python.
"""

import os
import sys

# Run as a script, its folder (SurfMesh/app) comes first on sys.path: none of the package's
# modules may stand in for one that numpy or gmsh imports.
_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != _HERE]

import json  # noqa: E402

EXIT_USAGE = 64


def _gmsh():
    import gmsh

    try:
        gmsh.initialize(readConfigFiles=False)
    except TypeError:  # older signature
        gmsh.initialize()
    # Gmsh's messages go to this process's output, which SurfMesh shows when Gmsh fails.
    gmsh.option.setNumber("General.Terminal", 1)
    return gmsh


def _open(gmsh, path, result):
    """gmsh.open(path); False (and the message in ``result``) when Gmsh refuses the file."""
    gmsh.clear()
    try:
        gmsh.open(path)
    except Exception as exc:  # Gmsh's Python API raises Exception with Gmsh's last error
        result["open_error"] = str(exc)
        return False
    return True


def op_read(gmsh, np, req, result, arrays):
    if not _open(gmsh, req["path"], result):
        return
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    arrays["node_tags"] = np.asarray(node_tags, dtype=np.int64)
    arrays["coords"] = np.asarray(coords, dtype=np.float64)
    types, tags, conn_tags = gmsh.model.mesh.getElements(2)
    result["types"] = [int(t) for t in types]
    result["names"] = [gmsh.model.mesh.getElementProperties(int(t))[0] for t in types]
    for i, (etags, ntags) in enumerate(zip(tags, conn_tags)):
        arrays[f"etags_{i}"] = np.asarray(etags, dtype=np.int64)
        arrays[f"conn_{i}"] = np.asarray(ntags, dtype=np.int64)
    vol_types, vol_tags, _ = gmsh.model.mesh.getElements(3)
    result["volumes"] = [[gmsh.model.mesh.getElementProperties(int(t))[0], len(t_tags)]
                         for t, t_tags in zip(vol_types, vol_tags)]


def op_lines(gmsh, np, req, result, arrays):
    if not _open(gmsh, req["path"], result):
        return
    types, _tags, conn = gmsh.model.mesh.getElements(1)
    result["sizes"] = [int(gmsh.model.mesh.getElementProperties(int(t))[3]) for t in types]
    for i, c in enumerate(conn):
        arrays[f"conn_{i}"] = np.asarray(c, dtype=np.int64)


def op_write(gmsh, np, req, result, arrays):
    with np.load(os.path.join(req["folder"], "request.npz")) as given:
        got = {k: given[k] for k in given.files}
    tags, nodes = got["node_tags"], got["nodes"]
    if req.get("source"):
        if not _open(gmsh, req["source"], result):
            return
        for tag, xyz in zip(tags.tolist(), nodes.tolist()):
            gmsh.model.mesh.setNode(int(tag), xyz, [])
    else:
        gmsh.clear()
        gmsh.model.add("surfmesh")
        gmsh.model.addDiscreteEntity(2, 1)
        gmsh.model.mesh.addNodes(2, 1, tags.tolist(), nodes.reshape(-1).tolist())
        for i, code in enumerate(req["codes"]):
            gmsh.model.mesh.addElementsByType(
                1, int(code), got[f"etags_{i}"].tolist(), got[f"conn_{i}"].tolist())
    gmsh.option.setNumber("Mesh.MshFileVersion", req["version"])
    gmsh.option.setNumber("Mesh.SaveAll", 1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(req["out"])


OPS = {"read": op_read, "lines": op_lines, "write": op_write}


def main(argv):
    if len(argv) != 2 or argv[0] not in OPS or not os.path.isdir(argv[1]):
        print(f"usage: gmsh_worker.py {{{','.join(OPS)}}} FOLDER", file=sys.stderr)
        return EXIT_USAGE
    op, folder = argv
    with open(os.path.join(folder, "request.json")) as fh:
        req = json.load(fh)
    req["folder"] = folder
    import numpy as np

    gmsh = _gmsh()
    with open(os.path.join(folder, "started"), "w") as fh:
        fh.write(f"{sys.executable}\n{getattr(gmsh, '__version__', '?')}\n")
    result, arrays = {"gmsh_version": getattr(gmsh, "__version__", "?")}, {}
    OPS[op](gmsh, np, req, result, arrays)
    if arrays:
        np.savez(os.path.join(folder, "result.npz"), **arrays)
    tmp = os.path.join(folder, "result.json.part")
    with open(tmp, "w") as fh:
        json.dump(result, fh)
    os.replace(tmp, os.path.join(folder, "result.json"))
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    # Without Gmsh's teardown (gmsh.finalize, static destructors): the answer is written.
    os._exit(code)
