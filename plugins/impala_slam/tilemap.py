"""The global radar map of R-SLAM: square tiles created on demand, updated by eq. (6).

Map cell ``(ix, iy)`` (integers, any sign) is centred at ``(ix * cell_m, iy * cell_m)`` in
the map frame. Tiles of ``tile_cells`` x ``tile_cells`` cells live in a dict keyed by tile
index, so memory grows with the area mapped, never with the mission's bounding box.

Each tile keeps two float32 layers: the sum of ``alpha(d_i) A_i`` and its normaliser, the
sum of ``alpha(d_i)`` (R-SLAM's default: the running weighted mean) or the number of
panoramics that covered each cell; the map value is their ratio. With
``total_normaliser`` the value is the sum divided by ``images``, the total number of
panoramics merged (eq. 6 as the seed writes it: N is the number of images, so a cell seen
in every image outweighs one seen once); the per-cell layer then only marks the support.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from impala_flow.msgs import Grid

__all__ = ["TileMap", "alpha_weight", "warp_grid_to_map"]


def alpha_weight(distance_m: np.ndarray, aperture_rad: float, resolution_m: float,
                 range_min_m: float, range_max_m: float) -> np.ndarray:
    """alpha(d) of eq. (6): 1 / (1 + d * aperture / resolution), 0 outside [range_min, range_max].

    The antenna's cross-range footprint ``d * aperture`` grows with the distance ``d`` while
    the range resolution stays fixed, so one image cell far away mixes more of the scene:
    it is trusted less, in proportion to that footprint once it exceeds the resolution.
    """
    a = 1.0 / (1.0 + distance_m * (aperture_rad / resolution_m))
    return np.where((distance_m >= range_min_m) & (distance_m <= range_max_m), a, 0.0).astype(np.float32)


def warp_grid_to_map(grid: Grid, pose_xyt: tuple[float, float, float], ix0: int, iy0: int,
                     nx: int, ny: int, cell_m: float, border: float = np.nan,
                     data: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """Resample ``grid`` (vehicle frame, radar at its origin) placed at ``pose_xyt`` onto the
    map cells ``ix0 .. ix0+nx-1`` x ``iy0 .. iy0+ny-1`` (bilinear); ``border`` outside it.
    ``data`` replaces the grid's values; ``out`` (float32 ny x nx, a view of rows of a larger
    array too) receives the result instead of a new array."""
    x, y, th = pose_xyt
    c, s = math.cos(th), math.sin(th)
    k = cell_m / grid.cell_m
    dx, dy = ix0 * cell_m - x, iy0 * cell_m - y
    # map cell (col, row) -> vehicle frame (u, v) = R(-theta) (X - x, Y - y) -> grid pixel
    mat = np.array([
        [k * c, k * s, (c * dx + s * dy - grid.origin_x_m) / grid.cell_m],
        [-k * s, k * c, (-s * dx + c * dy - grid.origin_y_m) / grid.cell_m],
    ])
    src = np.asarray(grid.data if data is None else data, dtype=np.float32)
    res = cv2.warpAffine(src, mat, (nx, ny), out, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=float(border))
    if out is not None and res is not out and not np.shares_memory(res, out):  # OpenCV wrote elsewhere
        out[...] = res
        return out
    return res


class TileMap:
    """Global map M of eq. (6) in tiles of ``tile_m`` metres created on demand."""

    def __init__(self, cell_m: float, tile_m: float = 64.0, total_normaliser: bool = False) -> None:
        self.cell_m = float(cell_m)
        self.total_normaliser = total_normaliser
        self.images = 0  # panoramics merged (the N of eq. 6 with total_normaliser)
        self.tile_cells = max(8, int(round(tile_m / cell_m)))
        self.weighted_sum: dict[tuple[int, int], np.ndarray] = {}  # sum_i alpha(d_i) A_i
        self.count: dict[tuple[int, int], np.ndarray] = {}  # normaliser: sum of alpha, or N
        self.dropped_tiles = 0  # tiles forgotten by :meth:`bound`

    # --- geometry ------------------------------------------------------------------
    def index_of(self, x_m: float, y_m: float) -> tuple[int, int]:
        """Map cell containing the point (x_m, y_m)."""
        return int(math.floor(x_m / self.cell_m + 0.5)), int(math.floor(y_m / self.cell_m + 0.5))

    def _tiles(self, ix0: int, iy0: int, nx: int, ny: int):
        n = self.tile_cells
        for ty in range(iy0 // n, (iy0 + ny - 1) // n + 1):
            for tx in range(ix0 // n, (ix0 + nx - 1) // n + 1):
                # overlap of the window with tile (tx, ty), in window and in tile coordinates
                x0, x1 = max(ix0, tx * n), min(ix0 + nx, (tx + 1) * n)
                y0, y1 = max(iy0, ty * n), min(iy0 + ny, (ty + 1) * n)
                win = (slice(y0 - iy0, y1 - iy0), slice(x0 - ix0, x1 - ix0))
                tile = (slice(y0 - ty * n, y1 - ty * n), slice(x0 - tx * n, x1 - tx * n))
                yield (tx, ty), win, tile

    @property
    def n_tiles(self) -> int:
        return len(self.count)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.weighted_sum.values()) + sum(a.nbytes for a in self.count.values())

    def bound(self, max_bytes: int, x_m: float, y_m: float) -> int:
        """Drop the tiles farthest from (x_m, y_m) (their centres) until the map holds at most
        ``max_bytes``; returns how many were dropped (also counted in ``dropped_tiles``). A
        dropped place is mapped anew when revisited, as if never seen."""
        per_tile = 2 * 4 * self.tile_cells * self.tile_cells  # two float32 layers
        excess = len(self.count) - max(0, max_bytes // per_tile)
        if excess <= 0:
            return 0
        scale = self.tile_cells * self.cell_m
        centre = 0.5 * (self.tile_cells - 1) * self.cell_m  # cell (ix, iy) is centred at (ix, iy) * cell_m
        keys = sorted(self.count, key=lambda k: math.hypot(k[0] * scale + centre - x_m, k[1] * scale + centre - y_m))
        for key in keys[len(keys) - excess:]:
            del self.count[key], self.weighted_sum[key]
        self.dropped_tiles += excess
        return excess

    @property
    def empty(self) -> bool:
        return not self.count

    # --- eq. (6) -----------------------------------------------------------------------
    def add(self, ix0: int, iy0: int, weighted_amplitude: np.ndarray, covered: np.ndarray) -> None:
        """Accumulate alpha(d) A over a window starting at map cell (ix0, iy0); ``covered``
        is what the panoramic adds to each cell's normaliser: a bool mask (N, the number of
        panoramics that saw the cell) or the weights alpha(d) themselves (sum of alpha).
        Only the cells where ``covered`` > 0 are merged (``weighted_amplitude`` is not read
        elsewhere: it may be NaN there)."""
        ny, nx = weighted_amplitude.shape
        n = self.tile_cells
        for key, win, tile in self._tiles(ix0, iy0, nx, ny):
            cov = covered[win]
            seen = cov > 0
            if not seen.any():
                continue
            if key not in self.count:
                self.weighted_sum[key] = np.zeros((n, n), np.float32)
                self.count[key] = np.zeros((n, n), np.float32)
            ws = self.weighted_sum[key][tile]
            np.add(ws, weighted_amplitude[win], out=ws, where=seen)  # cells not covered may hold NaN
            cnt = self.count[key][tile]
            np.add(cnt, cov, out=cnt, casting="unsafe")

    def add_with(self, ix0: int, iy0: int, nx: int, ny: int,
                 merge: Callable[[tuple[slice, slice], np.ndarray, np.ndarray], bool],
                 run: Callable[[Callable, list], list] | None = None) -> None:
        """Accumulate a window starting at map cell (ix0, iy0) through ``merge(win, ws, count)``,
        called once per tile the window overlaps: it adds the window's part ``win`` (slices of
        the window) into the tile's two layers (views of ``ws``, the sum of alpha A, and
        ``count``, its normaliser) and returns whether it merged any cell; a tile created for
        it is dropped when it did not (as :meth:`add` creates only the tiles it covers).
        ``run(fn, items)`` (default: in turn) may run the merges on several threads: each
        writes its own tile."""
        n = self.tile_cells
        parts, created = [], []
        for key, win, tile in self._tiles(ix0, iy0, nx, ny):
            if key not in self.count:
                self.weighted_sum[key] = np.zeros((n, n), np.float32)
                self.count[key] = np.zeros((n, n), np.float32)
                created.append(key)
            parts.append((key, win, tile))

        def one(part: tuple) -> bool:
            key, win, tile = part
            return merge(win, self.weighted_sum[key][tile], self.count[key][tile])

        merged = run(one, parts) if run is not None else [one(part) for part in parts]
        touched = {key for (key, _, _), hit in zip(parts, merged, strict=True) if hit}
        for key in created:
            if key not in touched:
                del self.weighted_sum[key], self.count[key]

    def crop(self, ix0: int, iy0: int, nx: int, ny: int) -> np.ndarray:
        """M(x, y) = sum_i alpha(d_i) A_i(x, y) / normaliser over a window (eq. 6); 0 where unmapped."""
        return self.crop_with_support(ix0, iy0, nx, ny)[0]

    def crop_with_support(self, ix0: int, iy0: int, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
        """(M over the window, float32 1 where mapped / 0 where never seen)."""
        out = np.zeros((ny, nx), np.float32)
        support = np.zeros((ny, nx), np.float32)
        for key, win, tile in self._tiles(ix0, iy0, nx, ny):
            cnt = self.count.get(key)
            if cnt is None:
                continue
            c = cnt[tile]
            if self.total_normaliser:
                np.multiply(self.weighted_sum[key][tile], np.float32(1.0 / max(1, self.images)), out=out[win])
            else:
                np.divide(self.weighted_sum[key][tile], c, out=out[win], where=c > 0)
            support[win] = c > 0
        return out, support

    def crop_with(self, ix0: int, iy0: int, nx: int, ny: int,
                  fill: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], None],
                  ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`crop_with_support` (the weighted mean: not with ``total_normaliser``) through
        ``fill(ws, count, out, support)``, called once per tile the window overlaps with views
        of the tile's two layers and of the window's two outputs (zero before the call)."""
        assert not self.total_normaliser
        out = np.zeros((ny, nx), np.float32)
        support = np.zeros((ny, nx), np.float32)
        for key, win, tile in self._tiles(ix0, iy0, nx, ny):
            cnt = self.count.get(key)
            if cnt is not None:
                fill(self.weighted_sum[key][tile], cnt[tile], out[win], support[win])
        return out, support

    def bounds(self) -> tuple[int, int, int, int]:
        """(ix0, iy0, nx, ny) of the tiles' bounding box."""
        n = self.tile_cells
        txs = [k[0] for k in self.count]
        tys = [k[1] for k in self.count]
        return min(txs) * n, min(tys) * n, (max(txs) - min(txs) + 1) * n, (max(tys) - min(tys) + 1) * n

    def to_grid(self, frame: str = "map") -> Grid:
        """The whole map as one :class:`Grid` (its tiles' bounding box)."""
        ix0, iy0, nx, ny = self.bounds()
        return Grid(self.crop(ix0, iy0, nx, ny), self.cell_m, ix0 * self.cell_m, iy0 * self.cell_m, frame)
