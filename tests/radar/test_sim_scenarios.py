"""Scenario files, seeds and the merged, time-ordered acquisition stream."""

import hashlib

import numpy as np
import pytest

import impala_msgs
from impala_radar.simulator.scenario import SCENARIO_DIR, ScenarioError, load_scenario


def _digest(items) -> str:
    """Hash of every timestamp, port and array/number of every message."""
    h = hashlib.sha256()

    def feed(x):
        if isinstance(x, np.ndarray):
            h.update(str((x.dtype, x.shape)).encode())
            h.update(np.ascontiguousarray(x).tobytes())
        elif hasattr(x, "__dataclass_fields__"):
            for name in x.__dataclass_fields__:
                feed(getattr(x, name))
        else:
            h.update(repr(x).encode())

    for t, port, msg in items:
        h.update(f"{t}:{port}".encode())
        feed(msg)
    return h.hexdigest()


def _world_digest(world) -> str:
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (
        world.x_m, world.y_m, world.z_m, world.rcs_m2, world.kind, world.phase_rad,
        world.segments))).hexdigest()


def test_same_seed_same_mission_different_seed_different_world():
    a = load_scenario("datmo", duration_s=2.5)
    items = list(a.simulate())
    again = list(load_scenario("datmo", duration_s=2.5).simulate())
    assert _digest(items) == _digest(again)
    other = load_scenario("datmo", duration_s=2.5, seed=a.seed + 1)
    assert _world_digest(other.world) != _world_digest(a.world)
    assert _digest(list(other.simulate())) != _digest(items)


@pytest.mark.parametrize("name", ["datmo", "campus-loop"])  # roof (two ramps, movers), sawtooth (one ramp)
def test_the_mission_does_not_depend_on_the_thread_count(name):
    """The turn's blocks, echo physics and ramps run on threads and are joined in a fixed order:
    the same bits with 1, 2 or 3 threads."""
    sc = load_scenario(name, duration_s=1.5)
    digests = []
    for threads in (1, 2, 3):
        sc.threads = threads
        digests.append(_digest(sc.simulate()))
    assert digests[1] == digests[0] and digests[2] == digests[0]


