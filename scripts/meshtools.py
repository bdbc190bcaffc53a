"""Small, dependency-light mesh helpers shared by the dataset scripts.

Only Python 3 + NumPy. Meshes are (V, F) with V a (nV, 3) float64 array and
F a (nF, 3) int64 array of 0-based vertex indices (triangles only).

Everything here is written independently of the Rust code in crates/ so that
`datasets/stats.json` can serve as a cross-check of the Rust topology code.
"""

import heapq
import os
from collections import defaultdict, deque

import numpy as np


# ----------------------------------------------------------------------------
# I/O
# ----------------------------------------------------------------------------

def _polys_to_tris(polys):
    tris = []
    for p in polys:
        for j in range(1, len(p) - 1):
            tris.append((p[0], p[j], p[j + 1]))
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def read_obj(path):
    """Read `v` and `f` lines (polygons fan-triangulated, `v/vt/vn` indices ok)."""
    verts, polys = [], []
    with open(path, "r") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                idx = []
                for tok in line.split()[1:]:
                    i = int(tok.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                polys.append(idx)
    return np.asarray(verts, dtype=np.float64), _polys_to_tris(polys)


def read_off(path):
    """Read an ASCII OFF file (polygons fan-triangulated)."""
    with open(path, "r") as fh:
        toks = fh.read().split()
    assert toks[0] == "OFF", path
    nv, nf = int(toks[1]), int(toks[2])
    pos = 4
    V = np.asarray(toks[pos:pos + 3 * nv], dtype=np.float64).reshape(nv, 3)
    pos += 3 * nv
    polys = []
    for _ in range(nf):
        k = int(toks[pos])
        polys.append([int(t) for t in toks[pos + 1:pos + 1 + k]])
        pos += 1 + k
    return V, _polys_to_tris(polys)


def read_ply_ascii(path):
    """Read an ASCII PLY with x y z as the first vertex properties and a face list."""
    with open(path, "r") as fh:
        lines = fh.read().split("\n")
    assert lines[0].strip() == "ply"
    assert "ascii" in lines[1], "only ASCII PLY supported here: " + path
    nv = nf = 0
    i = 2
    while lines[i].strip() != "end_header":
        t = lines[i].split()
        if t[:2] == ["element", "vertex"]:
            nv = int(t[2])
        elif t[:2] == ["element", "face"]:
            nf = int(t[2])
        i += 1
    i += 1
    V = np.asarray([[float(x) for x in lines[i + k].split()[:3]] for k in range(nv)])
    i += nv
    polys = []
    for k in range(nf):
        t = [int(x) for x in lines[i + k].split()]
        polys.append(t[1:1 + t[0]])
    return V, _polys_to_tris(polys)


def read_mesh(path):
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        return read_obj(path)
    if ext == ".off":
        return read_off(path)
    if ext == ".ply":
        return read_ply_ascii(path)
    raise ValueError("unknown mesh format: " + path)


def write_obj(path, V, F, header_lines=(), decimals=6):
    fmt = "v %.{0}f %.{0}f %.{0}f\n".format(decimals)
    with open(path, "w", newline="\n") as fh:
        for h in header_lines:
            fh.write("# " + h + "\n")
        fh.write("".join(fmt % tuple(p) for p in V))
        fh.write("".join("f %d %d %d\n" % (a + 1, b + 1, c + 1) for a, b, c in F))


def write_off(path, V, F, sig=6):
    fmt = "%.{0}g %.{0}g %.{0}g\n".format(sig)
    with open(path, "w", newline="\n") as fh:
        fh.write("OFF\n%d %d 0\n" % (len(V), len(F)))
        fh.write("".join(fmt % tuple(p) for p in V))
        fh.write("".join("3 %d %d %d\n" % (a, b, c) for a, b, c in F))


# ----------------------------------------------------------------------------
# Topology
# ----------------------------------------------------------------------------

def half_edges(F):
    """(3nF, 2) directed edges (i -> j) in face order."""
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=0)


