"""Scenario worlds shaped after the seeds' missions (RADAR.md, "Scenarios").

Each builder takes a seeded ``numpy.random.Generator`` and returns ``(world, routes)``,
``routes`` a dict of :class:`~impala_radar.simulator.world.Route` (waypoints and speed profile,
or a stationary pose). Coordinates in metres, x east, y north.

- ``beynes``: natural area (seed 1 §4.1, Beynes April 2011): grass fields, high bushes, a
  tree plantation, hedgerow trees, a few metal sheds and a road; a 713 m route at 1.15 m/s.
- ``campus``: buildings, roads, parked cars, trees, signs and a sports ground (seed 2);
  routes ``open`` (~1 000 m, 0-25 km/h, no loop) and ``loop`` (~700 m around the sports
  ground, closed).
- ``semi_urban``: houses, walls, hedges, trees, parked cars, four roundabouts; a 2.5 km
  route at ~30 km/h (seed 1 §4.2).
- ``datmo``: static radar by a crossroads; a car at 20 km/h, later one at 50 km/h, a convoy
  of three cars, then two crossing cars (seed 1 §4.3).
- ``urban``: a city centre shaped like the Oxford Radar RobotCar sample (sim-to-real):
  streets 12 m wide between building facades (with lanes and open plots), kerbs, parked
  cars, street trees and hedges,
  lamp posts, a few moving cars; a ~1.2 km route with five turns at 5-10 m/s.
"""

from __future__ import annotations

import numpy as np

from .world import Route, World, WorldBuilder, distance_to_polyline

__all__ = ["beynes", "campus", "semi_urban", "datmo", "urban", "SCENES"]

_MARGIN_M = 110.0  # clutter around the route: the radar's reach
_KMH = 1.0 / 3.6


def _polyline_length(p: np.ndarray) -> float:
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def _away_from(rng, n, rect, route_xy, clearance_m):
    """``n`` uniform points in ``rect`` at least ``clearance_m`` from the route polyline."""
    x0, y0, x1, y1 = rect
    xy = np.column_stack([rng.uniform(x0, x1, 3 * n), rng.uniform(y0, y1, 3 * n)])
    return xy[distance_to_polyline(xy, route_xy) > clearance_m][:n]


def _extent(route_xy: np.ndarray, margin: float = _MARGIN_M):
    lo, hi = route_xy.min(0) - margin, route_xy.max(0) + margin
    return (lo[0], lo[1], hi[0], hi[1])


def beynes(rng: np.random.Generator, extent=None) -> tuple[World, dict[str, Route]]:
    """Natural area: grass, bushes, a tree plantation, metal sheds, a road; 713 m route."""
    way = np.array([[0, 0], [180, 0], [200, 20], [200, 110], [180, 130], [40, 130],
                    [20, 110], [20, 60], [40, 45], [120, 45], [140, 65], [140, 90]], float)
    way *= 713.0 / _polyline_length(way)
    rect = extent or _extent(way)
    b = WorldBuilder(rng)
    b.road([[rect[0], -30.0], [rect[2], -30.0]], width_m=6.0)
    sheds = [(250.0, 65.0, 25.0, 12.0, 0.1), (100.0, -50.0, 20.0, 10.0, 0.0),
             (-45.0, 95.0, 30.0, 15.0, -0.3)]
    for x, y, w, h, a in sheds:
        b.building(x, y, w, h, a, metal=True)
    for x in np.arange(65.0, 125.0, 5.0):  # plantation, 12 x 8 trees on a 5 m grid
        for y in np.arange(72.0, 112.0, 5.0):
            b.tree(x + rng.normal(0, 0.2), y + rng.normal(0, 0.2), crown_m=1.8)
    for x in np.arange(rect[0] + 5, rect[2], 9.0):  # hedgerow along the road
        if rng.uniform() < 0.8:
            b.tree(x, -37.0 + rng.normal(0, 0.5), crown_m=rng.uniform(2.0, 3.5))
    for x, y in _away_from(rng, 90, rect, way, 6.0):
        b.bush(x, y, rng.uniform(1.0, 3.5))
    for x, y in _away_from(rng, 25, rect, way, 8.0):
        b.tree(x, y, crown_m=rng.uniform(2.0, 4.0))
    b.clutter(rect, 0.5, -22.0)
    # 1.15 m/s on the legs, 1.0 m/s at the corners: ~662 s (turns) over the 713 m
    mids = 0.5 * (way[1:] + way[:-1])
    dense = np.empty((2 * len(way) - 1, 2))
    dense[0::2], dense[1::2] = way, mids
    speed = np.where(np.arange(len(dense)) % 2 == 1, 1.15, 1.0)
    return b.build(), {"default": Route(dense, speed)}


