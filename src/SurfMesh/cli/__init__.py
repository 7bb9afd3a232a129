"""Command line entry (run with freecadcmd): see surfmesh_cli.py."""
