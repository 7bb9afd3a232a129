"""FreeCAD's FEM examples as cases of bench/peers.py (issue #45): the shape and the surface mesh
of each example with 2D elements (bench/python/fem_examples.py, run once by freecadcmd), written
as a Gmsh .msh 4.1 whose nodes are classified on the shape's entities with their parametric
coordinates, so that Gmsh's optimizers can run on it like on the suite's other cases.

Classification, with Gmsh's OCC kernel on the example's .brep (opened as gmsh_run opens it, so
the entity tags are those Gmsh gives the shape): a node within 1e-6 × the diagonal of a model
point is that point's; else of the nearest curve within that distance (its parameter t from
the orthogonal projection); else of the nearest surface within it whose trimmed face holds the
projection (its (u, v)). An element belongs to the surface of its nodes classified on a
surface, or, when all its nodes are on curves and points, to the surface holding its corners'
centroid. A node the classification cannot place is an error (no such node in FreeCAD 0.20's
examples). Node and element ids are FreeCAD's.

Perturbed variant: the surface-interior corner nodes are moved in (u, v) of their face by up
to 1.2 × their local size (the shortest corner edge of their elements), in rounds of 2 % of
them (at least 1, at most the target), a move kept only when the new (u, v) is inside the
trimmed face, so that every node stays exactly on its face, until at least max(2, min(20, 1 %
of the elements)) elements are tangled (seed 5, Python's random; 60 rounds at most). In a
second-order mesh every side node inside a face then follows its corners: it is put at the
face point of the (u, v) midpoint of its side's two corners (the examples' faces are flat: the
elements stay straight-sided, as FreeCAD's own tria6 are). Where that leaves fewer tangled
elements than the target (the quad8 cantilever: 2 × 2 elements of 4000 × 500 whose one
interior corner cannot fold any of them while it stays on the plate), every surface-interior
node, side nodes included, is moved the same way in further rounds. Tangled here: the
element's Jacobian, sampled at its corners, side midpoints and center, has a sign against the
majority of its face's elements somewhere (the suite's judge counts the invalid elements
itself; on FreeCAD 0.20.2's examples both counts agree).
"""
import json
import math
import os
import random
import subprocess
import time

import numpy as np

import gmsh

import gmsh_compare as gc

HERE = os.path.dirname(os.path.abspath(__file__))
# example → short name (case names); all are 2D meshes on a Part shape in FreeCAD 0.20.
EXAMPLES = {
    "ccx_cantilever_ele_quad4": "cantilever",
    "ccx_cantilever_ele_quad8": "cantilever",
    "ccx_cantilever_ele_tria3": "cantilever",
    "ccx_cantilever_ele_tria6": "cantilever",
    "mystran_plate": "mystran_plate",
    "rc_wall_2d": "rc_wall_2d",
    "buckling_platebuckling": "buckling_plate",
    "material_multiple_bendingbeam_fivefaces": "bendingbeam_5faces",
    "square_pipe_end_twisted_nodeforces": "square_pipe_twisted",
    "buckling_lateraltorsionalbuckling": "buckling_ibeam",
    "constraint_contact_shell_shell": "contact_tubes",
}
# element type of the examples (for the case names and the order)
ELEMENT = {"ccx_cantilever_ele_quad4": "quad4", "ccx_cantilever_ele_quad8": "quad8",
           "ccx_cantilever_ele_tria3": "tria3", "ccx_cantilever_ele_tria6": "tria6",
           "mystran_plate": "quad4", "rc_wall_2d": "tria6", "buckling_platebuckling": "tria6",
           "material_multiple_bendingbeam_fivefaces": "tria6",
           "square_pipe_end_twisted_nodeforces": "tria6",
           "buckling_lateraltorsionalbuckling": "tria6",
           "constraint_contact_shell_shell": "tria3"}
GMSH_TYPE = {3: 2, 4: 3, 6: 9, 8: 16}  # nodes per element → Gmsh element type
CORNERS = {3: 3, 4: 4, 6: 3, 8: 4}
SIDES = {6: [(3, 0, 1), (4, 1, 2), (5, 2, 0)], 8: [(4, 0, 1), (5, 1, 2), (6, 2, 3), (7, 3, 0)]}
AMP = 1.2