def topology(V, F):
    """Independent topology statistics of a triangle mesh.

    V counts vertices referenced by at least one face (`V_file` counts all).
    E counts undirected edges. chi = V - E + F. A boundary edge is used by
    exactly one face; boundary loops are traced over the boundary edges
    (counting the connected components of the boundary-edge graph).
    `oriented`: every interior edge appears once in each direction and no
    directed edge appears twice. `manifold`: every edge has 1 or 2 faces and
    every vertex's incident faces form a single fan (edge-connected around it).
    """
    F = np.asarray(F, dtype=np.int64)
    nF = len(F)
    used = np.unique(F)
    nV = len(used)
    he = half_edges(F)
    und = np.sort(he, axis=1)
    key = und[:, 0] * (int(F.max()) + 1) + und[:, 1]
    uniq, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    nE = len(uniq)
    edge_manifold = bool(cnt.max() <= 2)
    # orientation: directed edges unique
    dkey = he[:, 0] * (int(F.max()) + 1) + he[:, 1]
    oriented = bool(len(np.unique(dkey)) == len(dkey)) and edge_manifold
    # boundary edges
    bmask = cnt[inv] == 1
    bedges = he[bmask]
    # boundary loops = components of boundary edge graph
    parent = {}

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in bedges:
        a = int(a)
        b = int(b)
        parent.setdefault(a, a)
        parent.setdefault(b, b)
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    n_loops = len({find(a) for a in parent})
    # boundary vertex degree (in boundary edge graph) must be 2 for simple loops
    bdeg = defaultdict(int)
    for a, b in bedges:
        bdeg[int(a)] += 1
        bdeg[int(b)] += 1
    simple_boundary = all(d == 2 for d in bdeg.values())
    # components over faces (via shared vertices)
    comps = n_components(F)
    # vertex manifoldness: the faces around each vertex are one edge-connected fan
    vert_manifold = vertex_fans_ok(F)
    chi = nV - nE + nF
    manifold = edge_manifold and vert_manifold and simple_boundary
    if comps == 1 and manifold:
        genus = (2 - chi - n_loops) / 2
    else:
        genus = None
    if comps == 1 and manifold and n_loops == 1 and chi == 1:
        cls = "disk"
    elif comps == 1 and manifold and n_loops == 0 and chi == 2:
        cls = "sphere"
    else:
        cls = "other"
    return {
        "V": int(nV), "V_file": int(len(V)), "F": int(nF), "E": int(nE),
        "boundary_loops": int(n_loops), "euler": int(chi), "components": int(comps),
        "genus": genus, "manifold": bool(manifold), "oriented": bool(oriented),
        "class": cls,
    }


def n_components(F):
    F = np.asarray(F)
    n = int(F.max()) + 1
    parent = np.arange(n)

    def find(a):
        r = a
        while parent[r] != r:
            r = parent[r]
        while parent[a] != r:
            parent[a], a = r, parent[a]
        return r

    for a, b, c in F:
        ra, rb, rc = find(a), find(b), find(c)
        parent[rb] = ra
        parent[find(rc)] = ra
    used = np.unique(F)
    return len({find(int(v)) for v in used})


def vertex_fans_ok(F):
    """True iff, for every vertex, its incident faces are connected through
    edges incident to that vertex (no 'bow-tie' vertices)."""
    vf = defaultdict(list)
    for fi, f in enumerate(F):
        for k in range(3):
            vf[int(f[k])].append(fi)
    for v, faces in vf.items():
        # union faces sharing an edge (v, w)
        by_w = defaultdict(list)
        for fi in faces:
            for w in F[fi]:
                w = int(w)
                if w != v:
                    by_w[w].append(fi)
        parent = {fi: fi for fi in faces}

        def find(a):
            while parent[a] != a:
                a = parent[a]
            return a

        for fl in by_w.values():
            for fj in fl[1:]:
                ra, rb = find(fl[0]), find(fj)
                if ra != rb:
                    parent[ra] = rb
        if len({find(fi) for fi in faces}) != 1:
            return False
    return True


def boundary_loops(F):
    """Ordered boundary loops following the boundary half-edge direction
    (the face to the left). Requires a manifold, oriented mesh."""
    he = half_edges(np.asarray(F))
    dset = set(map(tuple, he.tolist()))
    nxt = {}
    for a, b in he.tolist():
        if (b, a) not in dset:
            assert a not in nxt, "non-simple boundary at vertex %d" % a
            nxt[a] = b
    loops, seen = [], set()
    for s in sorted(nxt):
        if s in seen:
            continue
        loop, v = [], s
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(loop)
    return loops


def triangle_areas(V, F):
    V = np.asarray(V)
    F = np.asarray(F)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return 0.5 * np.linalg.norm(n, axis=1)


