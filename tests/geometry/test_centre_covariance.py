"""A fitted ellipse's centre covariance against the scatter of centres over noisy trials."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camvlp.geometry.disc import (
    CENTRE_SIGMA_FLOOR_PX,
    centre_sigma,
    ellipse_centre_covariance,
    sampson_distances,
)

CENTRE = np.array([60.3, 55.7])
A, B, ANGLE = 40.0, 28.0, 25.0  # semi-axes (px) and orientation (deg)


def _chords(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left and right ends (x) of the ellipse's chords along image rows ``rows``."""
    t = np.radians(ANGLE)
    c, s = np.cos(t), np.sin(t)
    y = rows - CENTRE[1]
    # (c x + s y)^2 / A^2 + (-s x + c y)^2 / B^2 = 1, a quadratic in x
    qa = c**2 / A**2 + s**2 / B**2
    qb = 2 * y * c * s * (1 / A**2 - 1 / B**2)
    qc = y**2 * (s**2 / A**2 + c**2 / B**2) - 1
    root = np.sqrt(qb**2 - 4 * qa * qc)
    return CENTRE[0] + (-qb - root) / (2 * qa), CENTRE[0] + (-qb + root) / (2 * qa)


def _trial(rng, rows, shared: bool, noise: float):
    """Edge points of every row with noise along the row, each end its own (``shared``
    False) or one width error per row shared by its two ends: the fitted centre, its
    covariance (the rows as groups when shared), the points, axes and angle."""
    xl, xr = _chords(rows)
    if shared:
        e = rng.normal(0, noise, rows.size)
        xl, xr = xl - e, xr + e
    else:
        xl, xr = xl + rng.normal(0, noise, rows.size), xr + rng.normal(0, noise, rows.size)
    pts = np.concatenate([np.stack([xl, rows], 1), np.stack([xr, rows], 1)])
    (cx, cy), axes, angle = cv2.fitEllipse(pts.astype(np.float32))
    groups = np.concatenate([rows, rows]) if shared else None
    cov = ellipse_centre_covariance(pts, (cx, cy), axes, angle, groups)
    return np.array([cx, cy]), cov, pts, axes, angle


@pytest.mark.parametrize("shared", [False, True])
def test_covariance_matches_the_scatter_of_centres(shared: bool) -> None:
    rng = np.random.default_rng(5)
    rows = np.arange(int(CENTRE[1] - 28), int(CENTRE[1] + 28), dtype=float)
    trials = [_trial(rng, rows, shared, 0.3) for _ in range(300)]
    scatter = np.std(np.array([t[0] for t in trials]), axis=0)
    covs = np.array([t[1] for t in trials])
    predicted = np.sqrt(np.median(np.diagonal(covs, axis1=1, axis2=2), axis=0))
    np.testing.assert_allclose(predicted, scatter, rtol=0.3)
    if shared:
        # the same points taken as independent: the centre along the rows misjudged
        alone = np.array([ellipse_centre_covariance(p, c, ax, a) for c, _, p, ax, a in trials])
        assert np.sqrt(np.median(alone[:, 0, 0])) > 1.5 * scatter[0]


def test_degenerate_and_floor() -> None:
    assert np.all(np.isnan(ellipse_centre_covariance(np.zeros((3, 2)), (0, 0), (2, 2), 0)))
    assert np.all(np.isnan(ellipse_centre_covariance(np.ones((20, 2)), (0, 0), (0, 2), 0)))
    assert centre_sigma(np.zeros((2, 2))) == CENTRE_SIGMA_FLOOR_PX
    assert np.isnan(centre_sigma(np.full((2, 2), np.nan)))
    assert centre_sigma(np.diag([0.04, 0.0])) == pytest.approx(np.sqrt(0.02))


def test_fits_at_once_as_each_alone_whatever_the_labels() -> None:
    """Several fits worked at once give each one's covariance alone, and a fit's groups count
    by which points share a label, not by the labels' values or type: ranked, shifted,
    negative, float, small unsigned or none (every point alone)."""
    from camvlp.geometry.disc import ellipse_centre_covariances

    rng = np.random.default_rng(11)
    rows = np.arange(int(CENTRE[1] - 20), int(CENTRE[1] + 20), dtype=float)
    _, _, pts, axes, angle = _trial(rng, rows, True, 0.3)
    (cx, cy), _, _ = cv2.fitEllipse(pts.astype(np.float32))
    ranks = np.concatenate([np.arange(rows.size)] * 2) // 3  # 3 rows a group
    labels = [ranks, ranks + 1000, ranks - 7, ranks * 0.5, ranks.astype(np.uint8), None]
    fits = [(pts, (cx, cy), axes, angle, g) for g in labels]
    fits.insert(2, (pts[:30], (cx, cy), axes, angle, np.arange(30)))  # a shorter one between
    got = ellipse_centre_covariances(fits)
    alone = [ellipse_centre_covariance(*f) for f in fits]
    np.testing.assert_allclose(got, np.array(alone), rtol=1e-9, atol=1e-15)
    for k in (1, 3, 4, 5):  # the same groups as the ranks
        np.testing.assert_allclose(got[k], got[0], rtol=1e-9, atol=1e-15)
    assert np.all(np.isfinite(got[-1])) and not np.allclose(got[-1], got[0])


def test_sampson_distances_are_nil_on_the_rim_about_the_offset_off_it_and_differentiated():
    t = np.radians(ANGLE)
    p = np.array([[*CENTRE, A, B, t]])
    phi = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    axes = np.stack([A * np.cos(phi), B * np.sin(phi)])  # the rim in the ellipse's axes
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    rim = (rot @ axes).T + CENTRE
    normal = (rot @ (axes / np.array([[A**2], [B**2]]))).T
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    d, _ = sampson_distances(p, rim[None, :, 0], rim[None, :, 1])
    np.testing.assert_allclose(d, 0.0, atol=1e-12)
    out = rim + 0.5 * normal  # half a pixel outside, along the normal
    d, jac = sampson_distances(p, out[None, :, 0], out[None, :, 1])
    np.testing.assert_allclose(d, 0.5, rtol=0.02)
    for k in range(5):
        step = np.zeros(5)
        step[k] = 1e-6
        hi = sampson_distances(p + step, out[None, :, 0], out[None, :, 1])[0]
        lo = sampson_distances(p - step, out[None, :, 0], out[None, :, 1])[0]
        np.testing.assert_allclose(jac[..., k], (hi - lo) / 2e-6, rtol=1e-5, atol=1e-8)
