"""``radar.SpeckleFilter``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_radar.speckle.core`.
"""

from __future__ import annotations

from collections import deque

from impala_flow import Component, Input, Output, Param
from impala_flow.msgs import Grid

from .core import INTERPOLATIONS, multilook, threshold_image

__all__ = ["SpeckleFilter"]


class SpeckleFilter(Component):
    """Averages the last ``looks`` co-registered panoramic images, then thresholds.

    Output stamped like its input, same cells, origin, frame and pose as the newest image.
    Images without a pose are averaged as if the vehicle stood still.
    """

    image = Input(Grid, doc="panoramic image (radar.PanoramicBuilder contract)")
    filtered = Output(Grid, doc="multi-look, thresholded image in the same frame")

    looks = Param(int, default=4, ge=1, doc="number of co-registered turns averaged (N)")
    interpolation = Param(str, default="linear", choices=tuple(INTERPOLATIONS), doc="warp interpolation")
    threshold_mode = Param(str, default="none", choices=("none", "mean", "quantile"),
                           doc="FMT step 2 thresholding")
    threshold = Param(float, default=0.0, ge=0, doc="x mean (mode mean) or quantile in [0, 1]")

    def start(self) -> None:
        self._hist: deque[Grid] = deque(maxlen=self.looks)
        self.images = 0

    def process(self, t: int) -> None:
        g: Grid = self.image.take()
        if g.pose is None:
            from impala_flow.msgs import Pose2D

            g = Grid(g.data, g.cell_m, g.origin_x_m, g.origin_y_m, g.frame, Pose2D(0.0, 0.0, 0.0))
        self._hist.append(g)
        data, _ = multilook(list(self._hist), self.interpolation)
        data = threshold_image(data, self.threshold_mode, self.threshold)
        self.images += 1
        self.filtered.emit(t, Grid(data, g.cell_m, g.origin_x_m, g.origin_y_m, g.frame, g.pose))

    def summary(self) -> dict:
        return {"images": self.images}
