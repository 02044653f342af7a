"""The FMT's parameters, an image ready to register and a registration's result (the algorithm:
:mod:`impala_slam.fmt.core`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FmtParams", "FmtImage", "FmtResult"]


@dataclass(frozen=True)
class FmtParams:
    cell_m: float = 0.5  # cell of the registration grid
    size: int = 400  # cells per side (the grid spans +- size * cell_m / 2)
    range_min_m: float = 3.0  # blind range: zeroed
    range_max_m: float = 0.0  # outer radius used (0: the grid's half side)
    taper_m: float = 15.0  # width of the radial cosine taper before range_max_m
    db_floor_quantile: float = 0.9  # cells above this quantile of the observed power are kept (step 2)
    angles: int = 720  # rows of the polar magnitude spectrum over 360 deg
    band: tuple[float, float] = (0.02, 0.25)  # spatial frequencies used for the rotation (cycles / cell)
    k_translation: float = 5.0  # covariance constants (see the module docstring)
    k_rotation: float = 40.0  # rotation from the spectra alone (refine_deg = 0)
    k_rotation_refined: float = 20.0  # rotation refined on the translation peak
    floor_cells: float = 0.06  # std floor of each peak (cells, rotation bins)
    along_frac: float = 0.01  # std along the translation per metre (the odometer's scale in the images)
    rot_frac: float = 0.02  # rotation std per radian turned between the images (the gyro's, likewise)
    rot_floor_deg: float = 0.05  # rotation std the peaks never see (the gyro's bias in the motion correction)
    min_snr: float = 6.0  # a translation peak weaker than this is not a registration
    refine_deg: float = 0.5  # step of the rotation refinement on the translation peak (0: Algorithm 1 only)
    min_wavelength_m: float = 0.0  # finest spatial wavelength in the translation correlation (0: up to Nyquist)


@dataclass
class FmtImage:
    """An image ready to register: the tapered dB image and its polar magnitude spectrum."""

    image: np.ndarray  # float32 size x size, row = y, column = x, radar at the centre
    polar: np.ndarray  # angles x radii, float32: high-passed |FFT| in polar coordinates
    cell_m: float
    # rfft2 of image * Hann by number of columns kept (see image_spectrum): computed once however often
    # the image is registered as the older one
    spectra: dict[int, np.ndarray] = field(default_factory=dict, repr=False, compare=False)
    # the image on the coarse grid (half_image) and its spectrum by number of columns kept
    half: np.ndarray | None = field(default=None, repr=False, compare=False)
    half_spectra: dict[int, np.ndarray] = field(default_factory=dict, repr=False, compare=False)
    # the rotation's spectrum of the polar image folded onto half a turn (spectra.folded_spectrum)
    folded: np.ndarray | None = field(default=None, repr=False, compare=False)
    # whether a cell of the image is not 0 (None: not known yet, see any_cell)
    nonzero: bool | None = field(default=None, repr=False, compare=False)

    @property
    def any_cell(self) -> bool:
        """``np.any(image)``, taken once per image (:func:`prepare` knows it from its halves of rows)."""
        if self.nonzero is None:
            self.nonzero = bool(np.any(self.image))
        return self.nonzero

    @property
    def nbytes(self) -> int:
        return (self.image.nbytes + self.polar.nbytes + sum(s.nbytes for s in self.spectra.values())
                + (0 if self.half is None else self.half.nbytes) + sum(s.nbytes for s in self.half_spectra.values())
                + (0 if self.folded is None else self.folded.nbytes))


@dataclass
class FmtResult:
    """Pose of the newer image's frame in the older one's, with its 3x3 covariance."""

    x_m: float
    y_m: float
    theta_rad: float
    cov_xyt: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    snr_translation: float = 0.0
    snr_rotation: float = 0.0
    ok: bool = False
    reason: str = ""

    @property
    def xyt(self) -> tuple[float, float, float]:
        return self.x_m, self.y_m, self.theta_rad
