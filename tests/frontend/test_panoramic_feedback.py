"""PanoramicBuilder with a fed-back twist, live and offline (issue 27, item 5: live equals replay).

Offline, the twist a SLAM computes from image k is always back before turn k+1 is imaged. Live,
a slow SLAM (its first turns: allocations, caches) may still be busy: the builder then waits for
that twist, bounded in radar time (``twist_wait_s`` of beams after the waiting turn), so the live
run images every turn with the twist the offline run uses, bit for bit. The stand-in SLAM here
answers image k with a twist that depends on k, so an image made with another twist differs.
Beams: a simulated Navtech (4 turns/s, 400 beams) driving past four reflectors, paced at their
own times by the real-time executor (which shifts them all by one constant)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from impala_flow import Component, Input, Network, OfflineExecutor, Output, Param, RealTimeExecutor
from impala_flow.msgs import Grid, Twist2D
from impala_flow.testing import CollectingSink, ScriptedSource, connect
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.simulator.core import simulate
from impala_radar.simulator.presets import NAVTECH
from impala_radar.simulator.spectra import RadarParams
from impala_radar.simulator.vehicle import Trajectory
from impala_radar.simulator.world import WorldBuilder

POINTS = np.array([[30.0, 20.0], [-25.0, -15.0], [5.0, 40.0], [40.0, -30.0]])


@pytest.fixture(scope="module")
def beams() -> list[tuple[int, str, object]]:
    """Ten turns (2.5 s) of a simulated Navtech at 5 m/s."""
    rng = np.random.default_rng(7)
    b = WorldBuilder(rng)
    b.points(POINTS, 1.3, 10.0, "point")
    traj = Trajectory.from_waypoints(np.array([[-20.0, 0.0], [200.0, 0.0]]), 5.0, rest_at_ends=False)
    ev = simulate(b.build(), traj, NAVTECH, rng, start_t_ns=traj.start_ns + 1_000_000_000,
                  duration_ns=2_500_000_000, params=RadarParams(thermal_noise=False))
    return [e for e in ev if e[1] == "beams"]


class SlowSlam(Component):
    """Answers image k (1, 2, ...) with the twist (5 + 0.01 k m/s, 0.002 k rad/s), as a SLAM
    answers with its velocity estimate; sleeps ``delay_s`` on its first ``slow`` images (a slow
    start); ``answer: false`` never answers."""

    image = Input(Grid)
    twist = Output(Twist2D)
    delay_s = Param(float, default=0.0, ge=0)
    slow = Param(int, default=3, ge=0)
    answer = Param(bool, default=True)

    def start(self) -> None:
        self.k = 0

    def process(self, t: int) -> None:
        self.image.take()
        self.k += 1
        if self.k <= self.slow:
            time.sleep(self.delay_s)
        if self.answer:
            self.twist.emit(t, Twist2D(5.0 + 0.01 * self.k, 0.002 * self.k))


def _run(beams, live: bool, delay_s: float = 0.0, answer: bool = True, wait_s: float = 2.0):
    """The images (time, cells) and the builder's stale_twist count of one run."""
    net = Network(name="feedback")
    pano = PanoramicBuilder("pano", cell_m=0.5, range_max_m=50.0, twist_wait_s=wait_s)
    sink = CollectingSink("sink")
    for c in (ScriptedSource("src", beams), pano, SlowSlam("slam", delay_s=delay_s, answer=answer), sink):
        net.add(c)
    for spec in ("src.beams -> pano.beams", "pano.image -> slam.image", "slam.twist -> pano.twist [delay]",
                 "pano.image -> sink.x"):
        connect(net, spec)
    summary = RealTimeExecutor(net).run() if live else OfflineExecutor(net).run()
    assert summary.error is None and summary.drops() == {}
    return [(s.timestamp, s.data.data) for s in sink.samples], pano.stale_twist


def _same(a, b) -> bool:
    """The same images at the same times (live, the executor shifts a paced source's times by a
    constant: its first sample is the start of the run)."""
    return len(a) == len(b) and all(ta - a[0][0] == tb - b[0][0] and np.array_equal(ga, gb)
                                    for (ta, ga), (tb, gb) in zip(a, b, strict=True))


def test_a_slow_slam_live_images_every_turn_as_offline(beams) -> None:
    """The stand-in SLAM takes 0.3 s (more than a turn) on each of its first three images: turns
    3 and 4 close before the previous twist is back and wait for it. Without the wait
    (``twist_wait_s: 0``) they would be imaged with an older twist: the scenario needs the wait."""
    offline, stale_offline = _run(beams, live=False)
    assert len(offline) == 10 and stale_offline == 1  # the bootstrap's second image, both runs
    live, stale_live = _run(beams, live=True, delay_s=0.3)
    assert stale_live == stale_offline and _same(live, offline)
    _, stale_unwaited = _run(beams, live=True, delay_s=0.3, wait_s=0.0)
    assert stale_unwaited > stale_offline


def test_a_slam_that_never_answers_is_waited_for_a_bounded_time(beams) -> None:
    """No twist ever comes back: each turn waits ``twist_wait_s`` of radar time (beams stamped that
    long after its last one), then is imaged with what the builder has (the bootstrap's speed),
    counted as stale, the same live and offline; none is lost."""
    offline, stale_offline = _run(beams, live=False, answer=False, wait_s=0.3)
    live, stale_live = _run(beams, live=True, answer=False, wait_s=0.3)
    assert len(offline) == 10 and stale_offline == 9 and stale_live == stale_offline
    assert _same(live, offline)


class LaggingTwist(Component):
    """A twist from beside the builder (an estimator on the same beams, no feedback loop): at each
    turn's first beam, stamped 0.2 s earlier (its estimate lags), a value that depends on the turn."""

    beams = Input(object)
    twist = Output(Twist2D)

    def process(self, t: int) -> None:
        b = self.beams.take()
        if b.index == 0:
            self.twist.emit(t - 200_000_000, Twist2D(5.0 + 0.01 * b.turn, 0.002 * b.turn))


def test_a_twist_from_beside_the_builder_is_used_as_it_comes(beams) -> None:
    """Without a delayed connection (not a feedback loop) the builder never holds a turn for the
    twist: the images are those of a builder that never waits (``twist_wait_s: 0``)."""
    images = {}
    for wait_s in (0.0, 2.0):
        net = Network(name="beside")
        pano = PanoramicBuilder("pano", cell_m=0.5, range_max_m=50.0, twist_wait_s=wait_s)
        sink = CollectingSink("sink")
        for c in (ScriptedSource("src", beams), LaggingTwist("odo"), pano, sink):
            net.add(c)
        for spec in ("src.beams -> pano.beams", "src.beams -> odo.beams", "odo.twist -> pano.twist",
                     "pano.image -> sink.x"):
            connect(net, spec)
        assert OfflineExecutor(net).run().error is None
        assert not pano.twist.fed_back
        images[wait_s] = [(s.timestamp, s.data.data) for s in sink.samples]
    assert len(images[0.0]) == 10 and _same(images[2.0], images[0.0])
