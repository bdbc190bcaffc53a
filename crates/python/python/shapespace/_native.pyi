"""Type stubs of the Rust extension module (use the functions of ``shapespace`` instead)."""

from typing import Any, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

class ShapespaceError(Exception): ...

def version() -> str: ...
def read_mesh(path: str) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]: ...
def info(v: npt.NDArray[np.float64], f: npt.NDArray[np.uint32]) -> str: ...
def conformal_map(
    v: npt.NDArray[np.float64],
    f: npt.NDArray[np.uint32],
    center: Optional[str],
    boundary: Optional[str],
    method: str,
    pole: str,
    intrinsic_delaunay: bool,
    bff_fallback: bool,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], str]: ...
def area_preserving_map(
    v: npt.NDArray[np.float64],
    f: npt.NDArray[np.uint32],
    center: Optional[str],
    boundary: Optional[str],
    domain: str,
    tolerance: float,
    fold_repair: bool,
) -> Tuple[npt.NDArray[np.float64], str]: ...
def ot(
    points: npt.NDArray[np.float64],
    masses: npt.NDArray[np.float64],
    domain: str,
    density_uv: Optional[npt.NDArray[np.float64]],
    density_faces: Optional[npt.NDArray[np.uint32]],
    densities: Optional[npt.NDArray[np.float64]],
    tol: float,
    max_iterations: int,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], str]: ...

Record = Tuple[str, str, int, int, float, float, int, float, float, str, int, float]

class Prepared:
    def __init__(
        self,
        paths: Sequence[str],
        meshes: Optional[Sequence[Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]]],
        settings: Any,
    ) -> None: ...
    @property
    def names(self) -> List[str]: ...
    @property
    def inputs(self) -> str: ...
    @property
    def marker_warnings(self) -> List[str]: ...
    @property
    def ok(self) -> List[bool]: ...
    def pairs(self, pairs: Optional[Sequence[Tuple[int, int]]] = None) -> List[Record]: ...
    def shape_bytes(self) -> List[Optional[bytes]]: ...
    @staticmethod
    def from_shape_bytes(names: Sequence[str], shapes: Sequence[Optional[bytes]], settings: Any) -> "Prepared": ...

def matrix_of_pairs(
    ok: Sequence[bool], pairs: Sequence[Tuple[int, int, float]], symmetrize: bool
) -> Tuple[npt.NDArray[np.float64], List[float]]: ...
def shard_pairs(n: int, symmetrize: bool, index: int, count: int) -> List[Tuple[int, int]]: ...
def mds(d: npt.NDArray[np.float64], dims: int) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], str]: ...