def _campus_layout():
    xs, ys = [-120.0, 0.0, 230.0, 460.0], [-140.0, 0.0, 120.0, 270.0]
    return xs, ys


def campus(rng: np.random.Generator) -> tuple[World, dict[str, Route]]:
    """Campus: a road grid, buildings, parking lots, trees, signs, a sports ground."""
    xs, ys = _campus_layout()
    loop = np.array([[0, 0], [230, 0], [230, 120], [0, 120]], float)
    open_way = np.array([[460, 270], [350, 270], [230, 270], [120, 270], [0, 270], [0, 200],
                         [0, 120], [120, 120], [230, 120], [230, 40], [230, -60]], float)
    open_speed = np.array([3.0, 6.9, 4.0, 6.9, 3.0, 5.0, 3.0, 6.9, 3.5, 6.0, 6.9])
    rect = (-230.0, -250.0, 570.0, 380.0)
    b = WorldBuilder(rng)
    for x in xs:
        b.road([[x, rect[1]], [x, rect[3]]], width_m=7.0)
    for y in ys:
        b.road([[rect[0], y], [rect[2], y]], width_m=7.0)
    # sports ground: a fence (weak, transparent), floodlight masts, a stand
    for p0, p1 in [((15, 12), (215, 12)), ((215, 12), (215, 108)), ((215, 108), (15, 108)),
                   ((15, 108), (15, 12))]:
        b.wall(p0, p1, rcs_per_m=0.2, spacing_m=0.5, z_m=1.0, occludes=False)
    b.points([[18, 15], [212, 15], [212, 105], [18, 105]], 6.0, 15.0, "sign")
    b.building(115.0, 100.0, 40.0, 6.0)
    b.exclude_rect((15, 12, 215, 108))
    b.clutter((15, 12, 215, 108), 0.4, -25.0)  # the pitch, mown grass
    # building blocks: (cx, cy, w, h, metal) with >= 12 m setback from road centres
    blocks = [(290, 60, 40, 30, False), (400, 75, 50, 20, False), (60, 200, 70, 35, False),
              (170, 215, 40, 45, False), (300, 200, 60, 40, False), (410, 220, 45, 40, True),
              (80, -70, 90, 40, False), (330, -80, 70, 50, False), (-60, 60, 50, 60, False),
              (-60, 200, 55, 70, True), (520, 60, 40, 60, False), (520, 200, 45, 50, False),
              (-60, -70, 60, 50, False), (520, -70, 50, 50, False)]
    for cx, cy, w, h, metal in blocks:
        b.building(cx, cy, w, h, metal=metal)
    for row_y in (22.0, 30.0):  # parking lot east of the sports ground
        for x in np.arange(250.0, 445.0, 2.6):
            if rng.uniform() < 0.7:
                b.parked_car(x, row_y + rng.normal(0, 0.1), np.pi / 2 + rng.normal(0, 0.05))
    for x in np.arange(30.0, 440.0, 2.6):  # street parking along y = 270
        if rng.uniform() < 0.3:
            b.parked_car(x, 275.5, 0.0)
    for x in xs:
        for y in ys:
            for dx, dy in ((6, 6), (-6, -6)):
                b.sign(x + dx, y + dy)
    for y in ys:  # street trees
        for x in np.arange(rect[0], rect[2], 12.0):
            if rng.uniform() < 0.6 and min(abs(x - xx) for xx in xs) > 10:
                b.tree(x, y - 7.0, crown_m=rng.uniform(2.0, 3.0))
    for x, y in _away_from(rng, 60, rect, open_way, 9.0):
        b.bush(x, y, rng.uniform(0.8, 2.0))
    b.clutter(rect, 0.3, -24.0)  # lawns
    return b.build(), {"open": Route(open_way, open_speed),
                       "loop": Route(loop, 5.0, closed=True)}


