"""shapespace: shape analysis with conformal geometry and optimal mass transport.

The functions mirror the command-line tool and call the same Rust code (the GIL is released
while they compute):

>>> import shapespace
>>> V, F = shapespace.read_mesh("datasets/faces/id00_happy.obj")
>>> uv, factors, report = shapespace.conformal_map(V, F)
>>> D, pairs = shapespace.pairwise(["datasets/faces/id00_happy.obj", "datasets/faces/id01_sad.obj"])
>>> coords, eigenvalues = shapespace.mds(D, dims=2)

Errors are raised as :class:`ShapespaceError` with the message the command-line tool prints
(a file's errors name the file).
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import ShapespaceError

__all__ = [
    "ShapespaceError",
    "read_mesh",
    "info",
    "conformal_map",
    "area_preserving_map",
    "ot",
    "distance",
    "pairwise",
    "shard_pairs",
    "mds",
    "PAIR_COLUMNS",
]

__version__ = _native.version()

#: The columns of the pairs table, as in the command's pairs.csv (``source`` and ``target`` are
#: the shapes' indices).
PAIR_COLUMNS = (
    "a",
    "b",
    "source",
    "target",
    "distance",
    "cost",
    "iterations",
    "max_mass_error",
    "seconds",
    "status",
    "evaluations",
    "dual_cost",
)

Mesh = Tuple[np.ndarray, np.ndarray]
Shape = Union[str, "os.PathLike[str]", Mesh]


def _mesh(V: Any, F: Any) -> Mesh:
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.asarray(F)
    if F.size and (not np.issubdtype(F.dtype, np.integer) or F.min() < 0 or F.max() > np.iinfo(np.uint32).max):
        raise ShapespaceError("F: expected non-negative integer vertex indices")
    return V, np.ascontiguousarray(F, dtype=np.uint32)


def _marker(value: Any, what: str) -> Optional[str]:
    """A marker as the command line writes it: a vertex index, ``x,y,z`` or ``auto``."""
    if value is None:
        return None
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    values = list(value)
    if len(values) == 3 and what == "center":
        return ",".join(repr(float(x)) for x in values)
    raise ShapespaceError(f"{what}: expected a vertex index, 'auto'" + (" or a point (x, y, z)" if what == "center" else ""))


def read_mesh(path: Union[str, "os.PathLike[str]"]) -> Mesh:
    """Reads a mesh file (OBJ, OFF, PLY): ``(V, F)``, V float64 of shape (n, 3), F uint32 (m, 3)."""
    return _native.read_mesh(os.fspath(path))


def info(V: Any, F: Any) -> Dict[str, Any]:
    """The mesh report of ``shapespace info``: counts, components, boundary loops, Euler
    characteristic, genus, manifoldness (``report``) and the mesh class (``classification``)."""
    return json.loads(_native.info(*_mesh(V, F)))


def conformal_map(
    V: Any,
    F: Any,
    center: Any = None,
    boundary: Any = None,
    method: str = "green",
    pole: str = "center",
    intrinsic_delaunay: bool = True,
    bff_fallback: bool = True,
) -> Tuple[np.ndarray, np.ndarray, Dict[str, Any]]:
    """The conformal map of a disk-type mesh onto the unit disk (``shapespace conformal``).

    ``center`` (a vertex index, a point (x, y, z) projected to the surface, or ``"auto"``) goes
    to 0 and the boundary vertex ``boundary`` (or ``"auto"``) to 1. ``method`` is ``"green"``
    (Green's function) or ``"bff"`` (boundary-first flattening). Returns ``(uv, factors,
    report)``: uv of shape (n, 2), the log conformal factor per vertex, and the report (method,
    markers, quality statistics, timings). Folds that survive the local repair send the
    Green's map to BFF, then to a region repair (the report says which); ``bff_fallback=False``
    gives the Green's-function construction alone and raises on its folds.
    """
    uv, factors, report = _native.conformal_map(
        *_mesh(V, F),
        _marker(center, "center"),
        _marker(boundary, "boundary"),
        method,
        pole,
        intrinsic_delaunay,
        bff_fallback,
    )
    return uv, factors, json.loads(report)


def area_preserving_map(
    V: Any,
    F: Any,
    center: Any = None,
    boundary: Any = None,
    domain: str = "disk",
    tolerance: float = 1e-6,
    fold_repair: bool = True,
) -> Tuple[np.ndarray, Dict[str, Any]]:
    """The area-preserving map by optimal transport (``shapespace param``) onto ``"disk"`` or
    ``"square"``: ``(uv, report)`` with the OT summary, timings, fold repair and distortion."""
    uv, report = _native.area_preserving_map(
        *_mesh(V, F), _marker(center, "center"), _marker(boundary, "boundary"), domain, tolerance, fold_repair
    )
    return uv, json.loads(report)


def ot(
    points: Any,
    masses: Any,
    domain: str = "disk",
    density_mesh: Optional[Tuple[Any, Any]] = None,
    densities: Any = None,
    tol: float = 1e-6,
    max_iterations: int = 100,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
    """Semi-discrete optimal transport from a source density to weighted points
    (``shapespace ot``).

    The source is the uniform ``"disk"`` or ``"square"``, or ``density_mesh = (vertices,
    faces)`` (planar: the first two columns of the vertices) with one density per face
    (default 1). Returns ``(heights, cell_masses, centroids, report)``; the report holds the
    cost, the dual cost, the iterations and the status.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    masses = np.ascontiguousarray(masses, dtype=np.float64)
    uv = faces = dens = None
    if density_mesh is not None:
        vertices, faces = _mesh(np.asarray(density_mesh[0], dtype=np.float64)[:, :2], density_mesh[1])
        uv = np.ascontiguousarray(vertices)
        if densities is not None:
            dens = np.ascontiguousarray(densities, dtype=np.float64)
    heights, cell_masses, centroids, report = _native.ot(
        points, masses, domain, uv, faces, dens, tol, max_iterations
    )
    return heights, cell_masses, centroids, json.loads(report)


