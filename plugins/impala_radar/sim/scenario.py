"""Scenario files: YAML descriptions of simulated missions (``graphs/scenarios/*.yaml``).

A scenario names a world builder of :mod:`impala_radar.sim.scenes` and one of its routes,
a seed, a radar preset, optional duration/length limits, vehicle limits, radar options
(:class:`~impala_radar.sim.spectra.RadarParams`) and proprioceptive sensor settings
(:func:`impala_radar.sim.sensors.make_sensors`). Example::

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

Files are read with ``yaml.safe_load`` only. Unknown keys are errors naming the file and
the key. The seed drives both the world (first child of ``SeedSequence(seed)``) and the
acquisition noise (second child), so a seed reproduces a mission bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from impala_flow.msgs import RadarConfig

from .presets import preset
from .scenes import SCENES
from .spectra import RadarParams
from .world import World

__all__ = ["Scenario", "ScenarioError", "load_scenario", "scenario_path", "SCENARIO_DIR"]

SCENARIO_DIR = Path(__file__).resolve().parents[3] / "graphs" / "scenarios"
_TOP_KEYS = {"name", "description", "world", "route", "seed", "preset", "duration_s",
             "length_m", "start_t_ns", "speed_mps", "vehicle", "radar", "sensors",
             "movers_rate_hz"}
_VEHICLE_KEYS = {"max_curvature_1pm", "max_accel_mps2", "max_lateral_accel_mps2",
                 "rest_at_ends"}
_RADAR_KEYS = {f.name for f in dataclasses.fields(RadarParams)}
_SENSOR_KEYS = {"odometer", "gyro", "gps"}


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message is one line naming file and key."""


@dataclass
class Scenario:
    """Everything :func:`impala_radar.sim.simulate.simulate` needs for one mission."""

    name: str
    path: Path | None
    seed: int
    world: World
    trajectory: Any  # impala_radar.sim.vehicle.Trajectory
    config: RadarConfig
    params: RadarParams
    sensors: dict[str, Any]
    start_t_ns: int
    duration_ns: int
    movers_rate_hz: float = 10.0

    def acquisition_rng(self) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(self.seed).spawn(2)[1])

    def simulate(self):
        """The mission's ``(t_ns, port, msg)`` stream (see :func:`simulate.simulate`)."""
        from .simulate import simulate

        return simulate(self.world, self.trajectory, self.config, self.acquisition_rng(),
                        self.start_t_ns, self.duration_ns, self.sensors, params=self.params,
                        movers_rate_hz=self.movers_rate_hz)


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
            raise ScenarioError(f"{where}: unknown key {label}{key!r} "
                                f"(valid: {', '.join(sorted(allowed))})")
    return dict(mapping)


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
        with open(path, encoding="utf-8") as f:
            spec = yaml.safe_load(f)
    spec = _check(where, spec, _TOP_KEYS)
    for key in ("world", "seed", "preset"):
        if key not in spec:
            raise ScenarioError(f"{where}: missing key {key!r}")
    vehicle = _check(where, spec.get("vehicle"), _VEHICLE_KEYS, "vehicle.")
    radar = _check(where, spec.get("radar"), _RADAR_KEYS, "radar.")
    sensors_spec = _check(where, spec.get("sensors"), _SENSOR_KEYS, "sensors.")
    builder = SCENES.get(spec["world"])
    if builder is None:
        raise ScenarioError(f"{where}: unknown world {spec['world']!r} "
                            f"(valid: {', '.join(sorted(SCENES))})")
    try:
        config = preset(spec["preset"])
        sensors = make_sensors(sensors_spec)
        params = RadarParams(**radar)
        config.window = params.window  # the beams say how their spectra were weighted
    except (KeyError, ValueError, TypeError) as e:
        raise ScenarioError(f"{where}: {e.args[0] if e.args else e}") from None
    seed = int(spec["seed"] if seed is None else seed)
    world_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    world, routes = builder(world_rng)
    route_name = spec.get("route", "default")
    if route_name not in routes:
        raise ScenarioError(f"{where}: unknown route {route_name!r} for world "
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
