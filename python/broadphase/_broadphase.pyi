"""Type stub of the compiled core (broadphase._broadphase).

Use the ``broadphase`` package: it converts input and wraps these buffers
as numpy arrays.
"""

from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

class IntArray:
    """An int64 array owned by the module, read by numpy without a copy."""
    def __buffer__(self, flags: int) -> memoryview: ...

class PairChunks(Iterator[IntArray]):
    """Chunks of a snapshot of an index's pairs."""
    def __iter__(self) -> "PairChunks": ...
    def __next__(self) -> IntArray: ...
    def __len__(self) -> int: ...

def find_pairs(
    centers: Any,
    radii: Optional[Any],
    half_extents: Optional[Any],
    kinds: Optional[Any],
    sorted: bool,
    threads: int,
    groups: Optional[Any] = None,
    masks: Optional[Any] = None,
) -> IntArray: ...
def find_periodic_pairs(
    centers: Any,
    radii: Optional[Any],
    half_extents: Optional[Any],
    kinds: Optional[Any],
    box: Sequence[float],
    periodic: Sequence[bool],
    sorted: bool,
    groups: Optional[Any] = None,
    masks: Optional[Any] = None,
) -> Tuple[IntArray, IntArray]: ...
def ray_cast(
    centers: Any,
    radii: Optional[Any],
    half: Optional[Any],
    kinds: Optional[Any],
    groups: Optional[Any],
    masks: Optional[Any],
    origins: Any,
    directions: Any,
    tmax: Optional[Any],
    ray_masks: Optional[Any],
    all_hits: bool,
    threads: int,
    structure: str,
) -> Tuple[IntArray, ...]: ...
def find_pairs_between(
    centers: Any,
    radii: Optional[Any],
    half_extents: Optional[Any],
    kinds: Optional[Any],
    other_centers: Any,
    other_radii: Optional[Any],
    other_half_extents: Optional[Any],
    other_kinds: Optional[Any],
    threads: int,
    groups: Optional[Any] = None,
    masks: Optional[Any] = None,
    other_groups: Optional[Any] = None,
    other_masks: Optional[Any] = None,
) -> IntArray: ...
def structures() -> List[Tuple[str, str]]: ...
def scratch_bytes() -> int: ...
def set_scratch_limit(bytes: int) -> None: ...
def scratch_limit() -> int: ...
def knn(
    points: Any,
    queries: Optional[Any],
    k: int,
    box: Optional[Sequence[float]],
    exclude_self: bool,
    threads: int,
    d2_out: Any,
    index_out: Any,
) -> None: ...
def within(
    points: Any,
    queries: Optional[Any],
    r: float,
    box: Optional[Sequence[float]],
    exclude_self: bool,
    threads: int,
) -> Tuple[IntArray, IntArray, IntArray]: ...

class IndexCore:
    def __init__(
        self,
        centers: Any,
        radii: Optional[Any],
        half_extents: Optional[Any],
        kinds: Optional[Any],
        structure: str,
        threads: int,
        skin: float,
        spare_bytes: int,
        groups: Optional[Any] = None,
        masks: Optional[Any] = None,
    ) -> None: ...
    def size(self) -> int: ...
    def borrowing(self) -> bool: ...
    def structure(self) -> str: ...
    def ids(self) -> IntArray: ...
    def update_all(self, centers: Any, radii: Optional[Any], half_extents: Optional[Any]) -> None: ...
    def update_in_place(self, ids: Optional[Any]) -> None: ...
    def update_ids(
        self, ids: Any, centers: Any, radii: Optional[Any], half_extents: Optional[Any]
    ) -> None: ...
    def insert(
        self,
        centers: Any,
        radii: Optional[Any],
        half_extents: Optional[Any],
        kinds: Optional[Any],
        groups: Optional[Any] = None,
        masks: Optional[Any] = None,
    ) -> IntArray: ...
    def set_filters(self, ids: Optional[Any], groups: Any, masks: Any) -> None: ...
    def remove(self, ids: Any) -> None: ...
    def pairs(self, sorted: bool) -> IntArray: ...
    def count_pairs(self) -> int: ...
    def iter_pairs(self, chunk: int) -> PairChunks: ...
    def query(
        self, centers: Any, radii: Optional[Any], half_extents: Optional[Any], kinds: Optional[Any]
    ) -> IntArray: ...
    def query_box(self, lo: Sequence[float], hi: Sequence[float]) -> IntArray: ...
    def ray_cast(
        self,
        origins: Any,
        directions: Any,
        tmax: Optional[Any],
        ray_masks: Optional[Any],
        all_hits: bool,
        threads: int,
    ) -> Tuple[IntArray, ...]: ...
    def memory_bytes(self) -> int: ...
    def validate(self) -> None: ...

class NeighbourArray:
    """An int64 or float64 array of a neighbour list (numpy wraps it)."""

def neighbour_list(
    positions: Any,
    cell: Sequence[Sequence[float]],
    pbc: Sequence[bool],
    cutoff: float,
    cutoffs: Optional[Any],
    full: bool,
    self_interaction: bool,
    strict: bool,
    shifts: bool,
    distances: bool,
    vectors: bool,
    offsets: bool,
    threads: int,
) -> Dict[str, NeighbourArray]: ...
def neighbour_list_between(
    queries: Any,
    points: Any,
    cell: Sequence[Sequence[float]],
    pbc: Sequence[bool],
    cutoff: float,
    strict: bool,
    shifts: bool,
    distances: bool,
    vectors: bool,
    offsets: bool,
    threads: int,
) -> Dict[str, NeighbourArray]: ...

class MovingNeighbourList:
    """A neighbour list with a skin, reused over frames (moving_neighbours.hpp)."""

    def __init__(
        self,
        cell: Sequence[Sequence[float]],
        pbc: Sequence[bool],
        cutoff: float,
        cutoffs: Optional[Any],
        skin: float,
        full: bool,
        self_interaction: bool,
        strict: bool,
        shifts: bool,
        distances: bool,
        vectors: bool,
        offsets: bool,
        threads: int,
    ) -> None: ...
    def update(self, positions: Any) -> Dict[str, NeighbourArray]: ...
    def skin(self) -> float: ...
    def rebuilds(self) -> int: ...
    def candidates(self) -> int: ...
    def memory_bytes(self) -> int: ...
