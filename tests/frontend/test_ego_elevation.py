"""radar.EgoVelocity on ground clutter seen from the radar's height (issue 9 item 6).

A ground scatterer at slant range R below a radar h high has the radial speed
V cos(theta) cos(el), cos(el) = sqrt(1 - (h / R)^2) (RADAR.md item 3). Ignoring it biases the
speed low at short range; with it the fit is unbiased in every range band, and the reported
standard deviation covers the actual error. Scenes: ground clutter only (z = 0) in an annulus
of the band around the vehicle, simulated, paired and fitted by the components a user runs.
"""

import math

import numpy as np
import pytest

from impala_flow.testing import CollectingSink, ScriptedSource, run_components
from impala_radar.ego_velocity.component import EgoVelocity
from impala_radar.ego_velocity.core import elevation_factor
from impala_radar.pairer.component import FuzzyPairer
from impala_radar.simulator.core import simulate
from impala_radar.simulator.presets import IMPALA
from impala_radar.simulator.vehicle import Trajectory
from impala_radar.simulator.world import WorldBuilder

V_MPS = 5.0
SEEDS = (11, 12, 13, 14)
BANDS = ((3.0, 10.0), (10.0, 30.0), (30.0, 90.0))


def _turn_beams(seed: int, band: tuple[float, float]):
    """One turn at 5 m/s along x; ground clutter (sigma0 -15 dB) in the annulus ``band``
    around the vehicle's position at mid-turn."""
    rng = np.random.default_rng(seed)
    lo, hi = band
    n = int(0.3 * math.pi * (hi * hi - lo * lo))
    r = np.sqrt(rng.uniform(lo * lo, hi * hi, n))
    a = rng.uniform(0, 2 * math.pi, n)
    b = WorldBuilder(rng)
    b.points(np.column_stack([2.5 + r * np.cos(a), r * np.sin(a)]), 0.0, 10 ** -1.5 / 0.3 * rng.exponential(1, n),
             "grass")
    traj = Trajectory.from_waypoints(np.array([[0.0, 0.0], [200.0, 0.0]]), V_MPS, rest_at_ends=False)
    return [(t, "beams", bm) for t, port, bm in simulate(b.build(), traj, IMPALA, rng, duration_ns=1_000_000_000)
            if port == "beams"]


def _speeds(band, **params):
    out = []
    for seed in SEEDS:
        speeds, dets = CollectingSink("speed"), CollectingSink("dets")
        ego = EgoVelocity("ego", **params)
        run_components(ScriptedSource("src", _turn_beams(seed, band)), FuzzyPairer("pairer"), ego, speeds, dets,
                       connections=["src.beams -> pairer.beams", "pairer.detections -> ego.detections",
                                    "ego.speed -> speed.x", "pairer.detections -> dets.x"])
        (s,) = speeds.values()
        (d,) = dets.values()
        out.append((s.speed_mps, s.std_mps, d))
    return out


@pytest.fixture(scope="module")
def fits():
    return {band: {"ground": _speeds(band, radar_height_m=IMPALA.height_m),
                   "ignored": _speeds(band, radar_height_m=0.0)} for band in BANDS}


@pytest.mark.parametrize("band", BANDS, ids=lambda b: f"{b[0]:.0f}-{b[1]:.0f}m")
def test_fit_is_unbiased_in_every_range_band(fits, band):
    est = np.array([s for s, _, _ in fits[band]["ground"]])
    bias = float(np.mean(est - V_MPS))
    print(f"\n{band}: errors {np.round(est - V_MPS, 4)} m/s, bias {bias:+.4f}")
    assert abs(bias) < 0.01


def test_ignoring_the_elevation_biases_the_near_band_by_the_formula(fits):
    """Without the factor the fit returns about V mean(cos(el)) over the detections: the bias
    the formula predicts from their slant ranges (4.86 m/s for 5 at 3-10 m in the issue)."""
    band = BANDS[0]
    for (s, _, d), (s_ok, _, _) in zip(fits[band]["ignored"], fits[band]["ground"], strict=True):
        predicted = V_MPS * float(np.nanmean(elevation_factor(d.range_m, IMPALA.height_m)))
        assert s == pytest.approx(predicted, abs=0.03)
        assert s < s_ok - 0.05  # 2-3 % low, where the corrected fit is within 1 cm/s


def test_reported_std_covers_the_error(fits):
    """Normalised errors over every band and seed: none beyond 3 sigma, and their spread is
    close to a standard normal's (the std neither hides the error nor inflates it 3-fold)."""
    z = np.array([(s - V_MPS) / std for band in BANDS for s, std, _ in fits[band]["ground"]])
    print(f"\nz = {np.round(z, 2)}")
    assert np.all(np.abs(z) < 3.0)
    assert 0.3 < float(np.sqrt(np.mean(z * z))) < 2.0  # measured 0.47