def test_runs_handed_to_whichever_thread_is_free_come_back_in_order():
    """RadarSimulator._map_chunks gives each run to the first free thread (the caller included), and
    joins the results in run order, however the threads are delayed."""
    import time

    from impala_radar.simulator.core import RadarSimulator

    sc = load_scenario("datmo", duration_s=1.0)
    sim = RadarSimulator(sc.world, sc.config, sc.params, threads=2)
    rng = np.random.default_rng(3)
    delays = rng.uniform(0.0, 0.004, 12)

    def fn(run):
        time.sleep(float(delays[run.start // 5]))
        return [list(run)]

    out = sim._map_chunks(fn, range(0, 60, 5), min_len=1, per_thread=6)
    assert [x for r in out for x in r] == list(range(0, 60, 5))
    assert len(out) == 12  # 2 threads x 6 runs, of one item each


def test_stream_is_time_ordered_and_complete():
    s = load_scenario("datmo", duration_s=2.5)
    items = list(s.simulate())
    t = np.array([i[0] for i in items])
    assert np.all(np.diff(t) >= 0) and t.dtype.kind == "i"
    ports = {p for _, p, _ in items}
    assert ports == {"beams", "movers", "gps"}
    beams = [m for _, p, m in items if p == "beams"]
    assert len(beams) == 900  # 2.5 s at 360 beams/s
    assert all(isinstance(b, impala_msgs.RadarBeam) and b.up.dtype == np.float32 for b in beams)
    assert beams[400].turn == 1 and beams[400].index == 40
    movers = [m for _, p, m in items if p == "movers"]
    assert len(movers) == 25 and len(movers[-1].ids) == 1  # the 20 km/h car from t = 2 s
    assert np.hypot(*movers[-1].v_xy_mps[0]) == pytest.approx(20 / 3.6)


@pytest.mark.parametrize("name", sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml")))
def test_every_scenario_file_loads_and_runs_short(name):
    s = load_scenario(name, duration_s=0.05)
    assert s.duration_ns <= 50_000_000
    items = list(s.simulate())
    # one beam every 1 / (rotation rate x beams per turn) from t = 0: IMPALA 360/s -> 18,
    # Navtech 4 Hz x 400 -> 80
    period_ns = 1e9 / (s.config.rotation_hz * s.config.beams_per_turn)
    assert sum(p == "beams" for _, p, _ in items) == int(np.floor(50_000_000 / period_ns + 1e-9))


def test_scenario_shapes_follow_radar_md():
    beynes = load_scenario("beynes")
    assert beynes.trajectory.length_m == pytest.approx(713, rel=0.02)
    assert beynes.duration_ns / 1e9 == pytest.approx(662, rel=0.03)  # ~662 turns
    loop = load_scenario("campus-loop")
    p0, p1 = loop.trajectory.pose(loop.trajectory.start_ns), loop.trajectory.pose(
        loop.trajectory.end_ns)
    assert loop.trajectory.length_m == pytest.approx(700, rel=0.05)
    assert np.hypot(*(p1[:2] - p0[:2])) < 1.0  # the loop closes


def test_unknown_keys_are_one_line_errors(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("world: beynes\nseed: 1\npreset: impala\nspeeed: 3\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml:4:1: unknown key 'speeed'") as e:
        load_scenario(f)
    assert "\n" not in str(e.value)
    f.write_text("world: beynes\nseed: 1\npreset: impala\nradar: {windw: hann}\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml:4:9: unknown key radar\.'windw'"):
        load_scenario(f)
    f.write_text("world: mars\nseed: 1\npreset: impala\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml:1:8: unknown world 'mars'"):
        load_scenario(f)
    with pytest.raises(ScenarioError, match="valid names: .*beynes"):
        load_scenario("no-such-scenario")


@pytest.mark.parametrize(("text", "where", "what"), [
    # an unknown preset, on the line of its value
    ("world: beynes\nseed: 1\npreset: lidar\n", "3:9", "unknown radar preset 'lidar'"),
    # powers and gains that are not physical
    ("world: beynes\nseed: 1\npreset: k2pi\nradar:\n  antenna_gain_db: -20\n", "5:20",
     "radar.antenna_gain_db = -20 must be a number > 0 and <= 60"),
    ("world: beynes\nseed: 1\npreset: k2pi\nradar: {tx_power_dbm: 200.0}\n", "4:23",
     "radar.tx_power_dbm = 200.0 must be a number in [-30, 60]"),
    # a radar option out of its range, on its own line
    ("world: beynes\nseed: 1\npreset: impala\nradar:\n  window: hann\n  temperature_k: -3\n", "6:18",
     "radar.temperature_k = -3"),
    # 4 Hz: 250 000 000 ns per turn; 360 beams would be 694 444.4 ns each
    ("world: urban\nseed: 1\npreset: navtech\nbeams_per_turn: 360\n", "4:17",
     "beams_per_turn = 360 does not divide the turn of 250000000 ns"),
    # IMPALA turns in 1 s with 3 kHz ramp pairs: 4 000 beams leave 250 us, shorter than 333 us
    ("world: beynes\nseed: 1\npreset: impala\nbeams_per_turn: 4000\n", "4:17",
     "shorter than one modulation period"),
])
def test_bad_scenario_values_are_located_one_line_errors(tmp_path, text, where, what):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(f)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{f}:{where}: ") and what in msg, msg


def test_a_beam_count_that_divides_the_turn_is_used():
    s = load_scenario({"world": "urban", "seed": 1, "preset": "navtech", "beams_per_turn": 200})
    assert s.config.beams_per_turn == 200  # 250 000 000 ns / 200 = 1 250 000 ns >= 1 / 1600 Hz
