"""Scenario files: YAML descriptions of simulated missions (``graphs/scenarios/*.yaml``).

A scenario names a world builder of :mod:`impala_radar.simulator.scenes` and one of its routes,
a seed, a radar preset, optional duration/length limits, vehicle limits, radar options
(:class:`~impala_radar.simulator.spectra.RadarParams`) and proprioceptive sensor settings
(:func:`impala_radar.simulator.sensors.make_sensors`). Example::

    name: beynes
    world: beynes
    route: default
    seed: 2011
    preset: impala
    duration_s: null        # null: the whole route
    length_m: null
    speed_mps: 1.15         # optional: replaces the route's speed profile
    vehicle: {max_accel_mps2: 0.5}
    radar: {window: hann, noise_figure_db: 10.0}
    sensors: {odometer: {scale_error: 0.01}, gyro: {}, gps: {sigma_m: 0.02}}

Files are read with impala-flow's safe YAML loader (YAML 1.2 core schema, locations kept).
Every problem is one line ``file:line:col: ...`` naming the key, before anything is
simulated: an unknown key, preset, world or route, a radar option out of its range (a
gain or power that is not physical: ``antenna_gain_db`` <= 0 dBi, ``tx_power_dbm`` or
``eirp_dbm`` outside [-30, 60] / [-30, 90] dBm), and ``beams_per_turn`` (an optional
override of the preset's) that does not divide the turn into whole nanoseconds or leaves
a beam shorter than one modulation period. The seed drives both the world (first child of
``SeedSequence(seed)``) and the acquisition noise (second child), so a seed reproduces a mission bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow import YamlError, load_yaml, location
from impala_msgs import RadarConfig

from .presets import preset
from .scenes import SCENES
from .spectra import RadarParams
from .world import World

__all__ = ["Scenario", "ScenarioError", "load_scenario", "scenario_path", "SCENARIO_DIR"]

SCENARIO_DIR = Path(__file__).resolve().parents[3] / "graphs" / "scenarios"
_TOP_KEYS = {"name", "description", "world", "route", "seed", "preset", "duration_s",
             "length_m", "start_t_ns", "speed_mps", "vehicle", "radar", "sensors",
             "movers_rate_hz", "beams_per_turn"}
_VEHICLE_KEYS = {"max_curvature_1pm", "max_accel_mps2", "max_lateral_accel_mps2",
                 "rest_at_ends"}
_RADAR_KEYS = {f.name for f in dataclasses.fields(RadarParams)}
_SENSOR_KEYS = {"odometer", "gyro", "gps"}


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message is one line naming file and key."""


@dataclass
class Scenario:
    """Everything :func:`impala_radar.simulator.core.simulate` needs for one mission."""

    name: str
    path: Path | None
    seed: int
    world: World
    trajectory: Any  # impala_radar.simulator.vehicle.Trajectory
    config: RadarConfig
    params: RadarParams
    sensors: dict[str, Any]
    start_t_ns: int
    duration_ns: int
    movers_rate_hz: float = 10.0
    threads: int | None = None  # the simulator's threads (None: core.default_threads); same bits whatever

    def acquisition_rng(self) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(self.seed).spawn(2)[1])

    def simulate(self):
        """The mission's ``(t_ns, port, msg)`` stream (see :func:`simulate.simulate`)."""
        from .core import simulate

        return simulate(self.world, self.trajectory, self.config, self.acquisition_rng(),
                        self.start_t_ns, self.duration_ns, self.sensors, params=self.params,
                        movers_rate_hz=self.movers_rate_hz, threads=self.threads)


