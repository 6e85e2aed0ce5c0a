"""Constant-velocity Kalman filter used by the video tracker
(:mod:`camvlp.pipeline.track.tracker`)."""

from __future__ import annotations

import numpy as np

__all__ = ["ConstantVelocityFilter"]


class ConstantVelocityFilter:
    """Kalman filter with a constant-velocity model on D coordinates.

    State: the D values, then their D rates (units per s); ``x`` (2D,), ``P`` (2D, 2D).  The
    process noise is a random acceleration, constant over each step, of standard deviation
    ``accel_sigma`` per coordinate (units / s^2; the discrete white-noise acceleration model).

    Parameters
    ----------
    value : array_like, shape (D,)
        First measurement.
    value_sigma : array_like, shape (D,)
        Its standard deviation.
    rate_sigma : array_like, shape (D,)
        Standard deviation of the unknown initial rate (units per s).
    accel_sigma : array_like, shape (D,)
        Standard deviation of the acceleration per coordinate, units per s^2.
    """

    def __init__(self, value, value_sigma, rate_sigma, accel_sigma) -> None:
        v = np.asarray(value, dtype=float).reshape(-1)
        d = v.size
        self.d = d
        self.x = np.concatenate([v, np.zeros(d)])
        var = np.concatenate(
            [
                np.broadcast_to(np.asarray(value_sigma, dtype=float) ** 2, (d,)),
                np.broadcast_to(np.asarray(rate_sigma, dtype=float) ** 2, (d,)),
            ]
        )
        self.P = np.diag(var)
        self.q = np.broadcast_to(np.asarray(accel_sigma, dtype=float) ** 2, (d,)).copy()

    @property
    def value(self) -> np.ndarray:
        """Current values, shape (D,)."""
        return self.x[: self.d].copy()

    @property
    def rate(self) -> np.ndarray:
        """Current rates (units per s), shape (D,)."""
        return self.x[self.d :].copy()

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviation of each value, shape (D,)."""
        return np.sqrt(np.diag(self.P)[: self.d])

    def predicted(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The state (2D,) and covariance (2D, 2D) ``dt`` seconds on, without moving."""
        dt = max(float(dt), 0.0)
        eye = np.eye(self.d)
        f = np.block([[eye, dt * eye], [np.zeros_like(eye), eye]])
        q = np.diag(self.q)
        qm = np.block([[q * dt**4 / 4, q * dt**3 / 2], [q * dt**3 / 2, q * dt**2]])
        return f @ self.x, f @ self.P @ f.T + qm

    def predict(self, dt: float) -> None:
        """Move the state ``dt`` seconds on (``dt`` >= 0)."""
        self.x, self.P = self.predicted(dt)

    def update(self, z, sigma) -> None:
        """Fuse a measurement of the values, ``z`` (D,), with standard deviations (D,)."""
        z = np.asarray(z, dtype=float).reshape(-1)
        h = np.hstack([np.eye(self.d), np.zeros((self.d, self.d))])
        r = np.diag(np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, z.shape))
        self._fuse(z - self.x[: self.d], h, r)

    def update_some(self, indices, z, sigma) -> None:
        """Fuse a measurement of some of the values (``indices``), ``z`` and ``sigma`` alike."""
        idx = np.asarray(indices, dtype=int).reshape(-1)
        h = np.zeros((idx.size, self.x.size))
        h[np.arange(idx.size), idx] = 1.0
        z = np.asarray(z, dtype=float).reshape(-1)
        r = np.diag(np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, z.shape))
        self._fuse(z - self.x[idx], h, r)

    def update_linearized(self, residual, jacobian, state_ref, sigma: float) -> None:
        """Fuse a nonlinear measurement, linearised at ``state_ref``.

        ``residual`` (M,) is the measurement minus its model at ``state_ref``, ``jacobian``
        the model's derivative there with respect to the values (M, D) or the whole state
        (M, 2D), ``state_ref`` (D,) or (2D,) accordingly, ``sigma`` the measurement's standard
        deviation (an iterated extended Kalman filter step).  Directions the measurement does
        not see keep their prior.
        """
        jac = np.asarray(jacobian, dtype=float)
        ref = np.asarray(state_ref, dtype=float)
        if jac.shape[1] == self.d:
            jac = np.hstack([jac, np.zeros_like(jac)])
            ref = np.concatenate([ref, self.x[self.d :]])
        innovation = np.asarray(residual, dtype=float) - jac @ (self.x - ref)
        self._fuse(innovation, jac, np.eye(jac.shape[0]) * sigma**2)

    def _fuse(self, innovation: np.ndarray, h: np.ndarray, r: np.ndarray) -> None:
        s = h @ self.P @ h.T + r
        k = np.linalg.solve(s, h @ self.P).T
        self.x = self.x + k @ innovation
        ikh = np.eye(self.x.size) - k @ h
        self.P = ikh @ self.P @ ikh.T + k @ r @ k.T  # Joseph form: stays symmetric