def cases(examples=None):
    """Case dicts of peers.py (name, source "fem", example, order, kind) for the examples."""
    out = []
    for ex in examples or EXAMPLES:
        el = ELEMENT[ex]
        for kind in ("raw", "perturbed"):
            out.append(dict(name=f"fem {EXAMPLES[ex]} {el} {kind}", source="fem", example=ex,
                            order=2 if el in ("tria6", "quad8") else 1, kind=kind,
                            quads=el.startswith("quad")))
    return out


def export(work, examples):
    """Runs bench/python/fem_examples.py once (freecadcmd) for the examples not yet written in
    `work`; returns {example: its entry of fem_examples.json}."""
    listing = os.path.join(work, "fem_examples.json")
    have = {}
    if os.path.exists(listing):
        with open(listing) as f:
            have = {c["name"]: c for c in json.load(f)["cases"] if "error" not in c}
    if any(ex not in have for ex in examples):
        env = dict(os.environ, SURFMESH_FEM_OUT=work, SURFMESH_FEM_EXAMPLES=",".join(examples))
        run = subprocess.run(["freecadcmd", os.path.join(HERE, "python", "fem_examples.py")],
                             capture_output=True, text=True, env=env, timeout=600)
        if not os.path.exists(listing):
            tail = (run.stderr or run.stdout).strip().splitlines()[-3:]
            raise RuntimeError("fem_examples.py wrote nothing: " + " / ".join(tail))
        with open(listing) as f:
            got = json.load(f)
        have.update({c["name"]: c for c in got["cases"]})
        got["cases"] = list(have.values())
        with open(listing, "w") as f:  # those of earlier calls kept
            json.dump(got, f, indent=1)
    return have


def shape_functions(n):
    """(sample points, dN/dxi (S, n), dN/deta (S, n)) of an element of n nodes (SMESH = Gmsh
    order: corners, then the side nodes of sides 01, 12, 20 / 01, 12, 23, 30)."""
    if n in (3, 6):
        pts = [(0, 0), (1, 0), (0, 1), (.5, 0), (.5, .5), (0, .5), (1 / 3, 1 / 3)]
    else:
        pts = [(x, y) for x in (-1, 0, 1) for y in (-1, 0, 1)]
    dx, dy = [], []
    for x, y in pts:
        if n == 3:
            dx.append([-1, 1, 0])
            dy.append([-1, 0, 1])
        elif n == 6:
            l0 = 1 - x - y
            dx.append([1 - 4 * l0, 4 * x - 1, 0, 4 * (l0 - x), 4 * y, -4 * y])
            dy.append([1 - 4 * l0, 0, 4 * y - 1, -4 * x, 4 * x, 4 * (l0 - y)])
        else:
            c = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
            if n == 4:
                dx.append([xi * (1 + y * yi) / 4 for xi, yi in c])
                dy.append([yi * (1 + x * xi) / 4 for xi, yi in c])
            else:
                rx = [xi * (1 + y * yi) * (2 * x * xi + y * yi) / 4 for xi, yi in c]
                ry = [yi * (1 + x * xi) * (x * xi + 2 * y * yi) / 4 for xi, yi in c]
                for xi, yi in [(0, -1), (1, 0), (0, 1), (-1, 0)]:
                    if xi == 0:
                        rx.append(-x * (1 + y * yi))
                        ry.append(0.5 * (1 - x * x) * yi)
                    else:
                        rx.append(0.5 * xi * (1 - y * y))
                        ry.append(-y * (1 + x * xi))
                dx.append(rx)
                dy.append(ry)
    return np.array(pts, float), np.array(dx, float), np.array(dy, float)