def _roundabout_arc(c, r, a0_deg, a1_deg, step_deg=30.0):
    """Counter-clockwise waypoints around a roundabout (driving on the right)."""
    a = np.radians(np.arange(a0_deg, a1_deg + 1e-9, step_deg))
    return np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])


def semi_urban(rng: np.random.Generator) -> tuple[World, dict[str, Route]]:
    """Suburb: a 2.5 km street loop with houses, hedges, trees and four roundabouts."""
    r_drive = 14.0
    rb = [(400.0, 0.0), (800.0, 0.0), (800.0, 450.0), (400.0, 450.0)]
    way = np.vstack([[[0.0, 0.0], [360.0, 0.0]], _roundabout_arc(rb[0], r_drive, 180, 360),
                     [[760.0, 0.0]], _roundabout_arc(rb[1], r_drive, 180, 450),
                     [[800.0, 410.0]], _roundabout_arc(rb[2], r_drive, 270, 540),
                     [[440.0, 450.0]], _roundabout_arc(rb[3], r_drive, 0, 180),
                     [[40.0, 450.0], [0.0, 420.0], [0.0, 40.0], [20.0, 10.0]]])
    rect = _extent(way)
    b = WorldBuilder(rng)
    streets = [[(rect[0], 0.0), (rect[2], 0.0)], [(800.0, rect[1]), (800.0, rect[3])],
               [(rect[0], 450.0), (rect[2], 450.0)], [(0.0, rect[1]), (0.0, rect[3])],
               [(400.0, rect[1]), (400.0, 30.0)], [(400.0, 420.0), (400.0, rect[3])]]
    for s in streets:
        b.road(s, width_m=7.0)
    for c in rb:  # central islands: curb ring, bushes, a tree, entry signs
        ring = _roundabout_arc(c, 9.0, 0, 350, 10.0)
        b.points(ring, 0.15, 0.05, "road")
        b.bush(c[0], c[1], 5.0, density_pm2=2.0)
        b.tree(c[0], c[1], crown_m=3.0)
        b.exclude_disc(c[0], c[1], 18.0)
        for k in range(4):
            a = np.pi / 4 + k * np.pi / 2
            b.sign(c[0] + 20 * np.cos(a), c[1] + 20 * np.sin(a))
    for s in streets[:4]:  # houses, garden hedges, trees and parked cars along the loop
        p0, p1 = np.array(s[0]), np.array(s[1])
        d = (p1 - p0) / np.hypot(*(p1 - p0))
        n = np.array([-d[1], d[0]])
        for t in np.arange(0.0, np.hypot(*(p1 - p0)), 22.0):
            base = p0 + t * d
            if any(np.hypot(*(base - np.array(c))) < 40 for c in rb + [(0, 0), (0, 450)]):
                continue
            for side in (-1.0, 1.0):
                u = rng.uniform()
                if u < 0.55:
                    cxy = base + side * n * rng.uniform(16.0, 22.0) + d * rng.normal(0, 2)
                    ang = np.arctan2(d[1], d[0]) + rng.normal(0, 0.05)
                    b.building(*cxy, rng.uniform(8.0, 12.0), rng.uniform(7.0, 10.0), ang)
                elif u < 0.75:
                    h0 = base + side * n * 8.0
                    for k in range(5):
                        b.bush(*(h0 + d * (k * 2.5 - 5.0)), 1.2, density_pm2=3.0)
                elif u < 0.9:
                    b.tree(*(base + side * n * 7.5), crown_m=rng.uniform(2.0, 3.5))
                if rng.uniform() < 0.25:
                    car = base + side * n * 5.0
                    b.parked_car(*car, np.arctan2(d[1], d[0]))
    for cx, cy, w, h in [(200, 225, 60, 30), (600, 225, 50, 40), (400, 300, 30, 30)]:
        b.building(cx, cy, w, h, metal=True)
    for x, y in _away_from(rng, 40, (60, 60, 740, 390), way, 30.0):
        b.tree(x, y, crown_m=rng.uniform(2.5, 4.0))
    b.clutter(rect, 0.25, -22.0)
    return b.build(), {"default": Route(way, 30.0 * _KMH)}