def signed_volume(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def orient_consistently(F):
    """BFS over faces flipping each face to agree with an already-visited
    neighbour (shared edge used in opposite directions). Returns (F', n_flipped).
    Raises if the surface is not orientable."""
    F = np.array(F, dtype=np.int64)
    edge_faces = defaultdict(list)
    for fi, f in enumerate(F):
        for k in range(3):
            a, b = int(f[k]), int(f[(k + 1) % 3])
            edge_faces[(min(a, b), max(a, b))].append(fi)
    done = np.zeros(len(F), dtype=bool)
    flipped = 0

    def has_dir(f, a, b):
        for k in range(3):
            if f[k] == a and f[(k + 1) % 3] == b:
                return True
        return False

    for seed in range(len(F)):
        if done[seed]:
            continue
        done[seed] = True
        q = deque([seed])
        while q:
            fi = q.popleft()
            f = F[fi]
            for k in range(3):
                a, b = int(f[k]), int(f[(k + 1) % 3])
                for gj in edge_faces[(min(a, b), max(a, b))]:
                    if gj == fi:
                        continue
                    g = F[gj]
                    same = has_dir(g, a, b)
                    if done[gj]:
                        if same:
                            raise ValueError("non-orientable surface")
                        continue
                    if same:
                        F[gj] = g[[0, 2, 1]]
                        flipped += 1
                    done[gj] = True
                    q.append(gj)
    return F, flipped


def vertex_adjacency(V, F):
    """Undirected edge list (i<j) with Euclidean lengths and CSR adjacency."""
    he = half_edges(np.asarray(F))
    und = np.unique(np.sort(he, axis=1), axis=0)
    n = len(V)
    w = np.linalg.norm(V[und[:, 0]] - V[und[:, 1]], axis=1)
    src = np.concatenate([und[:, 0], und[:, 1]])
    dst = np.concatenate([und[:, 1], und[:, 0]])
    ww = np.concatenate([w, w])
    order = np.argsort(src, kind="stable")
    src, dst, ww = src[order], dst[order], ww[order]
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(ptr, src + 1, 1)
    ptr = np.cumsum(ptr)
    return ptr, dst, ww


def dijkstra(V, F, sources, adj=None):
    """Edge-graph geodesic distance from a set of source vertices."""
    ptr, dst, ww = adj if adj is not None else vertex_adjacency(V, F)
    n = len(V)
    d = np.full(n, np.inf)
    h = []
    for s in sources:
        d[s] = 0.0
        h.append((0.0, int(s)))
    heapq.heapify(h)
    while h:
        dv, v = heapq.heappop(h)
        if dv > d[v]:
            continue
        for k in range(ptr[v], ptr[v + 1]):
            u = dst[k]
            nd = dv + ww[k]
            if nd < d[u]:
                d[u] = nd
                heapq.heappush(h, (nd, int(u)))
    return d


def check_disk(V, F, name=""):
    """Assert the mesh is a consistently oriented manifold disk; return stats."""
    t = topology(V, F)
    ok = (t["components"] == 1 and t["manifold"] and t["oriented"]
          and t["boundary_loops"] == 1 and t["euler"] == 1 and t["V"] == t["V_file"])
    if not ok:
        raise AssertionError("%s is not an oriented manifold disk: %r" % (name, t))
    t["min_area"] = float(triangle_areas(V, F).min())
    return t


def cut_markers(V, F, k):
    """Markers of a cut disk (V, F; one boundary loop): k landmarks by farthest-point sampling
    from the boundary (geodesic, Dijkstra on edges), the center marker at the vertex farthest
    from both the boundary and the landmarks, and the boundary marker at the smallest index
    among the boundary vertices of largest z. Returns (landmarks, center, boundary, the center's
    distance to the boundary)."""
    adj = vertex_adjacency(V, F)
    loops = boundary_loops(F)
    assert len(loops) == 1
    loop = loops[0]
    dmin = dijkstra(V, F, loop, adj)
    d_bnd = dmin.copy()
    ext = []
    for _ in range(k):
        j = int(np.argmax(dmin))
        ext.append(j)
        dmin = np.minimum(dmin, dijkstra(V, F, [j], adj))
    d_lm = dijkstra(V, F, ext, adj)
    center = int(np.argmax(np.minimum(d_bnd, d_lm)))
    top = max(V[v, 2] for v in loop)
    boundary = int(min(v for v in loop if V[v, 2] == top))
    return ext, center, boundary, float(d_bnd[center])