def parameters(dim, tag, x, iterations=30):
    """(parametric coordinates (N, dim), distances (N,)) of the orthogonal projections of the
    points x (N, 3) on entity (dim, tag): the nearest of Gauss-Newton descents on getValue /
    getDerivative started from Gmsh's closest point's parameters and from a 3 × 3 grid of the
    parameter box, a periodic parameter brought back into its box. (Gmsh 4.8.4's
    getClosestPoint answers (u, v) = 0, "Inverse surface mapping could not converge", or now
    and then other parameters, for the planes and lines of FreeCAD's breps; one start is not
    enough on a cylinder, where a descent can stop at the antipode.)"""
    _, pc = gmsh.model.getClosestPoint(dim, tag, x.reshape(-1).tolist())
    lo, hi = (np.array(b, float) for b in gmsh.model.getParametrizationBounds(dim, tag))
    grid = [(a,) for a in (0.1, 0.5, 0.9)] if dim == 1 else \
        [(a, b) for a in (0.1, 0.5, 0.9) for b in (0.1, 0.5, 0.9)]
    starts = [np.array(pc, float).reshape(-1, dim)]
    starts += [np.tile(lo + np.array(g) * (hi - lo), (len(x), 1)) for g in grid]
    best_d = np.full(len(x), np.inf)
    best_p = np.zeros((len(x), dim))
    for p in starts:
        p = np.where(np.isfinite(p), p, 0.5 * (lo + hi))
        for _ in range(iterations):
            r = x - value(dim, tag, p)
            der = np.array(gmsh.model.getDerivative(dim, tag, p.reshape(-1).tolist()))
            jac = der.reshape(-1, dim, 3)  # (N, dim, 3)
            jtj = np.einsum("nic,njc->nij", jac, jac) + 1e-300 * np.eye(dim)
            jtr = np.einsum("nic,nc->ni", jac, r)
            dp = np.linalg.solve(jtj, jtr[..., None])[..., 0]
            p = p + dp
            if np.abs(dp).max() <= 1e-13 * (1 + np.abs(p).max()):
                break
        d = np.linalg.norm(value(dim, tag, p) - x, axis=1)
        better = d < best_d
        best_d[better], best_p[better] = d[better], p[better]
    # a periodic parameter (circle, cylinder) found outside its box: its period's image
    for i in range(dim):
        out = (best_p[:, i] < lo[i]) | (best_p[:, i] > hi[i])
        if out.any():
            q = best_p[out].copy()
            q[:, i] = lo[i] + np.mod(q[:, i] - lo[i], hi[i] - lo[i])
            same = np.linalg.norm(value(dim, tag, q) - value(dim, tag, best_p[out]),
                                  axis=1) < 1e-9 * (1 + np.abs(x[out]).max(axis=1))
            idx = np.nonzero(out)[0][same]
            best_p[idx] = q[same]
    return best_p, best_d


def value(dim, tag, par):
    """Points (N, 3) of entity (dim, tag) at the parameters par (N, dim)."""
    return np.array(gmsh.model.getValue(dim, tag, par.reshape(-1).tolist())).reshape(-1, 3)