def _settings(
    center: Any = None,
    boundary: Any = None,
    landmarks: Any = None,
    symmetrize: bool = False,
    tol: Optional[float] = None,
    max_iterations: Optional[int] = None,
    invariance: str = "fixed",
    target_points: Optional[int] = None,
    pair_time_limit: Optional[float] = None,
    domain: str = "auto",
    sphere_markers: Optional[Sequence[int]] = None,
    source_faces: Optional[int] = None,
) -> Dict[str, Any]:
    return {
        "center": _marker(center, "center"),
        "boundary": _marker(boundary, "boundary"),
        "landmarks": None if landmarks is None else os.fspath(landmarks),
        "symmetrize": bool(symmetrize),
        "tol": tol,
        "max_iterations": max_iterations,
        "invariance": invariance,
        "target_points": target_points,
        "pair_time_limit": pair_time_limit,
        "domain": domain,
        "sphere_markers": None if sphere_markers is None else [int(v) for v in sphere_markers],
        "source_faces": source_faces,
    }


class _Settings:
    """The settings as the Rust side reads them (attributes)."""

    def __init__(self, values: Dict[str, Any]):
        self.__dict__.update(values)


def _inputs(shapes: Sequence[Shape]) -> Tuple[List[str], Optional[List[Mesh]]]:
    """Paths, or names and meshes: all shapes are paths, or all are (V, F) pairs."""
    if isinstance(shapes, (str, os.PathLike)):
        raise ShapespaceError("shapes: expected a list of paths or of (V, F) pairs, got one path")
    shapes = list(shapes)
    is_path = [isinstance(s, (str, os.PathLike)) for s in shapes]
    if all(is_path):
        return [os.fspath(s) for s in shapes], None
    if any(is_path):
        raise ShapespaceError("shapes: give all shapes as paths or all as (V, F) pairs")
    meshes = [_mesh(*s) for s in shapes]
    return [f"shape{i}" for i in range(len(shapes))], meshes


def _prepare(shapes: Sequence[Shape], settings: Dict[str, Any]) -> Any:
    paths, meshes = _inputs(shapes)
    return _native.Prepared(paths, meshes, _Settings(settings))


def _table(records: List[tuple]) -> Any:
    """The pairs table: a pandas DataFrame when pandas is installed, else a dict of arrays."""
    columns = {name: [r[k] for r in records] for k, name in enumerate(PAIR_COLUMNS)}
    arrays: Dict[str, np.ndarray] = {}
    for name, values in columns.items():
        if name in ("a", "b", "status"):
            arrays[name] = np.array(values, dtype=object)
        elif name in ("source", "target", "iterations", "evaluations"):
            arrays[name] = np.array(values, dtype=np.int64)
        else:
            arrays[name] = np.array(values, dtype=np.float64)
    try:
        import pandas
    except ImportError:
        return arrays
    return pandas.DataFrame(arrays, columns=list(PAIR_COLUMNS))


def distance(a: Shape, b: Shape, **settings: Any) -> Tuple[float, Dict[str, Any]]:
    """The conformal Wasserstein distance from ``a`` to ``b`` (paths or ``(V, F)`` pairs), as
    ``shapespace distances a b`` computes it (the same markers: marker files beside the
    files, else automatic markers shared by meshes with the same faces).

    Keyword settings as in :func:`pairwise` (``symmetrize=True``: the mean of both directions).
    Returns ``(distance, record)``; the record holds the pair's cost, dual cost, iterations,
    mass error, seconds and status (NaN distance when the pair failed: see the status). A file
    that cannot be used raises :class:`ShapespaceError` naming it.
    """
    prepared = _prepare([a, b], _settings(**settings))
    _raise_failed_inputs(prepared)
    records = prepared.pairs(None)
    D, _ = _native.matrix_of_pairs(prepared.ok, [(r[2], r[3], r[4]) for r in records], bool(settings.get("symmetrize")))
    return float(D[0, 1]), dict(zip(PAIR_COLUMNS, records[0]))


def _raise_failed_inputs(prepared: Any) -> None:
    failed = [i for i in json.loads(prepared.inputs) if not i["ok"]]
    if failed:
        raise ShapespaceError("; ".join(i["error"] or f"{i['path']}: failed" for i in failed))


