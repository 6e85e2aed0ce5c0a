"""The options of :func:`~camvlp.pipeline.locate.locate` (and of the stages it runs)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.pnp import check_solver
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout

__all__ = ["DEFAULT_SETTINGS", "MIN_SIDE_PX", "LocateSettings", "check_arguments"]

#: Smallest image side, pixels, the detector works on.
MIN_SIDE_PX = 8


@dataclass(frozen=True)
class LocateSettings:
    """Tuning options of :func:`locate` (all keyword-only with defaults).

    Attributes
    ----------
    solver : str
        OpenCV PnP solver for the first estimate: iterative, sqpnp, ippe or epnp.
    outlier_px : float or None
        Reprojection error (pixels) beyond which a fixture does not fit the pose: dropped
        with five or more fixtures, a failure with four.  None: 1 % of the focal length and
        at least 4 px (39 px for the thesis' camera), which tolerates map errors of a few
        centimetres while a wrong ID or a moved light misses by far more.
    kernel_px : int
        Smallest closing length of the detector, full-resolution pixels.
    min_diameter_px : float
        Smallest fixture image considered, pixels.
    readout : Readout, str or None
        Readout ("rows", "columns", "rows-reversed", "columns-reversed"; see
        :class:`camvlp.model.readout.Readout`); None takes the camera's, else finds the axis
        from the stripes (forward).
    readout_hint : Readout, str or None
        A readout the photo's metadata suggests (:func:`camvlp.io.exif_readout`, from its
        EXIF orientation), when neither ``readout`` nor the camera gives one: the stripes
        still decide the axis; where the hint's axis is theirs, its direction is taken, and
        where the stripes do not show the axis, the hint's is read.
    mirrored : bool or None
        Flip the image left-right first; None takes the camera file's ``mirrored``.
    correct_perspective : bool
        Correct each disc's centre for the offset between an ellipse's centre and the
        projected centre of the disc (needs the map's diameters), then solve again.
    keep_stages : bool
        Keep the intermediate results (:class:`LocateStages`) in the result's ``stages``, for
        debug pictures.
    gravity_sigma_deg : float
        Uncertainty of a gravity direction given to :func:`locate`, degrees, about each of
        the two axes across it (a direction off by 1 degree RMS in a random way is 0.71
        about each): weighs the gravity residual against the reprojection residuals, and
        goes into the position's sigma.
    centre_sigma_px : float or None
        With gravity: the uncertainty of a detected disc centre, pixels, which weighs the
        reprojection residuals against the gravity residual.  None (the default): each
        disc's own, estimated from its ellipse fit (:attr:`FixtureResult.centre_sigma_px`;
        1 px for a disc too small to fit).
    max_position_sigma : float or None
        The most a located position's standard deviation may be along any of the map's axes,
        map units (:attr:`LocateResult.position_sigma`); a photo whose position is less sure
        (its fixtures on a narrow band of the photo, a centre or a map position off) is not
        located, its reason giving the sigma.  None (the default): no limit.  A pose solved
        with gravity is held to it too (its sigma weighs the gravity's).
    near : tuple of float or None
        A prior on where the photo was taken, for a map whose IDs repeat
        (:attr:`FixtureMap.reuse`): the camera's ``(x, y)`` or ``(x, y, z)``, map units (with
        two numbers only the map's x and y are compared).  Only the places within ``within``
        of it are searched (:mod:`camvlp.pipeline.identify.by_geometry`).  None: anywhere.
    within : float or None
        The prior's radius, map units; given with ``near`` (and only with it).
    """

    solver: str = "iterative"
    outlier_px: float | None = None
    kernel_px: int = 16
    min_diameter_px: float = 8.0
    readout: Readout | None = None
    readout_hint: Readout | None = None
    mirrored: bool | None = None
    correct_perspective: bool = True
    keep_stages: bool = False
    gravity_sigma_deg: float = 1.0
    centre_sigma_px: float | None = None
    max_position_sigma: float | None = None
    near: tuple[float, ...] | None = None
    within: float | None = None

    def __post_init__(self) -> None:
        check_solver(self.solver)
        for name in ("gravity_sigma_deg", "centre_sigma_px", "max_position_sigma"):
            sigma = getattr(self, name)
            if sigma is None and name != "gravity_sigma_deg":
                continue
            if isinstance(sigma, bool) or not (
                isinstance(sigma, (int, float)) and np.isfinite(sigma) and sigma > 0
            ):
                raise InputError(f"{name} must be a positive number, got {sigma!r}")
        self._check_prior()
        object.__setattr__(self, "readout", Readout.parse_optional(self.readout))
        hint = Readout.parse_optional(self.readout_hint, "readout_hint")
        object.__setattr__(self, "readout_hint", hint)

    def _check_prior(self) -> None:
        """InputError unless ``near`` (2 or 3 finite numbers) and ``within`` (a positive
        number) are given together, or neither."""
        if (self.near is None) != (self.within is None):
            raise InputError("near and within go together: give both or neither")
        if self.near is None:
            return
        near = np.asarray(self.near, dtype=float).reshape(-1)
        if near.size not in (2, 3) or not np.isfinite(near).all():
            raise InputError(f"near must be 2 or 3 finite numbers, got {self.near!r}")
        within = self.within
        if isinstance(within, bool) or not (
            isinstance(within, (int, float)) and np.isfinite(within) and within > 0
        ):
            raise InputError(f"within must be a positive number, got {within!r}")
        object.__setattr__(self, "near", tuple(near.tolist()))


DEFAULT_SETTINGS = LocateSettings()  # frozen: one instance serves every call without settings


def check_arguments(camera: object, fixture_map: object, settings: object) -> None:
    """InputError unless ``camera`` is a :class:`Camera`, ``fixture_map`` a
    :class:`FixtureMap` and ``settings`` :class:`LocateSettings` or None."""
    for name, value, kind in (
        ("camera", camera, Camera),
        ("fixture_map", fixture_map, FixtureMap),
        ("settings", settings, (LocateSettings, type(None))),
    ):
        if not isinstance(value, kind):
            wanted = "LocateSettings or None" if name == "settings" else kind.__name__
            raise InputError(f"{name} must be a {wanted}, got {type(value).__name__}")
