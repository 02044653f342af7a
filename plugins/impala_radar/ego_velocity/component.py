"""``radar.EgoVelocity``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_radar.ego_velocity.core`.
"""

from __future__ import annotations

import importlib

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_msgs import RadarDetections, Speed

from .core import EgoFit, fit_ego_velocity, subset

__all__ = ["EgoVelocity"]


class EgoVelocity(Component):
    """Per turn: robust fit of V(theta) = V0 cos(theta - theta0) cos(el) to the detections
    (cos(el) from each detection's slant range and the heights: see the module doc); emits the
    forward speed -V0 with its standard deviation, and the detections off the curve
    (candidate movers). Both stamped with the detections' time (the turn's last beam).
    Turns with fewer than ``min_detections`` finite detections emit nothing (counted)."""

    detections = Input(RadarDetections, doc="paired detections of one turn")
    speed = Output(Speed, doc="forward speed (m/s) and its standard deviation")
    movers = Output(RadarDetections, doc="detections off the static-Doppler curve")

    loss = Param(str, default="soft_l1", choices=("soft_l1", "huber", "cauchy", "arctan"),
                 doc="robust loss of scipy.optimize.least_squares")
    f_scale_mps = Param(float, default=0.25, gt=0, doc="residual scale of the robust loss")
    outlier_sigma = Param(float, default=3.0, gt=0, doc="movers: |residual| > this x robust sigma")
    min_gate_mps = Param(float, default=0.3, ge=0, doc="movers: and |residual| > this")
    min_detections = Param(int, default=10, ge=3, doc="fewer finite detections: no estimate")
    fit_offset = Param(bool, default=True, doc="fit theta0 (mounting / side-slip angle) too")
    radar_height_m = Param(float, default=1.3, ge=0,
                           doc="radar above the ground (IMPALA 1.3 m, K2Pi 3 m): the depression angle of the echoes")
    scatterers = Param(str, default="both", choices=("both", "ground", "raised"),
                       doc="heights of the static scatterers: 'ground' (z = 0, clutter: factor ground / slant "
                           "range), 'raised' (at the radar's height: factor 1), 'both' (a mixture of the two, "
                           "fitted by EM; see the module doc)")
    std_floor_mps = Param(float, default=0.005, ge=0,
                          doc="added in quadrature to the formal std (peak-interpolation bias: -3 mm/s measured)")

    def start(self) -> None:
        importlib.import_module("scipy.optimize")  # before the first sample (core imports it where it fits)
        self.last_fit: EgoFit | None = None
        self.estimates = 0
        self.skipped = 0

    def process(self, t: int) -> None:
        d: RadarDetections = self.detections.take()
        if np.isfinite(d.radial_speed_mps).sum() < self.min_detections:
            self.skipped += 1
            return
        fit = fit_ego_velocity(d.azimuth_rad, d.radial_speed_mps, range_m=d.range_m,
                               radar_height_m=self.radar_height_m, target_heights_m=self._heights_m(), loss=self.loss,
                               f_scale_mps=self.f_scale_mps, outlier_sigma=self.outlier_sigma,
                               min_gate_mps=self.min_gate_mps, fit_offset=self.fit_offset)
        if fit is None:
            self.skipped += 1
            return
        self.last_fit = fit
        self.estimates += 1
        self.speed.emit(t, Speed(fit.speed_mps, float(np.hypot(fit.v0_std_mps, self.std_floor_mps))))
        self.movers.emit(t, subset(d, ~fit.inlier & np.isfinite(d.radial_speed_mps)))

    def _heights_m(self) -> tuple[float, ...]:
        return {"ground": (0.0,), "raised": (self.radar_height_m,),
                "both": (0.0, self.radar_height_m)}[self.scatterers]

    def summary(self) -> dict:
        return {"estimates": self.estimates, "skipped": self.skipped}
