"""The simulated scene: point scatterers with radar cross sections, occluders, movers.

A :class:`World` holds static point scatterers as flat arrays (``x_m``, ``y_m``, ``z_m``
height above the ground, ``rcs_m2``, ``kind`` code, ``phase_rad`` the random phase fixed per
scatterer that makes the coherent sum speckle), occluding segments (building walls) and
:class:`Mover` objects. :class:`WorldBuilder` generates the parts from a seeded
``numpy.random.Generator``:

- distributed clutter (grass, road surface) has a backscatter coefficient sigma0 (m^2/m^2)
  at the reference grazing angle; a region of area A with density rho gets one point per
  tile of area 1/rho (stratified, ``area_m2`` and the tile centre ``tile_x_m``/``tile_y_m``
  kept) whose ``rcs_m2`` is the tile's mean sigma0 / rho; the simulator draws an exponential
  RCS (complex Gaussian amplitude) from it, so the mean power does not depend on the
  density and speckle is developed (:mod:`.clutter`);
- bushes and tree crowns are dense clusters, trunks, signs and car bodies strong points;
- walls and metal sheds are dense strong scatterers along segments, with dihedral corners,
  and their segments occlude: per beam, a scatterer whose line of sight from the radar
  crosses a segment gets no return (:meth:`World.visible`, vectorised ray-segment tests);
- trees (opaque trunk, foliage crown), parked cars and moving cars cast shadows through
  discs with a height interval and a two-way transmission (:func:`disc_transmission`).

The scenario worlds (``beynes``, ``campus``, ``semi_urban``, ``datmo``) are in
:mod:`impala_radar.simulator.scenes`; they return the world and their vehicle routes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["KIND", "VEGETATION_KINDS", "Mover", "Route", "World", "WorldBuilder", "car_discs", "distance_to_polyline",
           "disc_transmission"]

KIND = {"grass": 0, "bush": 1, "tree": 2, "wall": 3, "metal": 4, "road": 5, "car": 6,
        "sign": 7, "mover": 8, "point": 9, "trunk": 10}
VEGETATION_KINDS = (KIND["bush"], KIND["tree"])  # leaves: jitter between turns (.clutter)

# Shadowing discs (x, y, radius, z_bottom, z_top, two-way power transmission): a car body is
# three discs along its axis, a tree a trunk (opaque up to the crown) and a crown of foliage.
_CAR_DISCS = ((1.5, 0.9), (0.0, 0.9), (-1.5, 0.9))  # (x forward, radius): a car's body
CAR_HEIGHT_M = 1.5
CROWN_LOSS_DB = 12.0  # two-way foliage loss through a crown (about 1 dB/m one way at K band)
TRUNK_RADIUS_M = 0.25

# Car body: (x forward, y left, z) scatterers and RCS (bumpers, wheels, roof edge, sides).
_CAR_BODY = np.array([[2.2, 0.0, 0.5], [-2.2, 0.0, 0.6], [1.4, 0.85, 0.4], [1.4, -0.85, 0.4],
                      [-1.4, 0.85, 0.4], [-1.4, -0.85, 0.4], [0.0, 0.9, 1.0],
                      [0.0, -0.9, 1.0]])
_CAR_RCS_M2 = np.array([5.0, 5.0, 1.5, 1.5, 1.5, 1.5, 3.0, 3.0])


def _db(x_db: float) -> float:
    return 10.0 ** (x_db / 10.0)


@dataclass
class Route:
    """A vehicle route: waypoints and speed profile, or a stationary pose (DATMO)."""

    waypoints_xy_m: np.ndarray
    speed_mps: float | np.ndarray
    closed: bool = False
    stationary_pose: tuple[float, float, float] | None = None
    duration_s: float | None = None  # stationary routes only


@dataclass
class Mover:
    """A rigid vehicle following a polyline at constant speed from ``start_t_ns``.

    It exists (is seen and reported) only while on its path. Body scatterers are
    ``body_xyz_m`` (x forward) with ``rcs_m2`` and fixed random ``phase_rad``.
    """

    id: int
    waypoints_xy_m: np.ndarray
    speed_mps: float
    start_t_ns: int
    body_xyz_m: np.ndarray
    rcs_m2: np.ndarray
    phase_rad: np.ndarray

    def __post_init__(self) -> None:
        self.waypoints_xy_m = np.asarray(self.waypoints_xy_m, float)
        seg = np.diff(self.waypoints_xy_m, axis=0)
        self._s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
        self._heading = np.arctan2(seg[:, 1], seg[:, 0])
        self.end_t_ns = self.start_t_ns + int(round(self._s[-1] / self.speed_mps * 1e9))

    def state(self, t_ns):
        """(xy_m (..., 2), v_xy_mps (..., 2), heading_rad (...), active (...)) at ``t_ns``."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        s = (t_ns - self.start_t_ns) * 1e-9 * self.speed_mps
        active = (t_ns >= self.start_t_ns) & (t_ns <= self.end_t_ns)
        s = np.clip(s, 0.0, self._s[-1])
        x = np.interp(s, self._s, self.waypoints_xy_m[:, 0])
        y = np.interp(s, self._s, self.waypoints_xy_m[:, 1])
        i = np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, len(self._heading) - 1)
        h = self._heading[i]
        v = np.stack([np.cos(h), np.sin(h)], -1) * self.speed_mps
        return np.stack([x, y], -1), v, h, active

    def scatterers(self, t_ns):
        """Body scatterers at times ``t_ns`` (B,): xy (B, K, 2), v_xy (B, K, 2), active (B,)."""
        xy, v, h, active = self.state(t_ns)
        c, s = np.cos(h)[:, None], np.sin(h)[:, None]
        bx, by = self.body_xyz_m[:, 0], self.body_xyz_m[:, 1]
        pts = np.stack([xy[:, None, 0] + c * bx - s * by, xy[:, None, 1] + s * bx + c * by], -1)
        return pts, np.broadcast_to(v[:, None, :], pts.shape), active