def shard_pairs(n: int, index: int, count: int, symmetrize: bool = False) -> List[Tuple[int, int]]:
    """The directed pairs (source, target) of shard ``index`` of ``count`` (1-based) over n
    shapes, as ``shapespace distances --shard index/count`` computes them."""
    return _native.shard_pairs(n, symmetrize, index, count)


_WORKER_PREPARED: Dict[Any, Any] = {}


def _worker_tile(run: Tuple[str, List[str], List[Optional[bytes]], Dict[str, Any]], tile: List[Tuple[int, int]]) -> List[tuple]:
    """A Dask task: the records of a tile of pairs. ``run`` is the scattered run (a token, the
    names, every shape's prepared data, the settings); each worker process decodes the shapes
    once per run and keeps them for its later tiles."""
    token, names, shapes, settings = run
    prepared = _WORKER_PREPARED.get(token)
    if prepared is None:
        prepared = _native.Prepared.from_shape_bytes(names, shapes, _Settings(settings))
        _WORKER_PREPARED.clear()
        _WORKER_PREPARED[token] = prepared
    return prepared.pairs(tile)


def pairwise(
    shapes: Sequence[Shape],
    *,
    client: Any = None,
    tiles: Optional[int] = None,
    center: Any = None,
    boundary: Any = None,
    landmarks: Any = None,
    symmetrize: bool = False,
    tol: Optional[float] = None,
    max_iterations: Optional[int] = None,
    invariance: str = "fixed",
    target_points: Optional[int] = None,
    pair_time_limit: Optional[float] = None,
    domain: str = "auto",
    sphere_markers: Optional[Sequence[int]] = None,
    source_faces: Optional[int] = None,
) -> Tuple[np.ndarray, Any]:
    """All pairwise distances among ``shapes`` (paths or ``(V, F)`` pairs), as
    ``shapespace distances`` computes them: the same matrix, bit for bit.

    Without ``client`` the pairs run in this process on all cores (rayon). With a
    ``dask.distributed`` ``client``, the shapes are prepared once here (all cores), their data
    (disk maps, densities, target points) scattered once to every worker, and the pairs cut
    into ``tiles`` tiles (default: 4 per worker thread) of consecutive pairs, as ``--shard``
    cuts them, one task each. A task that is lost is run again with the same result.

    Settings as the command's flags: ``center``/``boundary`` markers for every shape,
    ``landmarks`` (a marker file for all), ``symmetrize``, ``tol``, ``max_iterations``,
    ``invariance`` (``"fixed"`` or ``"rotation"``), ``target_points``, ``source_faces``, ``pair_time_limit``
    (seconds), ``domain`` (``"auto"``: closed meshes on the sphere, others on the disk;
    ``"disk"``, ``"sphere"``) and ``sphere_markers`` (three vertices sent to 0, 1, ∞ of every
    closed mesh; without them each sphere pair is minimized over rotations; sphere shapes run
    without ``client`` only). Returns ``(D, pairs)``: the n × n matrix (NaN where a pair or shape failed) and
    the table of directed pairs (columns :data:`PAIR_COLUMNS`; a pandas DataFrame when pandas is
    installed, else a dict of numpy arrays). A file that fails leaves its row and column NaN
    and its pairs name the failure, as in the command.
    """
    settings = _settings(
        center,
        boundary,
        landmarks,
        symmetrize,
        tol,
        max_iterations,
        invariance,
        target_points,
        pair_time_limit,
        domain,
        sphere_markers,
        source_faces,
    )
    if client is None:
        prepared = _prepare(shapes, settings)
        records = prepared.pairs(None)
        ok = prepared.ok
    else:
        import uuid

        # every shape is prepared once, here (all cores), and its data scattered once
        prepared = _prepare(shapes, settings)
        ok = prepared.ok
        n = len(ok)
        if tiles is None:
            threads = sum(client.nthreads().values()) or 1
            tiles = 4 * threads
        total = n * (n - 1) // 2 * (2 if symmetrize else 1)
        count = max(1, min(int(tiles), total))
        run = (uuid.uuid4().hex, prepared.names, prepared.shape_bytes(), settings)
        [run_future] = client.scatter([run], broadcast=True)
        futures = [
            client.submit(_worker_tile, run_future, _native.shard_pairs(n, symmetrize, k, count), pure=False)
            for k in range(1, count + 1)
        ]
        records = [r for tile in client.gather(futures) for r in tile]
    D, _ = _native.matrix_of_pairs(ok, [(r[2], r[3], r[4]) for r in records], bool(symmetrize))
    return D, _table(records)


def mds(D: Any, dims: int = 2) -> Tuple[np.ndarray, np.ndarray]:
    """Classical MDS of a distance matrix (``shapespace mds``): ``(coordinates, eigenvalues)``,
    coordinates of shape (n, dims) and all n eigenvalues in non-increasing order. Missing (NaN)
    distances are an error."""
    coordinates, eigenvalues, _ = _native.mds(np.ascontiguousarray(D, dtype=np.float64), dims)
    return coordinates, eigenvalues