class FemModel:
    """The current Gmsh model: the example's shape with its mesh classified on it."""

    def __init__(self, brep, mesh_json):
        with open(mesh_json) as f:
            m = json.load(f)
        gmsh.clear()
        gmsh.open(brep)
        self.diag = gc.bbox_diagonal()
        tol = 1e-6 * self.diag
        ids = np.array(sorted(int(k) for k in m["nodes"]), dtype=np.int64)
        xyz = np.array([m["nodes"][str(i)] for i in ids], float)
        self.ids, self.xyz = ids, xyz
        self.index = {int(t): k for k, t in enumerate(ids)}
        n = len(ids)
        self.dim = np.full(n, -1)
        self.tag = np.zeros(n, dtype=np.int64)
        self.par = [None] * n
        best = np.full(n, np.inf)
        for _, p in gmsh.model.getEntities(0):
            d = np.linalg.norm(xyz - np.array(gmsh.model.getValue(0, p, [])), axis=1)
            hit = (d < tol) & (d < best)
            self.dim[hit], self.tag[hit], best[hit] = 0, p, d[hit]
        for dim in (1, 2):
            free = np.nonzero(self.dim < 0)[0]
            best = np.full(n, np.inf)
            for _, t in gmsh.model.getEntities(dim) if len(free) else []:
                pc, d = parameters(dim, t, xyz[free])
                lo, hi = gmsh.model.getParametrizationBounds(dim, t)
                for j in np.nonzero((d < tol) & (d < best[free]))[0]:
                    if dim == 1 and not lo[0] - 1e-9 <= pc[j, 0] <= hi[0] + 1e-9:
                        continue
                    if dim == 2 and not gc.inside_face(t, pc[j].tolist()):
                        continue
                    k = free[j]
                    self.dim[k], self.tag[k], self.par[k], best[k] = dim, t, pc[j].copy(), d[j]
        if (self.dim < 0).any():
            k = int(np.nonzero(self.dim < 0)[0][0])
            raise RuntimeError(f"{int((self.dim < 0).sum())} nodes off the shape (node "
                               f"{ids[k]} at {xyz[k].tolist()})")
        # elements → surfaces
        self.elements = {}  # surface tag → list of (id, node indices)
        for eid, nodes in m["elements"]:
            idx = [self.index[v] for v in nodes]
            on = {int(self.tag[k]) for k in idx if self.dim[k] == 2}
            if len(on) > 1:
                raise RuntimeError(f"element {eid} has nodes on surfaces {sorted(on)}")
            if on:
                s = on.pop()
            else:
                s = self.surface_of(xyz[idx[:CORNERS[len(idx)]]].mean(axis=0), tol)
            self.elements.setdefault(s, []).append((int(eid), idx))
        self.npe = {len(i) for v in self.elements.values() for _, i in v}
        if len(self.npe) != 1:
            raise RuntimeError(f"mixed element kinds {sorted(self.npe)}")
        self.npe = self.npe.pop()
        self._uv = {}  # (node, surface) → (u, v) of a node off that surface's interior
        self.add_to_gmsh()

    def surface_of(self, x, tol):
        for _, t in gmsh.model.getEntities(2):
            pc, d = parameters(2, t, np.array([x]))
            if d[0] < tol and gc.inside_face(t, pc[0].tolist()):
                return t
        raise RuntimeError(f"no surface holds the point {list(x)}")

    def add_to_gmsh(self):
        for dim in (0, 1, 2):
            for _, t in gmsh.model.getEntities(dim):
                k = np.nonzero((self.dim == dim) & (self.tag == t))[0]
                if len(k) == 0:
                    continue
                par = [] if dim == 0 else np.concatenate([self.par[j] for j in k]).tolist()
                gmsh.model.mesh.addNodes(dim, t, self.ids[k].tolist(),
                                         self.xyz[k].reshape(-1).tolist(), par)
        for s, els in self.elements.items():
            gmsh.model.mesh.addElementsByType(
                s, GMSH_TYPE[self.npe], [e for e, _ in els],
                self.ids[np.array([i for _, i in els]).reshape(-1)].tolist())

    def uv_on(self, k, s):
        """(u, v) of node k on surface s (its own when it is a node of s's interior)."""
        if self.dim[k] == 2 and self.tag[k] == s:
            return self.par[k]
        key = (k, s)
        if key not in self._uv:
            self._uv[key] = parameters(2, s, self.xyz[k][None])[0][0]
        return self._uv[key]

    def tangled(self):
        """Elements whose sampled Jacobian has a sign against their surface's majority."""
        _, dx, dy = shape_functions(self.npe)
        total = 0
        for s, els in self.elements.items():
            idx = np.array([i for _, i in els])
            x = self.xyz[idx]  # (E, n, 3)
            nc = CORNERS[self.npe]
            nrm = np.zeros((len(els), 3))
            for j in range(nc):
                uv = np.array([self.uv_on(k, s) for k in idx[:, j]])
                nrm += np.array(gmsh.model.getNormal(s, uv.reshape(-1).tolist())).reshape(-1, 3)
            sg = np.einsum("sn,enc->esc", dx, x)
            tg = np.einsum("sn,enc->esc", dy, x)
            det = np.einsum("esc,ec->es", np.cross(sg, tg), nrm)  # (E, samples)
            centre = det[:, -1] if self.npe in (3, 6) else det[:, 4]
            major = 1.0 if (centre > 0).sum() >= (centre < 0).sum() else -1.0
            total += int((det * major <= 0).any(axis=1).sum())
        return total

    def perturb(self, seed=5, amp=AMP, max_rounds=60, fraction=0.02):
        """Moves surface-interior nodes in (u, v) (module docstring); returns (tangled elements,
        moved nodes)."""
        n = self.npe
        nelem = sum(len(v) for v in self.elements.values())
        target = max(2, min(20, math.ceil(0.01 * nelem)))
        corner = np.zeros(len(self.ids), bool)
        size = np.full(len(self.ids), np.inf)
        for els in self.elements.values():
            for _, idx in els:
                c = self.xyz[idx[:CORNERS[n]]]
                le = np.min(np.linalg.norm(c - np.roll(c, 1, axis=0), axis=1))
                size[idx] = np.minimum(size[idx], le)
                corner[idx[:CORNERS[n]]] = True
        corners = [int(k) for k in np.nonzero(corner & (self.dim == 2))[0]]
        everyone = [int(k) for k in np.nonzero(self.dim == 2)[0]]
        if n in SIDES:  # boundary corners' (u, v) on their elements' surfaces, once
            for s, els in self.elements.items():
                for _, idx in els:
                    for k in idx[:CORNERS[n]]:
                        self.uv_on(k, s)
        rng = random.Random(seed)
        moved = set()
        tangled = self.tangled()
        # corners first (side nodes following them); then, on a second-order mesh that this
        # leaves with fewer tangled elements than asked, the side nodes too
        phases = [(corners, n in SIDES)] + ([(everyone, False)] if n in SIDES else [])
        for cand, sides_follow in phases:
            rounds = 0
            while cand and tangled < target and rounds < max_rounds:
                rounds += 1
                count = max(1, min(int(fraction * len(cand)), target))
                for k in rng.sample(cand, count):
                    s = int(self.tag[k])
                    du_dv = np.array(gmsh.model.getDerivative(2, s, self.par[k].tolist()))
                    hu, hv = np.linalg.norm(du_dv[:3]), np.linalg.norm(du_dv[3:])
                    uv = self.par[k] + np.array(
                        [amp * size[k] / max(hu, 1e-12) * rng.uniform(-1, 1),
                         amp * size[k] / max(hv, 1e-12) * rng.uniform(-1, 1)])
                    if not gc.inside_face(s, uv.tolist()):
                        continue
                    self.par[k] = uv
                    self.xyz[k] = gmsh.model.getValue(2, s, uv.tolist())
                    moved.add(k)
                if sides_follow:
                    self.sides_to_midpoints()
                tangled = self.tangled()
        for k in range(len(self.ids)):
            if self.dim[k] == 2:
                gmsh.model.mesh.setNode(int(self.ids[k]), self.xyz[k].tolist(),
                                        self.par[k].tolist())
        return tangled, len(moved)

    def sides_to_midpoints(self):
        for s, els in self.elements.items():
            for _, idx in els:
                for m, a, b in SIDES[self.npe]:
                    k = idx[m]
                    if self.dim[k] != 2:
                        continue
                    uv = 0.5 * (self.uv_on(idx[a], s) + self.uv_on(idx[b], s))
                    self.par[k] = uv
                    self.xyz[k] = gmsh.model.getValue(2, s, uv.tolist())


def write_case(case, work, stem, seed=5):
    """peers.write_case for a FEM example: (shape path, mesh path, tangled elements after the
    perturbation or None, seconds). Needs gmsh initialized (it is restarted)."""
    entry = export(work, [case["example"]])[case["example"]]
    if "error" in entry:
        raise RuntimeError(f"fem_examples.py: {case['example']}: {entry['error']}")
    t0 = time.perf_counter()
    # a fresh Gmsh: after gmsh.clear(), opening a .brep in the same session can give its
    # entities other tags than a fresh process (gmsh_run) gives them
    gmsh.finalize()
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
    model = FemModel(entry["brep"], entry["json"])
    tangled = None
    if case["kind"] == "perturbed":
        tangled, _ = model.perturb(seed=seed)
    seconds = time.perf_counter() - t0
    gmsh.option.setNumber("Mesh.SaveParametric", 1)
    gmsh.write(stem + ".msh")
    gmsh.option.setNumber("Mesh.SaveParametric", 0)
    return entry["brep"], stem + ".msh", tangled, seconds
