#!/usr/bin/python3
"""The ``surfmesh`` command (scripts/install.sh links it into ~/.local/bin, or /usr/local/bin as
root):

    surfmesh optimize part.step mesh.msh -o out.msh [--report r.json] [options]
    surfmesh measure part.step mesh.msh [--report r.json] [options]
    surfmesh measures
    surfmesh batch MANIFEST --out DIR [--jobs N] [--timeout S] [--resume] [--dask ADDRESS]
    surfmesh --version

It runs FreeCAD as a library of the system Python (the interpreter FreeCAD embeds), so exit
statuses and output are the script's own on every FreeCAD version. ``optimize``, ``measure`` and
``measures`` are the command line of surfmesh_cli.py, with its options, messages and exit
statuses (0 success, 2 bad input, 3 cancelled, 1 anything else); ``batch`` is batch.py.
"""

import os
import sys

# <Mod>/SurfMesh/SurfMesh/cli/launcher.py, through the command's symbolic link
_CLI = os.path.dirname(os.path.realpath(__file__))
_MOD = os.path.dirname(os.path.dirname(_CLI))
# Where Debian's (and upstream's) FreeCAD keep FreeCAD.so; FREECAD_LIB first when set.
_FREECAD_LIBS = ("/usr/lib/freecad/lib", "/usr/lib/freecad-python3/lib",
                 "/usr/lib/freecad-daily/lib", "/usr/local/lib/freecad/lib",
                 "/usr/local/lib")

USAGE = """usage: surfmesh {optimize,measure,measures,batch} ... | surfmesh --version

  optimize   smooth and untangle a mesh on a shape   (surfmesh optimize --help)
  measure    quality statistics of a mesh on a shape (surfmesh measure --help)
  measures   list the quality measures
  batch      run a CSV manifest of parts, each in its own process (surfmesh batch --help)
"""


def _import_freecad():
    try:
        import FreeCAD  # noqa: F401  (already importable: freecadcmd, or a set PYTHONPATH)

        return sys.modules["FreeCAD"]
    except ImportError:
        pass
    env = os.environ.get("FREECAD_LIB")
    for d in ([env] if env else []) + list(_FREECAD_LIBS):
        if d and os.path.isfile(os.path.join(d, "FreeCAD.so")) and d not in sys.path:
            sys.path.append(d)
            break
    try:
        import FreeCAD  # noqa: F811
    except ImportError as exc:
        raise SystemExit(
            f"surfmesh: error: cannot import FreeCAD in {sys.executable} ({exc}); install "
            "FreeCAD (scripts/install.sh), or set FREECAD_LIB to the folder of FreeCAD.so")
    # Imported as a library, FreeCAD puts only the Mod folders of its home (the libraries') on
    # sys.path, not those of its resource folder (Debian: /usr/share/freecad/Mod), which hold the
    # workbenches' Python parts: FEM's readers (Fem.read of an .inp asks feminout), its objects,
    # Gmsh tools. freecadcmd puts every one of them there; so does this.
    for base in dict.fromkeys((FreeCAD.getResourceDir(), FreeCAD.getHomePath())):
        mods = os.path.join(base, "Mod")
        if not os.path.isdir(mods):
            continue
        for name in sorted(os.listdir(mods)):
            d = os.path.join(mods, name)
            if os.path.isdir(d) and d not in sys.path:
                sys.path.append(d)
        if mods not in sys.path:
            sys.path.append(mods)
    return FreeCAD


def _version():
    fc = _import_freecad()
    if _MOD not in sys.path:
        sys.path.insert(0, _MOD)
    import SurfMesh

    ver = ".".join(fc.Version()[:3]).rstrip(".")
    return (f"surfmesh {SurfMesh.__version__} (FreeCAD {ver}, Python "
            f"{sys.version.split()[0]}, {os.path.normpath(os.path.dirname(SurfMesh.__file__))})")


def main(argv):
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE, end="")
        return 0 if argv else 2
    if argv[0] == "--version":
        print(_version())
        return 0
    if argv[0] == "batch":
        sys.path.insert(0, _CLI)
        import batch

        return batch.main(argv[1:], program=os.path.join(_CLI, "launcher.py"))
    _import_freecad()
    if _MOD not in sys.path:
        sys.path.insert(0, _MOD)
    from SurfMesh.cli import surfmesh_cli

    return surfmesh_cli.main(argv, prog="surfmesh")


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    # FreeCAD loaded as a library may still hold threads and Qt objects at interpreter exit:
    # leave without the teardown, with the status of the command.
    os._exit(code)
