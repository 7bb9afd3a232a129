"""Task panels of the SurfMesh workbench."""
