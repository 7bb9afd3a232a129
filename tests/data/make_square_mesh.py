# Regenerates square_frontal.txt: gmsh 4.8.4 (Debian python3-gmsh), unit square, Frontal-Delaunay
# (Mesh.Algorithm 6), h = 0.06. Usage: /usr/bin/python3 make_square_mesh.py 0.06 6 square_frontal.txt
# Format: "N E B", N lines "x y", E lines "i j k" (0-based, counter-clockwise), one line of B
# boundary node ids.
import gmsh, sys
gmsh.initialize(); gmsh.option.setNumber("General.Terminal",0)
gmsh.model.add("sq")
gmsh.model.occ.addRectangle(0,0,0,1,1); gmsh.model.occ.synchronize()
h=float(sys.argv[1]); alg=int(sys.argv[2])
gmsh.option.setNumber("Mesh.MeshSizeMin",h); gmsh.option.setNumber("Mesh.MeshSizeMax",h)
gmsh.option.setNumber("Mesh.Algorithm",alg)
gmsh.model.mesh.generate(2)
tags, xyz, _ = gmsh.model.mesh.getNodes()
et, etags, enodes = gmsh.model.mesh.getElements(2)
import numpy as np
xyz=np.array(xyz).reshape(-1,3); idx={t:i for i,t in enumerate(tags)}
tri=np.array([idx[t] for t in enodes[0]]).reshape(-1,3)
q=[]
for a,b,c in tri:
    A=xyz[a];B=xyz[b];C=xyz[c]
    ar=0.5*np.linalg.norm(np.cross(B-A,C-A)); l2=((B-A)**2).sum()+((C-B)**2).sum()+((A-C)**2).sum()
    q.append(4*np.sqrt(3)*ar/l2)
print(len(xyz),len(tri),min(q),np.mean(q))
# boundary nodes: on x=0,1 or y=0,1
bnd=[i for i,p in enumerate(xyz) if min(p[0],1-p[0],p[1],1-p[1])<1e-12]
with open(sys.argv[3],"w") as f:
    f.write(f"{len(xyz)} {len(tri)} {len(bnd)}\n")
    for p in xyz: f.write(f"{p[0]:.17g} {p[1]:.17g}\n")
    for t in tri: f.write(f"{t[0]} {t[1]} {t[2]}\n")
    f.write(" ".join(map(str,bnd))+"\n")
gmsh.finalize()