def datmo(rng: np.random.Generator) -> tuple[World, dict[str, Route]]:
    """Static radar at a crossroads; movers: 20 km/h, then 50 km/h, a convoy, a crossing."""
    rect = (-120.0, -120.0, 120.0, 120.0)
    b = WorldBuilder(rng)
    b.road([[rect[0], 25.0], [rect[2], 25.0]], width_m=7.0)
    b.road([[35.0, rect[1]], [35.0, rect[3]]], width_m=7.0)
    for cx, cy, w, h, metal in [(-40, 65, 20, 12, False), (75, 75, 15, 15, True),
                                (-60, -45, 25, 15, False), (80, -50, 12, 30, False)]:
        b.building(cx, cy, w, h, metal=metal)
    for x in np.arange(-110.0, 110.0, 15.0):
        if abs(x - 35.0) > 10:
            b.tree(x + rng.normal(0, 1), 34.0, crown_m=rng.uniform(2.0, 3.0))
    for x in np.arange(-75.0, -45.0, 2.6):
        b.parked_car(x, 45.0, np.pi / 2)
    for dx, dy in ((6, 6), (-6, -6), (6, -6), (-6, 6)):
        b.sign(35.0 + dx, 25.0 + dy)
    b.clutter(rect, 0.5, -22.0)
    east, west, north = 23.25, 26.75, 33.25
    s = 1_000_000_000
    b.car_mover([[-130, east], [130, east]], 20 * _KMH, 2 * s)
    b.car_mover([[130, west], [-130, west]], 50 * _KMH, 52 * s)
    for k in range(3):  # convoy, 15 m apart
        b.car_mover([[-130, east], [130, east]], 30 * _KMH, 74 * s + int(k * 15 / (30 * _KMH) * s))
    b.car_mover([[-130, east], [130, east]], 30 * _KMH, 112 * s)
    t_cross = (north + 130) / (30 * _KMH) - (east + 100) / (30 * _KMH)
    b.car_mover([[north, -100], [north, 150]], 30 * _KMH, 112 * s + int(t_cross * s))
    route = Route(np.zeros((1, 2)), 0.0, stationary_pose=(0.0, 0.0, np.pi / 2),
                  duration_s=145.0)
    return b.build(), {"default": route}


