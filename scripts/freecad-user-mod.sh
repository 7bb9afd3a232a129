#!/usr/bin/env bash
# Prints the folder where FreeCAD looks for the current user's workbenches, as FreeCAD itself
# says (FreeCAD.getUserAppDataDir()): ~/.local/share/FreeCAD/Mod for 0.20 and 1.0,
# ~/.local/share/FreeCAD/v1-1/Mod for 1.1 (versioned user folders). Falls back to the former
# when FreeCAD cannot be imported (not installed yet).
/usr/bin/python3 - 2>/dev/null <<'PY' || echo "$HOME/.local/share/FreeCAD/Mod"
import os, sys
for d in ("/usr/lib/freecad/lib", "/usr/lib/freecad-python3/lib"):
    if os.path.isdir(d):
        sys.path.append(d)
import FreeCAD
print(os.path.join(FreeCAD.getUserAppDataDir(), "Mod").replace("//", "/"))
PY