@dataclass
class World:
    """Static scatterers (flat arrays), occluding segments (S, 4) and movers."""

    x_m: np.ndarray
    y_m: np.ndarray
    z_m: np.ndarray
    rcs_m2: np.ndarray
    kind: np.ndarray
    phase_rad: np.ndarray
    segments: np.ndarray
    movers: list[Mover] = field(default_factory=list)
    area_m2: np.ndarray | None = None  # > 0: a distributed-clutter tile of that area
    tile_x_m: np.ndarray | None = None  # the tile's centre (== x_m, y_m for discrete points)
    tile_y_m: np.ndarray | None = None
    discs: np.ndarray | None = None  # (D, 6) shadowing discs: x, y, r, z0, z1, transmission
    _tree: cKDTree | None = field(default=None, repr=False)
    _disc_tree: cKDTree | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        n = len(self.x_m)
        if self.area_m2 is None:
            self.area_m2 = np.zeros(n)
        if self.tile_x_m is None:
            self.tile_x_m, self.tile_y_m = np.asarray(self.x_m, float), np.asarray(self.y_m, float)
        if self.discs is None:
            self.discs = np.zeros((0, 6))

    def discs_near(self, center_xy_m, radius_m: float) -> np.ndarray:
        """Shadowing discs whose centre is within ``radius_m`` of ``center_xy_m``."""
        if len(self.discs) == 0:
            return self.discs
        if self._disc_tree is None:
            self._disc_tree = cKDTree(self.discs[:, :2])
        idx = self._disc_tree.query_ball_point(np.asarray(center_xy_m, float), radius_m)
        return self.discs[np.sort(np.asarray(idx, dtype=np.intp))]

    @property
    def xy_m(self) -> np.ndarray:
        return np.column_stack([self.x_m, self.y_m])

    def __len__(self) -> int:
        return len(self.x_m)

    def query(self, center_xy_m, radius_m: float) -> np.ndarray:
        """Sorted indices of the static scatterers within ``radius_m`` of ``center_xy_m``."""
        if self._tree is None:
            self._tree = cKDTree(self.xy_m)
        idx = self._tree.query_ball_point(np.asarray(center_xy_m, float), radius_m,
                                          return_sorted=True)
        return np.asarray(idx, dtype=np.intp)

    def segments_near(self, center_xy_m, radius_m: float) -> np.ndarray:
        """Occluding segments passing within ``radius_m`` of ``center_xy_m``."""
        if len(self.segments) == 0:
            return self.segments
        a, b = self.segments[:, :2], self.segments[:, 2:]
        d = b - a
        t = np.clip(np.einsum("ij,ij->i", np.asarray(center_xy_m) - a, d)
                    / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
        near = np.hypot(*(a + t[:, None] * d - center_xy_m).T) <= radius_m
        return self.segments[near]

    def visible(self, radar_xy_m, x_m, y_m, segments: np.ndarray | None = None,
                eps_m: float = 0.05) -> np.ndarray:
        """True where the line of sight radar -> scatterer crosses no occluding segment.

        ``radar_xy_m`` (..., 2) broadcasts against ``x_m``/``y_m``; a scatterer lying on a
        segment (a wall's own scatterers) is not hidden by it (ray parameter < 1 - eps/R).
        """
        # hand-written ray/segment test (shapely could, per pair; this is one compiled pass)
        seg = self.segments if segments is None else segments
        x_m, y_m = np.asarray(x_m, float), np.asarray(y_m, float)
        px = np.asarray(radar_xy_m, float)[..., 0]
        py = np.asarray(radar_xy_m, float)[..., 1]
        shape = np.broadcast_shapes(px.shape, x_m.shape)
        if len(seg) == 0:
            return np.ones(shape, bool)
        px, py = np.broadcast_to(px, shape).ravel(), np.broadcast_to(py, shape).ravel()
        qx, qy = np.broadcast_to(x_m, shape).ravel(), np.broadcast_to(y_m, shape).ravel()
        from .kernels import segments_clear  # numba: compiled (cached) at the first call, not at import

        out = segments_clear(np.ascontiguousarray(px), np.ascontiguousarray(py), np.ascontiguousarray(qx),
                             np.ascontiguousarray(qy), np.ascontiguousarray(seg, float), float(eps_m))
        return out.reshape(shape)


def car_discs(x_m, y_m, heading_rad) -> np.ndarray:
    """Shadowing discs (K, 6) of cars at (x, y, heading) (arrays of the same shape)."""
    x_m, y_m, h = (np.atleast_1d(np.asarray(a, float)) for a in (x_m, y_m, heading_rad))
    out = []
    for fwd, r in _CAR_DISCS:
        out.append(np.column_stack([x_m + fwd * np.cos(h), y_m + fwd * np.sin(h), np.full(len(h), r),
                                    np.zeros(len(h)), np.full(len(h), CAR_HEIGHT_M), np.zeros(len(h))]))
    return np.concatenate(out) if out else np.zeros((0, 6))


def disc_transmission(radar_xy_m, radar_z_m: float, x_m, y_m, z_m, discs: np.ndarray,
                      eps_m: float = 0.05) -> np.ndarray:
    """Two-way power transmission of the line of sight radar -> scatterer through ``discs``.

    A disc (x, y, r, z0, z1, T) shadows a scatterer when the ray passes within r of its
    centre at a height between z0 and z1, the centre's projection lying between the radar
    and the scatterer (so a car's or a crown's far side is shadowed by its own body, its
    near side is not); shadows multiply. ``radar_xy_m`` (..., 2) broadcasts against the
    scatterer arrays.
    """
    x_m, y_m = np.asarray(x_m, float), np.asarray(y_m, float)
    px = np.asarray(radar_xy_m, float)[..., 0]
    py = np.asarray(radar_xy_m, float)[..., 1]
    shape = np.broadcast_shapes(px.shape, x_m.shape)
    out = np.ones(int(np.prod(shape)))
    if len(discs) == 0:
        return out.reshape(shape)
    px, py = np.broadcast_to(px, shape).ravel(), np.broadcast_to(py, shape).ravel()
    qx, qy = np.broadcast_to(x_m, shape).ravel(), np.broadcast_to(y_m, shape).ravel()
    qz = np.broadcast_to(np.asarray(z_m, float), shape).ravel()
    from .kernels import discs_transmission  # numba: compiled (cached) at the first call, not at import

    out = discs_transmission(np.ascontiguousarray(px), np.ascontiguousarray(py), np.ascontiguousarray(qx),
                             np.ascontiguousarray(qy), np.ascontiguousarray(qz), float(radar_z_m),
                             np.ascontiguousarray(discs, float), float(eps_m))
    return out.reshape(shape)


class WorldBuilder:
    """Accumulates scatterers, occluders and movers drawn from one seeded generator."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._parts: list[tuple[np.ndarray, ...]] = []
        self._segments: list[np.ndarray] = []
        self._exclusions: list = []  # (kind, params): areas where no clutter grows
        self._discs: list[np.ndarray] = []  # shadowing discs (x, y, r, z0, z1, transmission)
        self.movers: list[Mover] = []

    # --- primitives -------------------------------------------------------------------
    def points(self, xy, z, rcs, kind: str, area_m2: float = 0.0, tile_xy=None) -> None:
        """Point scatterers; ``area_m2`` > 0 marks clutter tiles centred at ``tile_xy``."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        n = len(xy)
        tile = xy if tile_xy is None else np.asarray(tile_xy, float).reshape(-1, 2)
        self._parts.append((xy[:, 0], xy[:, 1], np.broadcast_to(z, (n,)).astype(float),
                            np.broadcast_to(rcs, (n,)).astype(float),
                            np.full(n, KIND[kind], np.uint8), self.rng.uniform(0, 2 * np.pi, n),
                            np.full(n, float(area_m2)), tile[:, 0], tile[:, 1]))

    def disc(self, x_m: float, y_m: float, r_m: float, z0_m: float, z1_m: float,
             transmission: float = 0.0) -> None:
        """A shadowing disc (two-way power ``transmission``, 0 = opaque); see :func:`disc_transmission`."""
        self._discs.append(np.array([[x_m, y_m, r_m, z0_m, z1_m, transmission]], float))

    def _tiles(self, lo, hi, density_pm2: float):
        """Stratified clutter: one uniform point per square tile of area 1 / density (tile
        centres, jittered points) over the box lo..hi."""
        side = 1.0 / math.sqrt(density_pm2)
        gx = np.arange(lo[0], hi[0], side) + 0.5 * side
        gy = np.arange(lo[1], hi[1], side) + 0.5 * side
        centre = np.stack(np.meshgrid(gx, gy, indexing="ij"), -1).reshape(-1, 2)
        return centre + self.rng.uniform(-0.5 * side, 0.5 * side, centre.shape), centre

    def _texture(self, n: int, spread: float = 0.6) -> np.ndarray:
        """Log-normal RCS texture of mean 1."""
        return np.exp(self.rng.normal(-0.5 * spread**2, spread, n))

    def clutter(self, rect, density_pm2: float, sigma0_db: float, kind: str = "grass",
                z_m=0.0) -> None:
        """Distributed clutter over the rectangle (x0, y0, x1, y1), outside exclusions.

        One point per tile of area 1 / density (stratified); ``rcs_m2`` holds the tile's mean
        RCS sigma0 / density, which the simulator turns into an exponential RCS with a
        uniform phase (a complex Gaussian amplitude), or splits near the radar, so the sum
        in a resolution cell is Rayleigh (developed speckle, :mod:`.clutter`). ``sigma0_db``
        is sigma0 at the reference grazing angle ``RadarParams.grazing_ref_deg``.
        """
        x0, y0, x1, y1 = rect
        xy, centre = self._tiles((x0, y0), (x1, y1), density_pm2)
        keep = ~self.excluded(xy)
        xy, centre = xy[keep], centre[keep]
        rcs = np.full(len(xy), _db(sigma0_db) / density_pm2)  # the tile's mean RCS
        self.points(xy, z_m, rcs, kind, 1.0 / density_pm2, centre)

    def excluded(self, xy: np.ndarray) -> np.ndarray:
        out = np.zeros(len(xy), bool)
        for what, p in self._exclusions:
            if what == "rect":
                out |= ((xy[:, 0] >= p[0]) & (xy[:, 0] <= p[2])
                        & (xy[:, 1] >= p[1]) & (xy[:, 1] <= p[3]))
            elif what == "disc":
                out |= np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) <= p[2]
            else:  # corridor: polyline p[0] of half-width p[1]
                out |= distance_to_polyline(xy, p[0]) <= p[1]
        return out

    def exclude_rect(self, rect) -> None:
        self._exclusions.append(("rect", tuple(rect)))

    def exclude_disc(self, x_m: float, y_m: float, r_m: float) -> None:
        self._exclusions.append(("disc", (x_m, y_m, r_m)))

    def road(self, polyline, width_m: float = 6.0, sigma0_db: float = -32.0,
             density_pm2: float = 0.3) -> None:
        """Asphalt (low return) along a polyline; no grass grows on it afterwards."""
        pl = np.asarray(polyline, float)
        xy, centre = self._tiles(pl.min(0) - width_m, pl.max(0) + width_m, density_pm2)
        keep = distance_to_polyline(xy, pl) <= width_m / 2
        xy, centre = xy[keep], centre[keep]
        self.points(xy, 0.0, np.full(len(xy), _db(sigma0_db) / density_pm2), "road",
                    1.0 / density_pm2, centre)
        self._exclusions.append(("corridor", (pl, width_m / 2 + 0.5)))

    def wall(self, p0, p1, rcs_per_m: float = 2.0, spacing_m: float = 0.25, z_m: float = 1.5,
             kind: str = "wall", occludes: bool = True) -> None:
        """Dense strong scatterers along a segment (jittered spacing); an occluder."""
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        length = float(np.hypot(*(p1 - p0)))
        n = max(2, int(length / spacing_m))
        f = (np.arange(n) + self.rng.uniform(0.2, 0.8, n)) / n
        self.points(p0 + f[:, None] * (p1 - p0), z_m,
                    rcs_per_m * length / n * self._texture(n, 0.8), kind)
        if occludes:
            self._segments.append(np.concatenate([p0, p1]))

    def building(self, x_m: float, y_m: float, w_m: float, h_m: float, angle_rad: float = 0.0,
                 metal: bool = False) -> None:
        """Rectangular building centred at (x, y): four walls + dihedral corners."""
        c, s = math.cos(angle_rad), math.sin(angle_rad)
        loc = np.array([[-w_m, -h_m], [w_m, -h_m], [w_m, h_m], [-w_m, h_m]]) / 2
        corners = np.column_stack([x_m + c * loc[:, 0] - s * loc[:, 1],
                                   y_m + s * loc[:, 0] + c * loc[:, 1]])
        kind, rcs_per_m, corner_rcs = ("metal", 8.0, 200.0) if metal else ("wall", 1.5, 30.0)
        for i in range(4):
            self.wall(corners[i], corners[(i + 1) % 4], rcs_per_m, kind=kind)
        self.points(corners, 2.0, corner_rcs * self._texture(4), kind)
        r = 0.5 * math.hypot(w_m, h_m) + 1.0
        self._exclusions.append(("disc", (x_m, y_m, r)) if abs(w_m - h_m) < 2 else
                                ("rect", (*(corners.min(0) - 0.5), *(corners.max(0) + 0.5))))

    def bush(self, x_m: float, y_m: float, radius_m: float, density_pm2: float = 4.0,
             sigma0_db: float = -8.0) -> None:
        n = max(3, self.rng.poisson(density_pm2 * math.pi * radius_m**2))
        r = radius_m * np.sqrt(self.rng.uniform(0, 1, n))
        a = self.rng.uniform(0, 2 * np.pi, n)
        rcs = _db(sigma0_db) / density_pm2 * self._texture(n, 0.8)
        self.points(np.column_stack([x_m + r * np.cos(a), y_m + r * np.sin(a)]),
                    self.rng.uniform(0.3, 1.8, n), rcs, "bush")

    def tree(self, x_m: float, y_m: float, crown_m: float = 3.0) -> None:
        """A trunk (strong point, opaque disc) and a crown cluster between 2 and 6 m high
        (a disc of foliage, ``CROWN_LOSS_DB`` two-way)."""
        self.points([x_m, y_m], 1.0, self.rng.uniform(0.5, 2.0), "trunk")
        self.disc(x_m, y_m, TRUNK_RADIUS_M, 0.0, 2.0, 0.0)
        self.disc(x_m, y_m, crown_m, 2.0, 6.0, 10.0 ** (-CROWN_LOSS_DB / 10.0))
        n = max(8, int(3.0 * math.pi * crown_m**2))
        r = crown_m * np.sqrt(self.rng.uniform(0, 1, n))
        a = self.rng.uniform(0, 2 * np.pi, n)
        self.points(np.column_stack([x_m + r * np.cos(a), y_m + r * np.sin(a)]),
                    self.rng.uniform(2.0, 6.0, n), _db(-8.0) / 3.0 * self._texture(n, 0.8),
                    "tree")
        self.exclude_disc(x_m, y_m, 0.5)

    def parked_car(self, x_m: float, y_m: float, heading_rad: float) -> None:
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        b = _CAR_BODY
        xy = np.column_stack([x_m + c * b[:, 0] - s * b[:, 1], y_m + s * b[:, 0] + c * b[:, 1]])
        self.points(xy, b[:, 2], _CAR_RCS_M2 * self._texture(len(b), 0.5), "car")
        self._discs.append(car_discs(x_m, y_m, heading_rad))

    def sign(self, x_m: float, y_m: float) -> None:
        """A road sign: a metal plate on a pole (strong, a few m^2 to 20 m^2)."""
        self.points([[x_m, y_m], [x_m, y_m]], [1.0, 2.2],
                    [0.5, self.rng.uniform(3.0, 20.0)], "sign")

    def car_mover(self, waypoints_xy_m, speed_mps: float, start_t_ns: int) -> Mover:
        m = Mover(len(self.movers) + 1, np.asarray(waypoints_xy_m, float), speed_mps,
                  int(start_t_ns), _CAR_BODY, _CAR_RCS_M2 * self._texture(len(_CAR_BODY), 0.5),
                  self.rng.uniform(0, 2 * np.pi, len(_CAR_BODY)))
        self.movers.append(m)
        return m

    def build(self) -> World:
        cols = [np.concatenate([p[i] for p in self._parts]) if self._parts else np.zeros(0)
                for i in range(9)]
        seg = np.array(self._segments, float).reshape(-1, 4)
        discs = np.concatenate(self._discs) if self._discs else np.zeros((0, 6))
        return World(cols[0], cols[1], cols[2], cols[3], cols[4].astype(np.uint8), cols[5],
                     seg, list(self.movers), cols[6], cols[7], cols[8], discs)


def distance_to_polyline(xy: np.ndarray, polyline: np.ndarray, chunk: int = 20000):
    """Distance of each point to the nearest segment of a polyline (vectorised)."""
    # hand-written (shapely could): one numpy pass over points x segments, no new dependency
    a, b = polyline[:-1], polyline[1:]
    d = b - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    out = np.empty(len(xy))
    for i in range(0, len(xy), chunk):
        p = xy[i:i + chunk, None, :] - a[None]
        t = np.clip(np.einsum("nij,ij->ni", p, d) / dd, 0.0, 1.0)
        out[i:i + chunk] = np.hypot(*np.moveaxis(p - t[..., None] * d, -1, 0)).min(axis=1)
    return out