def scenario_path(name_or_path: str | Path) -> Path:
    """A scenario file: an existing path, or ``NAME`` in ``graphs/scenarios/NAME.yaml``."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    cand = SCENARIO_DIR / f"{name_or_path}.yaml"
    if cand.is_file():
        return cand
    names = sorted(f.stem for f in SCENARIO_DIR.glob("*.yaml"))
    raise ScenarioError(f"{name_or_path}: no such scenario file or name "
                        f"(valid names: {', '.join(names)})")


def _check(where: str, mapping: Any, allowed: set[str], label: str = "") -> dict:
    if mapping is None:
        return {}
    if not isinstance(mapping, dict):
        raise ScenarioError(f"{where}: {label or 'scenario'} must be a mapping, "
                            f"got {type(mapping).__name__}")
    for key in mapping:
        if key not in allowed:
            raise ScenarioError(f"{location(mapping, key, where)}: unknown key {label}{key!r} "
                                f"(valid: {', '.join(sorted(allowed))})")
    return mapping


#: physical ranges of the power budget (a typo such as a gain of -20 dBi is refused)
_POWER_RANGES = {"tx_power_dbm": (-30.0, 60.0), "eirp_dbm": (-30.0, 90.0), "antenna_gain_db": (0.0, 60.0)}


def _check_power(where: str, radar: Any) -> None:
    for key, (lo, hi) in _POWER_RANGES.items():
        v = radar.get(key) if isinstance(radar, dict) else None
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo < v <= hi if lo == 0.0 else lo <= v <= hi):
            what = f"> {lo:g} and <= {hi:g}" if lo == 0.0 else f"in [{lo:g}, {hi:g}]"
            raise ScenarioError(f"{location(radar, key, where, value=True)}: radar.{key} = {v!r} must be a "
                                f"number {what} (a gain or power that is not physical)")


def _check_beams(where: str, spec: Any, config: RadarConfig) -> None:
    n = spec.get("beams_per_turn")
    if n is None:
        return
    at = location(spec, "beams_per_turn", where, value=True)
    if isinstance(n, bool) or not isinstance(n, int) or n < 8:
        raise ScenarioError(f"{at}: beams_per_turn = {n!r} must be an integer >= 8")
    turn_ns = 1e9 / config.rotation_hz
    if abs(turn_ns - round(turn_ns)) > 1e-6 or round(turn_ns) % n:
        raise ScenarioError(f"{at}: beams_per_turn = {n} does not divide the turn of {turn_ns:.0f} ns "
                            f"({config.name} at {config.rotation_hz:g} Hz) into whole nanoseconds; "
                            f"divisors near it: {_near_divisors(int(round(turn_ns)), n)}")
    beam_s = 1.0 / (config.rotation_hz * n)
    if beam_s * config.modulation_hz < 1.0 - 1e-9:
        raise ScenarioError(f"{at}: beams_per_turn = {n} leaves {beam_s * 1e6:.1f} us per beam, shorter than "
                            f"one modulation period of {config.name} ({1e6 / config.modulation_hz:.1f} us)")
    config.beams_per_turn = n


def _near_divisors(total: int, n: int) -> str:
    below = next((k for k in range(n - 1, 7, -1) if total % k == 0), None)
    above = next((k for k in range(n + 1, 4 * n) if total % k == 0), None)
    return ", ".join(str(k) for k in (below, above) if k is not None)


def load_scenario(source: str | Path | dict, *, seed: int | None = None,
                  duration_s: float | None = None, length_m: float | None = None) -> Scenario:
    """Load, validate and build a scenario; ``seed``/``duration_s``/``length_m`` override."""
    from .sensors import make_sensors
    from .vehicle import Trajectory

    if isinstance(source, dict):
        path, where, spec = None, "<scenario>", source
    else:
        path = scenario_path(source)
        where = str(path)
        try:
            spec = load_yaml(path)
        except YamlError as e:
            raise ScenarioError(str(e)) from None
    spec = _check(where, spec, _TOP_KEYS)
    for key in ("world", "seed", "preset"):
        if key not in spec:
            raise ScenarioError(f"{location(spec, None, where)}: missing key {key!r}")
    vehicle = _check(where, spec.get("vehicle"), _VEHICLE_KEYS, "vehicle.")
    radar = _check(where, spec.get("radar"), _RADAR_KEYS, "radar.")
    sensors_spec = _check(where, spec.get("sensors"), _SENSOR_KEYS, "sensors.")
    builder = SCENES.get(spec["world"])
    if builder is None:
        raise ScenarioError(f"{location(spec, 'world', where, value=True)}: unknown world {spec['world']!r} "
                            f"(valid: {', '.join(sorted(SCENES))})")
    _check_power(where, radar)
    try:
        config = preset(spec["preset"])
    except (KeyError, ValueError) as e:
        raise ScenarioError(f"{location(spec, 'preset', where, value=True)}: {e.args[0] if e.args else e}") from None
    _check_beams(where, spec, config)
    try:
        params = RadarParams(**radar)
    except (ValueError, TypeError) as e:
        msg = str(e.args[0] if e.args else e)
        bad = next((k for k in radar if f"radar.{k} " in msg or f"'{k}'" in msg), None)
        raise ScenarioError(f"{location(radar, bad, where, value=True) if bad else location(spec, 'radar', where)}: "
                            f"{msg}") from None
    try:
        sensors = make_sensors(dict(sensors_spec))
    except (KeyError, ValueError, TypeError) as e:
        raise ScenarioError(f"{location(spec, 'sensors', where)}: {e.args[0] if e.args else e}") from None
    config.window = params.window  # the beams say how their spectra were weighted
    seed = int(spec["seed"] if seed is None else seed)
    world_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    world, routes = builder(world_rng)
    route_name = spec.get("route", "default")
    if route_name not in routes:
        raise ScenarioError(f"{location(spec, 'route', where, value=True)}: unknown route {route_name!r} for world "
                            f"{spec['world']!r} (valid: {', '.join(sorted(routes))})")
    route = routes[route_name]
    start = int(spec.get("start_t_ns", 0))
    duration_s = spec.get("duration_s") if duration_s is None else duration_s
    length_m = spec.get("length_m") if length_m is None else length_m
    if route.stationary_pose is not None:
        total_s = float(duration_s if duration_s is not None else route.duration_s)
        trajectory = Trajectory.stationary(*route.stationary_pose, total_s, start_t_ns=start)
    else:
        speed = spec.get("speed_mps", route.speed_mps)
        trajectory = Trajectory.from_waypoints(route.waypoints_xy_m, np.asarray(speed, float),
                                               start_t_ns=start, closed=route.closed, **vehicle)
        if duration_s is not None or length_m is not None:
            trajectory = trajectory.truncated(
                None if duration_s is None else int(round(float(duration_s) * 1e9)),
                None if length_m is None else float(length_m))
    return Scenario(str(spec.get("name", Path(where).stem)), path, seed, world, trajectory,
                    config, params, sensors, start, trajectory.end_ns - start,
                    float(spec.get("movers_rate_hz", 10.0)))
