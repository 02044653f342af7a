"""``radar.FrontendReport``: PNG figures of the front end like the seed's (written at stop).

- ``ppi.png``: panoramic image before and after anti-speckle filtering (seed 1 Fig. 3);
- ``doppler.png``: radial speed of the detections against azimuth with the fitted cosine
  V0 cos(theta - theta0) and the detections off the curve (Fig. 17);
- ``pairs.png``: up- and down-ramp spectra of one beam with the pairs drawn (Fig. 4).
"""

from __future__ import annotations

import numpy as np

from impala_msgs import SPEED_OF_LIGHT_MPS, RadarConfig

__all__ = ["beat_bins_of_detections"]


def beat_bins_of_detections(range_m, radial_mps, config: RadarConfig) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (3) inverted: f_up + f_down = 8 dF Fm R / c, f_up - f_down = 4 f0 V / c (bins)."""
    s = 8.0 * config.bandwidth_hz * config.modulation_hz * np.asarray(range_m) / SPEED_OF_LIGHT_MPS
    d = 4.0 * config.f0_hz * np.asarray(radial_mps) / SPEED_OF_LIGHT_MPS
    return 0.5 * (s + d) / config.bin_hz, 0.5 * (s - d) / config.bin_hz
