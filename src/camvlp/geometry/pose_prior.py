"""The pose that best fits a few points and a Gaussian prior on the pose (a track's
prediction): :func:`refine_pose`.

With fewer than four points (or points on a line) PnP alone has no unique answer; the prior
fills in what the points leave open.  The fit is Levenberg-Marquardt over the camera centre
and the thesis' angles (and their rates, for a camera moving during a rolling shutter's
readout: :func:`~camvlp.geometry.projection.project_moving`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.geometry.projection import project_moving
from camvlp.model.camera import Camera, Pose

__all__ = ["PriorSolve", "refine_pose"]


@dataclass(frozen=True)
class PriorSolve:
    """A pose fitted to a few points and a prior (:func:`refine_pose`).

    Attributes
    ----------
    pose : Pose
        The fitted pose (at ``dt = 0``).
    values : ndarray, shape (6,)
        The same as ``(x, y, z, theta_x, theta_y, theta_z)``, map units and degrees.
    rates : ndarray, shape (6,)
        Their fitted rates per s (the prior's when no times were given).
    residuals_px : ndarray, shape (N,)
        Each point's reprojection error with it, pixels.
    jacobian_px : ndarray, shape (2N, 6) or (2N, 12)
        Derivative of the points' pixels (u0, v0, u1, ...) with respect to the values (and
        the rates, when times were given) at the fit.
    """

    pose: Pose
    values: np.ndarray
    rates: np.ndarray
    residuals_px: np.ndarray
    jacobian_px: np.ndarray

    @property
    def reprojection_rms_px(self) -> float:
        """RMS of :attr:`residuals_px`, pixels."""
        return float(np.sqrt(np.mean(self.residuals_px**2)))


def refine_pose(
    object_points,
    image_points,
    camera: Camera,
    prior_position,
    prior_euler_deg,
    *,
    sigma_position=0.05,
    sigma_euler_deg=1.0,
    sigma_px: float = 1.0,
    dt_s=None,
    prior_rates=None,
    sigma_rates=None,
    prior_covariance=None,
) -> PriorSolve | None:
    """The pose that best fits a few points (one or more) and a Gaussian prior on the pose.

    With fewer than four points (or points on a line) PnP alone has no unique answer; a
    prior (a track's prediction) fills in what the points leave open.  Least squares
    (Levenberg-Marquardt, from the prior) over the camera centre and the thesis' angles of
    ``[reprojection / sigma_px, (C - C0) / sigma_position, (theta - theta0) / sigma_euler]``.
    With ``dt_s`` (each point's time, a rolling shutter's rows), the camera moves at constant
    rates (:func:`project_moving`) and the rates are fitted too, with their own prior.

    Parameters
    ----------
    object_points, image_points, camera
        As in :func:`solve_pnp`, but N >= 1.
    prior_position : array_like, shape (3,)
        The prior camera centre, map units.
    prior_euler_deg : array_like, shape (3,)
        The prior's thesis angles, degrees.
    sigma_position : float or array_like, shape (3,)
        The prior's standard deviation per axis, map units.
    sigma_euler_deg : float or array_like, shape (3,)
        The prior's standard deviation per angle, degrees.
    sigma_px : float
        Standard deviation of an image point, pixels.
    dt_s : array_like, shape (N,), optional
        Each point's time relative to the pose's, s.
    prior_rates, sigma_rates : array_like, shape (6,), optional
        The rates' prior (map units and degrees per s) and its standard deviation; needed
        with ``dt_s``.
    prior_covariance : array_like, shape (6, 6) or (12, 12), optional
        The prior's full covariance (values, then rates with ``dt_s``), used instead of the
        standard deviations (which then only scale the steps).

    Returns
    -------
    PriorSolve or None
        None when the fit does not converge to a finite pose with the points in front.
    """
    obj = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
    img = np.asarray(image_points, dtype=np.float64).reshape(-1, 2)
    n = obj.shape[0]
    if img.shape[0] != n or n < 1:
        raise ValueError("object_points and image_points need the same number (>= 1) of points")
    moving = dt_s is not None
    dt = np.zeros(n) if not moving else np.asarray(dt_s, dtype=np.float64).reshape(n)
    x0, sig, r0 = _prior_vector(
        (prior_position, prior_euler_deg),
        (sigma_position, sigma_euler_deg),
        (prior_rates, sigma_rates),
        moving=moving,
    )
    if not (np.all(sig > 0) and np.all(np.isfinite(sig)) and sigma_px > 0):
        raise ValueError("the prior's standard deviations and sigma_px must be positive")
    whiten = _prior_whitening(sig, prior_covariance)
    steps = 1e-6 * np.maximum(np.abs(x0), 1.0)

    def pixel_terms(x: np.ndarray, with_jacobian: bool):
        """Whitened pixel residuals (2N,) and, optionally, their Jacobian (2N, P)."""
        xs = x[None, :]
        if with_jacobian:
            xs = np.vstack([x, x + np.diag(steps)])
        rates = xs[:, 6:] if moving else np.broadcast_to(r0, (xs.shape[0], 6))
        uv = project_moving(camera, xs[:, :6], rates, obj, dt).reshape(xs.shape[0], -1)
        res = (uv[0] - img.ravel()) / sigma_px
        if not with_jacobian:
            return res, None
        return res, ((uv[1:] - uv[0]) / steps[:, None]).T / sigma_px

    x = _levenberg_marquardt(pixel_terms, x0, whiten, sig)
    if x is None:
        return None
    try:
        pose = Pose.from_euler(x[:3], x[3:6])
    except ValueError:
        return None
    if np.any(pose.to_camera(obj)[:, 2] <= 0):
        return None
    res_w, jac = pixel_terms(x, True)
    res = np.hypot(*(res_w.reshape(-1, 2) * sigma_px).T)
    if not (np.all(np.isfinite(res)) and np.all(np.isfinite(jac))):
        return None
    jac = jac * sigma_px
    return PriorSolve(pose, x[:6].copy(), x[6:].copy() if moving else r0, res, jac)


def _prior_vector(
    values: tuple, sigmas: tuple, rates: tuple, *, moving: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The prior's mean (6,) or (12,), its standard deviations (same) and the rates (6,).

    ``values`` is ``(prior_position, prior_euler_deg)``, ``sigmas`` their standard deviations
    and ``rates`` ``(prior_rates, sigma_rates)`` as :func:`refine_pose` takes them.  The mean
    is ``(x, y, z, theta_x, theta_y, theta_z)`` (map units, degrees), followed by the rates
    per s when the camera is ``moving`` (which needs both of ``rates``).
    """
    prior_position, prior_euler_deg = values
    sigma_position, sigma_euler_deg = sigmas
    prior_rates, sigma_rates = rates
    x0 = np.concatenate(
        [
            np.asarray(prior_position, dtype=float).reshape(3),
            np.asarray(prior_euler_deg, dtype=float).reshape(3),
        ]
    )
    sig = np.concatenate(
        [
            np.broadcast_to(np.asarray(sigma_position, dtype=np.float64), (3,)),
            np.broadcast_to(np.asarray(sigma_euler_deg, dtype=np.float64), (3,)),
        ]
    )
    if moving:
        if prior_rates is None or sigma_rates is None:
            raise ValueError("dt_s needs prior_rates and sigma_rates")
        r0 = np.asarray(prior_rates, dtype=np.float64).reshape(6)
        x0 = np.concatenate([x0, r0])
        sig = np.concatenate([sig, np.broadcast_to(np.asarray(sigma_rates, dtype=float), (6,))])
    else:
        r0 = np.zeros(6) if prior_rates is None else np.asarray(prior_rates, dtype=float)
    return x0, sig, r0


def _prior_whitening(sig: np.ndarray, prior_covariance) -> np.ndarray:
    """The matrix W (P, P) with ``|W (x - x0)|^2`` the prior's cost: ``diag(1 / sig)``, or
    ``L^T`` with ``L L^T`` the inverse of ``prior_covariance`` (P, P) when given."""
    if prior_covariance is None:
        return np.diag(1.0 / sig)
    cov = np.asarray(prior_covariance, dtype=np.float64)
    if cov.shape != (sig.size, sig.size) or not np.all(np.isfinite(cov)):
        raise ValueError(f"prior_covariance must be a finite {sig.size} x {sig.size} matrix")
    try:
        return np.linalg.cholesky(np.linalg.inv(cov)).T
    except np.linalg.LinAlgError:
        raise ValueError("prior_covariance must be positive definite") from None


def _levenberg_marquardt(pixel_terms, x0: np.ndarray, whiten: np.ndarray, sig: np.ndarray):
    """Minimise the pixel terms plus the prior's (linear) terms from the prior ``x0`` (P,).

    ``pixel_terms(x, with_jacobian)`` gives the whitened pixel residuals (2N,) and their
    Jacobian (2N, P); ``whiten`` (P, P) the prior's; ``sig`` (P,) scales the step that counts
    as converged.  Returns the fitted values (P,), or None when a cost is not finite or a
    step cannot be solved.
    """

    def cost(x: np.ndarray) -> float:
        res, _ = pixel_terms(x, False)
        return float(res @ res + np.sum((whiten @ (x - x0)) ** 2))

    x = x0.copy()
    current = cost(x)
    if not np.isfinite(current):
        return None
    damping = 1e-3
    for _ in range(30):
        res, jac = pixel_terms(x, True)
        if not (np.all(np.isfinite(res)) and np.all(np.isfinite(jac))):
            return None
        prior = whiten @ (x - x0)
        h = jac.T @ jac + whiten.T @ whiten
        g = jac.T @ res + whiten.T @ prior
        improved = False
        while damping < 1e10:
            try:
                step = np.linalg.solve(h + damping * np.diag(np.diag(h)), -g)
            except np.linalg.LinAlgError:
                return None
            trial = x + step
            new = cost(trial)
            if np.isfinite(new) and new <= current:
                x, damping, improved = trial, max(damping / 10, 1e-9), True
                break
            damping *= 10
        if not improved or abs(current - new) <= 1e-6 * max(current, 1e-12):
            break
        current = new
        if np.all(np.abs(step) <= 1e-3 * np.maximum(sig, 1e-12)):
            break
    return x
