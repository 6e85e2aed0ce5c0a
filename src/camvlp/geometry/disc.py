"""The geometry of a fixture's disc: its plane, its rim, and where its image's centre lies.

Used by the simulator (to draw discs), the locator (to correct a detected ellipse's centre to
the projected centre of its disc) and the coverage study (to test whether a disc is in view).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose, finite_rows

__all__ = [
    "CENTRE_SIGMA_FLOOR_PX",
    "centre_sigma",
    "disc_normals",
    "ellipse_centre_covariance",
    "ellipse_centre_covariances",
    "perspective_offset",
    "perspective_offsets",
    "plane_basis",
    "rim_points",
    "sampson_distances",
]


def plane_basis(normals) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane of each normal.

    Parameters
    ----------
    normals : array_like, shape (N, 3) or (3,)
        Plane normals (need not be unit length, must not be zero).

    Returns
    -------
    a, b : ndarray, shape like ``normals``
        Orthonormal, both perpendicular to the normal, ``b = n x a`` (right-handed).
    """
    n = np.asarray(normals, dtype=float)
    flat = n.ndim == 1
    n = np.atleast_2d(n)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    helper = np.eye(3)[np.argmin(np.abs(n), axis=1)]  # the axis least aligned with n
    a = np.cross(n, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(n, a)
    return (a[0], b[0]) if flat else (a, b)


def rim_points(centres, diameters, normals, n_rim: int) -> np.ndarray:
    """Points on each disc's rim.

    Parameters
    ----------
    centres : array_like, shape (N, 3)
        Disc centres (any length unit).
    diameters : array_like, shape (N,)
        Disc diameters, same unit.
    normals : array_like, shape (N, 3)
        Disc normals.
    n_rim : int
        Points per rim, evenly spaced in angle.

    Returns
    -------
    ndarray, shape (N, n_rim, 3)
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    d = np.asarray(diameters, dtype=float).reshape(-1)
    a, b = plane_basis(np.asarray(normals, dtype=float).reshape(-1, 3))
    t = 2 * np.pi * np.arange(int(n_rim)) / int(n_rim)
    r = 0.5 * d[:, None, None]
    return c[:, None, :] + r * (
        np.cos(t)[None, :, None] * a[:, None, :] + np.sin(t)[None, :, None] * b[:, None, :]
    )


def disc_normals(centres, normals, toward) -> np.ndarray:
    """Unit normal of each disc, facing the point ``toward``.

    A normal given in ``normals`` is kept as it is (a disc can face away: the camera is then
    behind it).  Rows of NaN (unknown) take the normal of the plane through all the centres
    when they lie on one (three or more, not on a line), signed to face ``toward``; otherwise the
    direction from the disc to ``toward`` (a disc that faces the camera).

    Parameters
    ----------
    centres : array_like, shape (N, 3)
        Disc centres.
    normals : array_like, shape (N, 3), or None
        Known normals, NaN rows where unknown; None when none is known.
    toward : array_like, shape (3,)
        The camera's centre, same frame.

    Returns
    -------
    ndarray, shape (N, 3)
        Unit normals.
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    out = np.full_like(c, np.nan) if normals is None else np.array(normals, float).reshape(-1, 3)
    known = finite_rows(out)
    out /= np.linalg.norm(out, axis=1, keepdims=True)  # (NaN rows stay NaN)
    if all(known):
        return out
    known = np.array(known)
    to_cam = np.asarray(toward, dtype=float).reshape(3) - c
    plane = None
    if c.shape[0] >= 3:
        _, s, vt = np.linalg.svd(c - c.mean(axis=0), full_matrices=False)  # vt: 3 x 3
        # a plane: not all on a line, and every centre on it (within 1 % of the spread)
        if s[1] > 1e-9 * max(s[0], 1e-300) and s[2] <= 0.01 * s[0]:
            plane = vt[2]
    if plane is not None:
        sign = np.where(to_cam @ plane >= 0, 1.0, -1.0)
        out[~known] = sign[~known, None] * plane
    else:
        dist = np.linalg.norm(to_cam, axis=1, keepdims=True)
        facing = np.divide(to_cam, dist, out=np.tile([0.0, 0.0, 1.0], (len(c), 1)), where=dist > 0)
        out[~known] = facing[~known]
    return out


def perspective_offset(camera: Camera, pose: Pose, centre, diameter: float, normal) -> np.ndarray:
    """Offset of a disc's image (an ellipse) centre from its centre's projection, pixels.

    Under perspective the centre of a circle's image is not the image of its centre; the
    locator subtracts this offset from each detected centre before the final solve.

    Parameters
    ----------
    camera, pose : Camera, Pose
        The camera and its pose in the map frame.
    centre : array_like, shape (3,)
        The disc's centre, map units.
    diameter : float
        Its diameter, map units.
    normal : array_like, shape (3,)
        Its normal.

    Returns
    -------
    ndarray, shape (2,)
        ``ellipse centre - projected centre``, pixels; zeros when the rim is not all in front.
    """
    return perspective_offsets(camera, pose, centre, [diameter], normal)[0]


def perspective_offsets(camera: Camera, pose: Pose, centres, diameters, normals) -> np.ndarray:
    """:func:`perspective_offset` of several discs at once (one projection for all).

    Parameters
    ----------
    camera, pose : Camera, Pose
        The camera and its pose in the map frame.
    centres : array_like, shape (N, 3)
        The discs' centres, map units.
    diameters : array_like, shape (N,)
        Their diameters, map units.
    normals : array_like, shape (N, 3)
        Their normals.

    Returns
    -------
    ndarray, shape (N, 2)
        ``ellipse centre - projected centre`` of each disc, pixels; zeros for a disc whose rim
        is not all in front.

    Notes
    -----
    Without lens distortion the image of a disc is exactly an ellipse, whose centre is given
    in closed form (:func:`_pinhole_offsets`).  With distortion the rim is projected at 72
    points and an ellipse fitted to them (:func:`cv2.fitEllipse`).
    """
    if camera.dist_or_none is None:
        return _pinhole_offsets(camera, pose, centres, diameters, normals)
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    n_rim = 72
    rim = rim_points(c, diameters, np.asarray(normals, float).reshape(-1, 3), n_rim)
    pts = np.concatenate([c[:, None, :], rim], axis=1)  # (N, 1 + n_rim, 3): centre, rim
    uv = camera.project(pose, pts.reshape(-1, 3)).reshape(c.shape[0], 1 + n_rim, 2)
    out = np.zeros((c.shape[0], 2))
    finite = np.all(np.isfinite(uv), axis=(1, 2))
    rim_uv = uv[:, 1:].astype(np.float32)
    for k in np.flatnonzero(finite).tolist():
        (cx, cy), _, _ = cv2.fitEllipse(rim_uv[k])
        out[k] = (cx - uv[k, 0, 0], cy - uv[k, 0, 1])
    return out


def _pinhole_offsets(camera: Camera, pose: Pose, centres, diameters, normals) -> np.ndarray:
    """:func:`perspective_offsets` for a camera without distortion, in closed form.

    A disc of radius ``r``, centre ``C`` and unit normal ``n`` (camera frame) is the image
    under ``H = K [r a, r b, C]`` of the unit circle (``a``, ``b`` spanning its plane).  The
    centre of an image conic is the pole of the line at infinity, ``H diag(1, 1, -1) H^T
    (0, 0, 1)``, which is ``K (C_z C - r^2 (z - n_z n))`` with ``z = (0, 0, 1)``: the ellipse's
    centre, exact (a fit to sampled rim points is off by up to about 1e-3 px).  A disc whose
    rim reaches behind the camera (``C_z <= r sqrt(1 - n_z^2)``) gets zeros.
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    r = 0.5 * np.asarray(diameters, dtype=float).reshape(-1)
    cc = pose.to_camera(c)
    nc = n @ pose.world_from_camera  # normals in the camera frame
    w = -nc[:, 2:3] * nc
    w[:, 2] += 1.0  # z - n_z n: the optical axis' part in the disc's plane
    e = cc[:, 2:3] * cc - (r * r)[:, None] * w
    # rims in front (a NaN normal's rim is not)
    front = cc[:, 2] > r * np.sqrt(np.maximum(1.0 - nc[:, 2] * nc[:, 2], 0.0))
    k = camera.matrix
    if front.all():  # (as usual: every disc, no rows picked)
        return _centre_shifts(e, cc, k)
    out = np.zeros((c.shape[0], 2))
    if front.any():
        out[front] = _centre_shifts(e[front], cc[front], k)
    return out


def _centre_shifts(e: np.ndarray, cc: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The pixels of the ellipses' centres ``K e`` less those of the discs' centres ``K cc``
    (both (M, 3), camera frame), (M, 2)."""
    he, hc = e @ k.T, cc @ k.T
    return he[:, :2] / he[:, 2:] - hc[:, :2] / hc[:, 2:]


#: Smallest centre uncertainty an ellipse fit is credited with, pixels (1-sigma per axis):
#: the fit cannot see errors common to all its edge points (the disc's own outline, the
#: perspective correction), so a perfect fit never weighs infinitely.
CENTRE_SIGMA_FLOOR_PX = 0.01


def ellipse_centre_covariance(points, centre, axes, angle_deg: float, groups=None) -> np.ndarray:
    """Covariance of a fitted ellipse's centre, from the scatter of the points about it.

    The points' geometric (Sampson) distances from the ellipse, linearised in the five
    parameters (centre, semi-axes, angle) as ``J`` (M, 5), give the cluster-robust
    ("sandwich") covariance ``B (sum_g s_g s_g^T) B`` with ``B = (J^T J)^-1`` and
    ``s_g = J_g^T d_g`` the summed score of group ``g``: points of one group share their
    errors (the two ends of one sensor row see the same exposure, so a row's chord comes out
    too wide or too narrow as a whole), points of different groups do not, and each group's
    errors may have a spread of its own.  An error common to a row's two ends moves the
    centre along the row not at all and across it according to where the row lies, which
    is what this measures.  It also reflects how the points sit around the rim (a rim seen
    only in part fixes its centre less well).  Errors that every point shares (the disc's
    own outline, the perspective correction) are not seen.

    Parameters
    ----------
    points : array_like, shape (M, 2)
        The edge points fitted, pixels, M >= 6.
    centre : array_like, shape (2,)
        The fitted centre, same pixels.
    axes : array_like, shape (2,)
        Full lengths of the axes, as :func:`cv2.fitEllipse` gives them (first along
        ``angle_deg``).
    angle_deg : float
        Orientation of the first axis, degrees (OpenCV's convention).
    groups : array_like, shape (M,), optional
        A label per point; points with the same label share their errors.  Default: every
        point alone.

    Returns
    -------
    ndarray, shape (2, 2)
        Covariance of ``(u, v)``, pixels squared; NaN when it cannot be told (fewer than six
        points or groups, or a degenerate fit).
    """
    return ellipse_centre_covariances([(points, centre, axes, angle_deg, groups)])[0]


def ellipse_centre_covariances(fits) -> np.ndarray:
    """:func:`ellipse_centre_covariance` of several fitted ellipses at once.

    The ellipses' points are padded to the longest and worked as one stack, so that the
    cost of a photo's discs is that of one (the padding adds nothing to any sum).

    Parameters
    ----------
    fits : sequence of tuple
        ``(points, centre, axes, angle_deg, groups)`` per ellipse, each as
        :func:`ellipse_centre_covariance` takes them (``groups`` may be None).

    Returns
    -------
    ndarray, shape (N, 2, 2)
        Each centre's covariance, pixels squared; NaN for those that cannot be told.
    """
    n = len(fits)
    out = np.full((n, 2, 2), np.nan)
    pts = [np.asarray(f[0], dtype=float).reshape(-1, 2) for f in fits]
    sizes = [p.shape[0] for p in pts]
    labels, n_groups, span = _group_labels([f[4] for f in fits], sizes)
    # each fit's centre, semi-axes and angle (radians), in Python floats: NumPy's values
    p0 = [
        [*map(float, f[1][:2]), *(0.5 * float(v) for v in f[2][:2]), math.radians(float(f[3]))]
        for f in fits
    ]
    k = [
        i
        for i, p in enumerate(p0)
        if n_groups[i] >= 6 and all(map(math.isfinite, p)) and min(p[2], p[3]) > 0
    ]
    if not k:
        return out
    m_max = max(sizes[i] for i in k)
    # the fits worked, padded to the longest by a point of their own (a finite distance)
    xy = np.empty((len(k), m_max, 2))
    lab = np.zeros((len(k), m_max), dtype=np.int64)
    for j, i in enumerate(k):
        m = sizes[i]
        xy[j, :m], xy[j, m:] = pts[i], pts[i][0]
        lab[j, :m] = labels[i]
    sizes_k = np.array([sizes[i] for i in k], dtype=float)
    groups_k = np.array([n_groups[i] for i in k], dtype=float)
    real = np.arange(m_max)[None, :] < sizes_k[:, None]  # (K, M): not padding
    ellipses = np.array([p0[i] for i in k])
    d, jac = sampson_distances(ellipses, xy[:, :, 0], xy[:, :, 1])  # (K, M), (K, M, 5)
    d *= real
    jac *= real[:, :, None]
    jtj = jac.transpose(0, 2, 1) @ jac
    good = np.isfinite(jtj).all(axis=(1, 2))
    # np.linalg.cond(jtj) <= 1e12: J^T J is symmetric, its singular values its |eigenvalues|;
    # its inverse from the same eigenvectors (one LAPACK call for both)
    eig, vec = np.linalg.eigh(jtj[good])
    size = np.abs(eig)
    low = size.min(axis=1)
    well = (size.max(axis=1) <= 1e12 * low) & (low > 0)
    good[good] = well
    # each group's summed score, (K, G, 5), in the points' order (the padding adds zeros;
    # a label no point has, a group of zeros, adds nothing to the meat)
    scores = np.bincount(
        (5 * (lab + span * np.arange(len(k))[:, None])[:, :, None] + np.arange(5)).ravel(),
        weights=(jac * d[:, :, None]).ravel(),
        minlength=5 * span * len(k),
    ).reshape(len(k), span, 5)
    # small-sample factor of the cluster-robust estimator (CR1)
    scale = groups_k / (groups_k - 1) * (sizes_k - 1) / np.maximum(sizes_k - 5, 1)
    kk = good.nonzero()[0]
    eig, vec = eig[well], vec[well]
    bread = (vec / eig[:, None, :]) @ vec.transpose(0, 2, 1)  # V diag(1 / eig) V^T
    meat = scores[kk].transpose(0, 2, 1) @ scores[kk]
    out[np.array(k)[kk]] = (scale[kk, None, None] * bread @ meat @ bread)[:, :2, :2]
    return out


def sampson_distances(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sampson distances of points from ellipses, and their derivatives in the ellipses'
    parameters: a first-order approximation of each point's distance from its ellipse.

    With ``(u, v)`` a point in the ellipse's axes, ``P = u / a^2``, ``Q = v / b^2``, the
    distance is ``d = (u P + v Q - 1) / (2 g)``, ``g = hypot(P, Q)``; moving the centre or
    the angle changes ``(u, v)`` only, by which ``d`` changes by ``alpha du + beta dv``.

    Parameters
    ----------
    p : ndarray, shape (K, 5)
        Each ellipse's centre ``(cx, cy)`` and semi-axes ``(a, b)``, pixels, and the angle of
        its ``a`` axis, radians.
    x, y : ndarray, shape (K, M)
        The points' coordinates, pixels: ``M`` points for each ellipse.

    Returns
    -------
    d : ndarray, shape (K, M)
        Signed distances (positive outside), pixels.
    jac : ndarray, shape (K, M, 5)
        Their derivatives with respect to ``(cx, cy, a, b, angle)``.
    """
    c, s = np.cos(p[:, 4:5]), np.sin(p[:, 4:5])
    dx, dy = x - p[:, 0:1], y - p[:, 1:2]
    u, v = c * dx + s * dy, c * dy - s * dx
    ia, ib = 1.0 / p[:, 2:3], 1.0 / p[:, 3:4]
    a2, b2 = ia * ia, ib * ib  # 1 / a^2, 1 / b^2
    pp, qq = u * a2, v * b2
    ig = 1.0 / np.hypot(pp, qq)
    d = 0.5 * (u * pp + v * qq - 1.0) * ig
    e = d * ig
    alpha = pp * (1.0 - e * a2) * ig  # dd/du
    beta = qq * (1.0 - e * b2) * ig  # dd/dv
    jac = np.empty((*d.shape, 5))
    jac[..., 0] = s * beta - c * alpha  # du/dcx = -c, dv/dcx = s
    jac[..., 1] = -s * alpha - c * beta  # du/dcy = -s, dv/dcy = -c
    jac[..., 2] = -pp * ia * ig * (u - 2.0 * e * pp)
    jac[..., 3] = -qq * ib * ig * (v - 2.0 * e * qq)
    jac[..., 4] = alpha * v - beta * u  # du/dt = v, dv/dt = -u
    return d, jac


def _group_labels(groups: list, sizes: list[int]) -> tuple[list, list[int], int]:
    """Each fit's points' group labels as small non-negative integers (``None``: every point
    alone; other labels ranked among their distinct values, NumPy's ``np.unique(...,
    return_inverse=True)``), how many distinct groups each fit has, and one more than the
    largest label (the labels' span).  Non-negative integer labels are kept as they are: a
    label no point has is an empty group, which adds nothing to a sum over groups."""
    out = [
        np.arange(m) if g is None else np.asarray(g).reshape(-1)
        for m, g in zip(sizes, groups, strict=True)
    ]
    if not any(g.size for g in out):
        return out, [0] * len(out), 1
    # every fit's lowest and highest label at once (a fit without points: none)
    n = np.array([g.size for g in out])
    whole = [g.dtype.kind in "iu" for g in out]
    flat = np.concatenate(
        [g if ok else np.zeros(g.size, np.int64) for g, ok in zip(out, whole, strict=True)]
    )
    first = (n.cumsum() - n)[n > 0]
    low, high = (np.zeros(len(out), np.int64) for _ in range(2))
    low[n > 0], high[n > 0] = np.minimum.reduceat(flat, first), np.maximum.reduceat(flat, first)
    for i in ((low < 0) | (high > 4 * n + 64) | ~np.array(whole)).nonzero()[0].tolist():
        if n[i]:
            out[i] = np.unique(out[i], return_inverse=True)[1].reshape(-1)
            high[i] = out[i].max()
    span = int(high.max()) + 1
    # the distinct labels of each fit: one count of them all, each fit's after the previous'
    counts = np.bincount(
        np.concatenate(out).astype(np.int64) + span * np.arange(len(out)).repeat(n),
        minlength=span * len(out),
    )
    return out, np.count_nonzero(counts.reshape(len(out), span), axis=1).tolist(), span


def centre_sigma(cov) -> float:
    """One uncertainty of a centre from its covariance: the RMS of its two axes' sigmas,
    pixels, at least :data:`CENTRE_SIGMA_FLOOR_PX`; NaN when the covariance is unknown.

    Parameters
    ----------
    cov : array_like, shape (2, 2)
        Covariance of the centre, pixels squared.
    """
    var = 0.5 * float(np.trace(np.asarray(cov, dtype=float).reshape(2, 2)))  # (half the trace)
    if not math.isfinite(var):
        return float("nan")
    return max(CENTRE_SIGMA_FLOOR_PX, math.sqrt(max(var, 0.0)))