def _street_side(b: WorldBuilder, rng, p0, p1, side: float, half_road_m: float) -> None:
    """One side of a street from p0 to p1: kerb, parked cars, trees or hedges, lamp posts,
    then a continuous row of facades (gaps for side streets are left by the caller)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.hypot(*(p1 - p0)))
    d = (p1 - p0) / length
    n = np.array([-d[1], d[0]]) * side
    heading = float(np.arctan2(d[1], d[0]))
    t = np.arange(0.0, length, 0.5)
    kerb = p0 + t[:, None] * d + (half_road_m * n)[None, :]
    b.points(kerb, 0.12, 0.05, "road")  # a granite kerb: weak, continuous, 12 cm high
    for s in np.arange(3.0, length - 3.0, 5.5):  # parked cars along the kerb
        if rng.uniform() < 0.35:
            b.parked_car(*(p0 + s * d + (half_road_m - 1.1) * n), heading + rng.normal(0, 0.03))
    for s in np.arange(6.0, length, 11.0):  # pavement: street trees or hedges
        u = rng.uniform()
        where = p0 + (s + rng.normal(0, 0.5)) * d + (half_road_m + 1.6) * n
        if u < 0.35:
            b.tree(*where, crown_m=rng.uniform(1.8, 3.0))
        elif u < 0.5:
            for k in range(3):
                b.bush(*(where + d * (k * 1.8 - 1.8)), 0.9, density_pm2=3.0)
    for s in np.arange(12.0, length, 26.0):  # lamp posts: a metal pole, the lantern at 6 m
        post = p0 + s * d + (half_road_m + 0.6) * n
        b.points([post, post], [1.0, 6.0], [1.0, rng.uniform(2.0, 6.0)], "sign")
    s = 0.0
    while s < length - 6.0:  # facades 10-30 m wide, set back 4-10 m, with lanes and open plots
        w = min(rng.uniform(10.0, 30.0), length - s)
        if rng.uniform() < 0.25:  # an open plot (a square, a car park): a few cars and trees
            for _ in range(rng.integers(0, 4)):
                b.parked_car(*(p0 + (s + rng.uniform(0, w)) * d + (half_road_m + rng.uniform(6, 20)) * n),
                             heading + np.pi / 2 + rng.normal(0, 0.1))
            for _ in range(rng.integers(0, 3)):
                b.tree(*(p0 + (s + rng.uniform(0, w)) * d + (half_road_m + rng.uniform(6, 25)) * n),
                       crown_m=rng.uniform(2.0, 3.5))
        else:
            depth = rng.uniform(10.0, 18.0)
            setback = half_road_m + rng.uniform(4.0, 10.0)
            c = p0 + (s + w / 2) * d + (setback + depth / 2) * n
            b.building(*c, w, depth, heading + rng.normal(0, 0.03), metal=rng.uniform() < 0.1)
        s += w + rng.uniform(1.0, 8.0)


def urban(rng: np.random.Generator) -> tuple[World, dict[str, Route]]:
    """City centre for sim-to-real (the Oxford sample's kind of street): blocks of facades."""
    half_road = 6.0  # 12 m between kerbs
    # the route along the street centrelines: five turns, ~1.2 km
    centre = np.array([[0, 0], [260, 0], [260, 180], [120, 180], [120, 330], [-80, 330], [-80, 120]], float)
    streets = [((-140, 0), (330, 0)), ((260, -60), (260, 240)), ((60, 180), (330, 180)),
               ((120, 120), (120, 400)), ((-150, 330), (190, 330)), ((-80, 60), (-80, 400))]
    b = WorldBuilder(rng)
    junctions = [np.array(p, float) for p in centre[1:]] + [np.array([120.0, 0.0]), np.array([-80.0, 0.0])]
    for p0, p1 in streets:
        p0, p1 = np.array(p0, float), np.array(p1, float)
        b.road([p0, p1], width_m=2 * half_road, sigma0_db=-30.0)
        length = float(np.hypot(*(p1 - p0)))
        d = (p1 - p0) / length
        # cut the street into stretches between junctions (side streets open the facades)
        along = {float((j - p0) @ d): abs(float(d[0] * (j - p0)[1] - d[1] * (j - p0)[0])) for j in junctions}
        cuts = sorted({0.0, length} | {a for a, off in along.items() if off < 1.0 and 0.0 < a < length})
        for a0, a1 in zip(cuts[:-1], cuts[1:], strict=True):
            lo, hi = a0 + (half_road + 3.0 if a0 > 0 else 0.0), a1 - (half_road + 3.0 if a1 < cuts[-1] else 0.0)
            if hi - lo < 8.0:
                continue
            for side in (-1.0, 1.0):
                _street_side(b, rng, p0 + lo * d, p0 + hi * d, side, half_road)
    b.clutter(_extent(centre, 80.0), 0.3, -26.0, kind="grass")  # courtyards, pavements
    # a few moving cars: oncoming and same-direction traffic on the route's streets
    s = 1_000_000_000
    b.car_mover([[330, -1.8], [-140, -1.8]], 9.0, 2 * s)
    b.car_mover([[-140, 1.8], [330, 1.8]], 7.0, 0)
    b.car_mover([[261.8, -60], [261.8, 240]], 8.0, 20 * s)
    b.car_mover([[190, 331.8], [-150, 331.8]], 10.0, 60 * s)
    b.car_mover([[-81.8, 400], [-81.8, 60]], 8.0, 95 * s)
    way = centre
    # speeds: 9 m/s on the straights, 5 m/s through the turns
    mids = 0.5 * (way[1:] + way[:-1])
    dense = np.empty((2 * len(way) - 1, 2))
    dense[0::2], dense[1::2] = way, mids
    speed = np.where(np.arange(len(dense)) % 2 == 1, 9.0, 5.0)
    return b.build(), {"default": Route(dense, speed)}


SCENES = {"beynes": beynes, "campus": campus, "semi_urban": semi_urban, "datmo": datmo, "urban": urban}
