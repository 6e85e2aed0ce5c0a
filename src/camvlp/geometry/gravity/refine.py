"""Many poses refined at once on the gravity solver's cost (vectorised Gauss-Newton)."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.pnp import rodrigues_batch

__all__ = ["refine_gravity_batch"]


def refine_gravity_batch(
    rotations,
    centres,
    points,
    bearings,
    gravity,
    up,
    *,
    focal_px: float,
    sigma_deg: float = 1.0,
    pixel_sigma_px=1.0,
    mask=None,
    iterations: int = 12,
) -> tuple[np.ndarray, np.ndarray]:
    """Many poses refined at once on the cost of :func:`solve_pose_gravity`.

    Gauss-Newton (forward-difference Jacobians, a little Levenberg-Marquardt damping) on the
    reprojection residuals (pixels / ``pixel_sigma_px``) and the gravity residual
    (``(R g) x down / sigma``), for studies that start each pose near its answer (the
    true pose): it finds the same local minimum as the solver, without its search for a
    start.

    Parameters
    ----------
    rotations : array_like, shape (B, 3, 3)
        Starting camera-to-world rotations.
    centres : array_like, shape (B, 3)
        Starting camera centres, map units.
    points : array_like, shape (N, 3)
        Fixture positions, map units.
    bearings : array_like, shape (B, N, 2)
        Undistorted normalised image coordinates of each fixture in each pose.
    gravity : array_like, shape (B, 3)
        Measured gravity per pose, camera frame (any length).
    up : array_like, shape (3,)
        The map's up.
    focal_px : float
        Focal length (pixels per unit of normalised coordinates).
    sigma_deg : float
        Uncertainty of the gravity direction, degrees.
    pixel_sigma_px : float or array_like, shape (N,) or (B, N)
        Uncertainty of the centres, pixels: one for all, or one per fixture (per pose).
    mask : array_like of bool, shape (B, N), optional
        Which fixtures each pose uses (default all).
    iterations : int
        Gauss-Newton steps.

    Returns
    -------
    rotations : ndarray, shape (B, 3, 3)
    centres : ndarray, shape (B, 3)
    """
    r0 = np.asarray(rotations, float).reshape(-1, 3, 3)
    c = np.asarray(centres, float).reshape(-1, 3).copy()
    x = np.asarray(points, float).reshape(-1, 3)
    b_obs = np.asarray(bearings, float).reshape(r0.shape[0], x.shape[0], 2)
    g = np.asarray(gravity, float).reshape(-1, 3)
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    down = -np.asarray(up, float) / np.linalg.norm(up)
    w = np.ones(b_obs.shape[:2]) if mask is None else np.asarray(mask, float)
    w = w / np.broadcast_to(np.asarray(pixel_sigma_px, float), b_obs.shape[:2])
    sigma = np.radians(sigma_deg)
    nb = r0.shape[0]

    def residuals(q: np.ndarray) -> np.ndarray:
        """Residuals (7B, M) of the parameters (7, B, 6): each pose and its 6 nudges."""
        rot = (rodrigues_batch(q[..., :3].reshape(-1, 3)).reshape(7, nb, 3, 3)) @ r0
        pc = np.einsum("kbni,kbij->kbnj", x[None, None] - q[..., None, 3:], rot)
        z = np.where(np.abs(pc[..., 2]) < 1e-12, 1e-12, pc[..., 2])
        rp = focal_px * (pc[..., :2] / z[..., None] - b_obs) * w[..., None]
        gw = np.einsum("kbij,bj->kbi", rot, g)
        rg = np.stack(
            [
                gw[..., 1] * down[2] - gw[..., 2] * down[1],
                gw[..., 2] * down[0] - gw[..., 0] * down[2],
                gw[..., 0] * down[1] - gw[..., 1] * down[0],
            ],
            axis=-1,
        )
        return np.concatenate([rp.reshape(7, nb, -1), rg / sigma], axis=2)

    p = np.concatenate([np.zeros((nb, 3)), c], axis=1)
    step = np.array([1e-7] * 3 + [1e-7 * max(1.0, float(np.abs(x).max()))] * 3)
    nudges = np.concatenate([np.zeros((1, 6)), np.diag(step)])[:, None, :]  # (7, 1, 6)
    for _ in range(iterations):
        f = residuals(p[None] + nudges)
        jac = np.moveaxis((f[1:] - f[0]) / step[:, None, None], 0, -1)  # (B, M, 6)
        jtj = np.einsum("bmi,bmj->bij", jac, jac)
        jtf = np.einsum("bmi,bm->bi", jac, f[0])
        damp = 1e-9 * np.trace(jtj, axis1=1, axis2=2)[:, None, None] * np.eye(6)
        delta = np.linalg.solve(jtj + damp, jtf[..., None])[..., 0]
        p = p - delta
        if np.all(np.abs(delta) <= 1e-12 * (1.0 + np.abs(p))):
            break
    return rodrigues_batch(p[:, :3]) @ r0, p[:, 3:]
