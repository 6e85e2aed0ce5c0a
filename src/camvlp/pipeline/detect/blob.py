"""What a detected fixture is: its disc's outline and centre in the photo, the readout axis
its stripes show, and how sure its centre is from the scatter of the disc's edge points about
the ellipse fitted to them.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from camvlp.geometry.disc import centre_sigma, ellipse_centre_covariance

__all__ = ["Blob", "EllipseFit", "row_groups"]


@dataclass(frozen=True)
class Blob:
    """One detected fixture.

    Attributes
    ----------
    pixel : ndarray, shape (2,)
        Centre of the disc ``[u, v]`` in full-resolution pixels (sub-pixel).
    box : tuple of int
        Region of interest ``(x0, y0, x1, y1)``, full resolution, end exclusive.
    mask : ndarray of bool, shape (y1 - y0, x1 - x0)
        The disc, stripes filled, inside the region of interest.
    axes_px : ndarray, shape (2,)
        Full lengths of the fitted ellipse's axes, pixels (major first).
    angle_deg : float
        Orientation of the fitted ellipse as :func:`cv2.fitEllipse` gives it, degrees: of the
        first axis it returns, which may be the minor one (``axes_px`` is sorted).  The
        consumers of the pair (the row profiles' rings, the radial fit's starts) were
        measured with it as it is; the glow check takes the major axis's own angle
        (:attr:`major_angle`).
    touches_border : bool
        The disc is cut by the image border (its centre would be biased).
    axis : str
        Readout axis seen in this blob: ``"rows"`` (horizontal stripes) or ``"columns"``.
    stripe_contrast : float
        Variance ratio of the profile along the readout axis to the profile across it; high
        for a striped disc, near 1 for a steady light, below 1 when the readout was given and
        the blob varies more across it.
    edge_points : int
        Edge points the ellipse was fitted to (0 when the centroid was used instead).
    centre_cov_px2 : ndarray, shape (2, 2)
        Covariance of ``pixel`` from the ellipse fit's residuals, pixels squared (read-only:
        ``centre_cov`` when given, else :attr:`EllipseFit.covariance` of ``edge_fit``); NaN
        when the centroid was used or the fit cannot tell.
    gray : ndarray of uint8, shape (y1 - y0, x1 - x0), or None
        The region of interest in gray levels
        (:func:`~camvlp.imaging.gray.to_gray`), kept so that later stages need not
        convert it again.
    cell : ndarray of bool, shape (y1 - y0, x1 - x0), or None
        The part of the region that is this light's when its glow joins other lights'
        (:mod:`camvlp.pipeline.detect.touching`); None when the region is all its own.
    face : bool
        ``mask`` is the light's face as its dark stripes show it
        (:func:`~camvlp.pipeline.detect.faces.own_face`: a light whose glow joins others'),
        not its lit pixels.
    stripe_share : float
        The share (0 to 1) of the variance of the light's pixels that its mean level per line
        along ``axis`` explains (:func:`~camvlp.pipeline.detect.readout.stripe_share`): near
        1 for a striped light (its lines alternate bright and dark across their whole length;
        0.6 to 0.98 on the real photos' lights and the renders), low for text or a steady
        light.
    """

    pixel: np.ndarray
    box: tuple[int, int, int, int]
    mask: np.ndarray
    axes_px: np.ndarray
    angle_deg: float
    touches_border: bool
    axis: str
    stripe_contrast: float
    edge_points: int
    gray: np.ndarray | None = field(default=None, repr=False, compare=False)
    cell: np.ndarray | None = field(default=None, repr=False, compare=False)
    face: bool = field(default=False, repr=False, compare=False)
    stripe_share: float = field(default=float("nan"), compare=False)
    edge_fit: EllipseFit | None = field(default=None, repr=False, compare=False)
    centre_cov: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def major_angle(self) -> float:
        """Orientation of the fitted ellipse's major axis (the first of :attr:`axes_px`),
        degrees from the image's x axis towards its y axis: :attr:`angle_deg`, a quarter turn
        more where the fit's first axis (:attr:`edge_fit`) is its shorter one."""
        fit = self.edge_fit
        # (a round outline put in its place, equal axes, has no major axis to turn to)
        turned = fit is not None and fit.axes[0] < fit.axes[1] and self.axes_px[0] > self.axes_px[1]
        return (self.angle_deg + 90.0) % 180.0 if turned else self.angle_deg

    @property
    def centre_cov_px2(self) -> np.ndarray:
        """:attr:`centre_cov` when given, else the ellipse fit's (NaN without one), (2, 2)."""
        if self.centre_cov is not None:
            return self.centre_cov
        if self.edge_fit is None:
            return np.full((2, 2), np.nan)
        return self.edge_fit.covariance.copy()

    @property
    def centre_sigma_px(self) -> float:
        """The centre's uncertainty, pixels (1-sigma per axis, the RMS of the two): from
        :attr:`centre_cov_px2`, at least
        :data:`~camvlp.geometry.disc.CENTRE_SIGMA_FLOOR_PX`; NaN when unknown."""
        return centre_sigma(self.centre_cov_px2)


@dataclass(frozen=True)
class EllipseFit:
    """The ellipse fitted to a disc's edge points, whose scatter tells how sure its centre is.

    Attributes
    ----------
    points : ndarray, shape (M, 2)
        The edge points fitted, pixels.
    centre : ndarray, shape (2,)
    axes : ndarray, shape (2,)
        Full lengths of the axes, as :func:`cv2.fitEllipse` gives them.
    angle_deg : float
    axis : {"rows", "columns"}
        The readout axis: the points of a run of sensor lines share their errors.
    """

    points: np.ndarray
    centre: np.ndarray
    axes: np.ndarray
    angle_deg: float
    axis: str

    @functools.cached_property
    def covariance(self) -> np.ndarray:
        """The centre's covariance, pixels squared, shape (2, 2)
        (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`, the points grouped by
        :func:`row_groups`); worked out when first read (most calls never read it)."""
        groups = row_groups(self.points, self.axis)
        return ellipse_centre_covariance(
            self.points, self.centre, self.axes, self.angle_deg, groups
        )


def row_groups(points: np.ndarray, axis: str) -> np.ndarray:
    """The groups of edge points (M, 2) whose errors an ellipse's centre covariance takes as
    shared (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`): runs of about sqrt(n)
    consecutive sensor lines out of the n they span (batch means).  A line's two ends share
    its exposure, and the stripes make neighbouring lines' errors depend on each other,
    while runs far apart do not.  One label per point, shape (M,)."""
    lines = points[:, 1] if axis == "rows" else points[:, 0]
    low = lines.min()
    step = max(1.0, math.sqrt(lines.max() - low + 1.0))
    return np.floor((lines - low) / step).astype(np.int64)
