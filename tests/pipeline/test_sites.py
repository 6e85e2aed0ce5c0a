"""Maps whose IDs repeat (``frame: reuse: true``): photos placed by their lights' IDs and
geometry (camvlp.pipeline.identify.by_geometry), refused when the place is ambiguous, and a
prior that narrows the search."""

from __future__ import annotations

import csv
import itertools
import json
import math
import re

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from tests.conftest import one_error_line

from camvlp import locate
from camvlp.cli import main
from camvlp.geometry.hypotheses import distance_bounds
from camvlp.io import save_camera, save_map
from camvlp.model.camera import Camera, Pose
from camvlp.pipeline.identify import by_geometry
from camvlp.pipeline.identify.placement import PLAIN_SLACK, LightsWithIds
from camvlp.pipeline.settings import LocateSettings
from camvlp.sim.render import RenderSettings, render
from camvlp.sim.site import site_map

#: 640 x 480, f = 400 px, 25 us rows, read top down; 16 kHz chips: 2.5 rows a chip.
ROW_TIME_S, CHIP_RATE_HZ = 25e-6, 16_000.0
#: The site: 20 x 10 fixtures 1 m apart, 0.5 m discs on a 4 m ceiling, the thesis' 4-bit IDs.
SITE = dict(spacing=1.0, height=4.0, diameter=0.5)


def site_camera() -> Camera:
    return Camera.from_focal(640, 480, 400.0, row_time_s=ROW_TIME_S, readout="rows")


def photo(fixture_map, pose: Pose, seed: int) -> np.ndarray:
    settings = RenderSettings(chip_rate_hz=CHIP_RATE_HZ, row_time_s=ROW_TIME_S, seed=seed)
    return render(site_camera(), fixture_map, pose, settings).image


def pose_at(x: float, y: float, z: float, heading: float, tilt=(0.0, 0.0)) -> Pose:
    """A camera at (x, y, z) looking up (+z), turned ``heading`` degrees about the vertical
    and tilted by ``tilt`` (degrees about its x and y)."""
    r = Rotation.from_euler("zxy", [heading, *tilt], degrees=True).as_matrix()
    return Pose(r, np.array([x, y, z]))


@pytest.fixture(scope="module")
def varied():
    """The site with IDs no two within two grid steps alike (seed 0): 200 fixtures, 16 IDs."""
    return site_map(20, 10, pattern="varied", seed=0, **SITE)


@pytest.fixture(scope="module")
def periodic():
    """The same site with the IDs repeated every four grid steps: no photo tells its place."""
    return site_map(20, 10, pattern="periodic", **SITE)


@pytest.fixture(scope="module")
def periodic_photo(periodic):
    """A photo of the periodic site from (9.3, 4.4, 1.3), and that pose."""
    pose = pose_at(9.3, 4.4, 1.3, 20.0)
    return photo(periodic, pose, seed=3), pose


def test_the_site_reuses_its_ids(varied):
    assert len(varied.fixtures) == 200 and varied.reuse
    assert sorted(varied.distinct_ids) == list(range(16))
    assert all(varied.with_id(i).size >= 8 for i in range(16))
    assert varied.get(3) is None  # an ID of many fixtures names none


@pytest.mark.parametrize(
    "where",
    [(4.3, 3.2, 1.2, 35.0, (5.0, -4.0), 11), (15.6, 6.1, 1.6, 250.0, (-8.0, 3.0), 12)],
)
def test_a_photo_is_located_at_its_place(varied, where):
    *xyz, heading, tilt, seed = where
    pose = pose_at(*xyz, heading, tilt)
    result = locate(photo(varied, pose, seed), site_camera(), varied)
    assert result, result.reason
    assert np.linalg.norm(result.position - pose.position) < 0.05
    # every fixture reported is the one of the map with that ID the camera sees there (a
    # disc cut by the border, not used, is centred off)
    where_px = site_camera().project(pose, varied.positions)
    for f in result.fixtures:
        if f.id is not None:
            off = np.sort(np.hypot(*(where_px[varied.with_id(f.id)] - f.pixel).T))
            assert off[0] < (5.0 if f.used else 60.0) and off[1] > 200.0
    assert sum(f.used for f in result.fixtures) >= 5


@pytest.fixture(scope="module")
def periodic_files(tmp_path_factory, periodic, periodic_photo):
    """The periodic site's map, the camera and the photo as files (for ``camvlp locate``)."""
    d = tmp_path_factory.mktemp("site")
    save_map(periodic, d / "site.yaml")
    save_camera(site_camera(), d / "camera.yaml")
    cv2.imwrite(str(d / "photo.png"), periodic_photo[0])
    return [str(d / "photo.png"), "--camera", str(d / "camera.yaml"), "--map", str(d / "site.yaml")]


def test_an_ambiguous_place_is_refused_listing_the_places(capsys, periodic_files, periodic_photo):
    code = main(["locate", *periodic_files, "--json"])
    out, err = capsys.readouterr()
    assert code == 1
    line = one_error_line(err)
    result = json.loads(out)
    assert result["position"] is None and not any(f["used"] for f in result["fixtures"])
    reason = result["error"]
    assert reason in line and reason.startswith("ambiguous: ")
    assert "places of the map fit" in reason and "a prior" in reason
    # the places listed lie a whole number of the pattern's periods (4 m) from the truth
    listed = np.array(re.findall(r"\((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\)", reason), float)
    assert len(listed) >= 2
    for p in listed:
        off = p - periodic_photo[1].position
        assert np.allclose(off[1:], 0.0, atol=0.05) and abs(off[0] / 4 - round(off[0] / 4)) < 0.02


def test_a_prior_tells_the_places_apart(capsys, periodic_files, periodic_photo):
    code = main(["locate", *periodic_files, "--json", "--near", "9,4", "--within", "1.5"])
    out, err = capsys.readouterr()
    assert code == 0, err
    position = np.array(json.loads(out)["position"])
    assert np.linalg.norm(position - periodic_photo[1].position) < 0.05
    # the prior's two halves go together
    assert main(["locate", *periodic_files, "--near", "9,4"]) == 2
    assert "--near and --within go together" in one_error_line(capsys.readouterr()[1])
    assert main(["locate", *periodic_files, "--near", "9", "--within", "1"]) == 2
    assert "--near must be 2 comma-separated numbers" in one_error_line(capsys.readouterr()[1])


def test_a_prior_that_holds_no_place_is_refused(periodic, periodic_photo):
    image, _ = periodic_photo
    result = locate(image, site_camera(), periodic, LocateSettings(near=(11.0, 4.0), within=1.0))
    assert not result
    assert result.reason.startswith("no place of the map within 1 m of the prior fits")


def test_a_photo_of_another_site_is_refused_not_placed(varied):
    # the same grid with its IDs drawn again: the photo's arrangement of IDs is nowhere
    other = site_map(20, 10, pattern="varied", seed=1, **SITE)
    result = locate(photo(varied, pose_at(6.4, 5.3, 1.4, 120.0), 5), site_camera(), other)
    assert not result and result.position is None
    assert result.reason.startswith("no place of the map fits its ")


def test_the_distance_bounds_hold_the_true_distance():
    rng = np.random.default_rng(4)
    for _ in range(200):
        r1, r2 = rng.uniform(0.5, 10.0, 2)
        u, v = rng.normal(size=(2, 3))
        u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
        cos = float(u @ v)
        true = np.linalg.norm(r1 * u - r2 * v)
        for slack in (1.0, 1.5):
            lo, hi = distance_bounds((r1 / slack, r1 * slack), (r2 / slack, r2 * slack), cos)
            assert lo - 1e-9 <= true <= hi + 1e-9
        lo, hi = distance_bounds((r1, r1), (r2, r2), cos)  # exact distances: the bounds meet
        assert lo == pytest.approx(true) and hi == pytest.approx(true)
    assert distance_bounds((1.0, np.inf), (1.0, 2.0), 0.5) == (0.0, np.inf)


def _bounds_of_one_pair(a, b, cos):
    """The least and greatest distance of two points at distances within ``a`` and ``b``
    seen ``arccos(cos)`` apart, pair by pair in plain Python: the least over a fine grid of
    both distances (an upper bound of it, close), the greatest at a corner."""

    def d(r1, r2):
        return math.sqrt(max(r1 * r1 + r2 * r2 - 2 * r1 * r2 * cos, 0.0))

    if not (math.isfinite(a[1]) and math.isfinite(b[1])):
        return 0.0, math.inf
    grid = [
        (a[0] + (a[1] - a[0]) * i / 200, b[0] + (b[1] - b[0]) * j / 200)
        for i in range(201)
        for j in range(201)
    ]
    return min(d(r1, r2) for r1, r2 in grid), max(d(r1, r2) for r1 in a for r2 in b)


def test_distance_bounds_of_arrays_are_those_of_each_pair():
    rng = np.random.default_rng(5)
    r1, r2 = rng.uniform(0.5, 10.0, (2, 6, 1)), rng.uniform(0.5, 10.0, (2, 1, 7))
    cos = rng.uniform(-1.0, 1.0, (6, 7))
    r2[1, 0, 3] = np.inf  # (a greatest distance unknown: that pair's bounds are (0, inf))
    lo, hi = distance_bounds((r1[0], r1[0] + r1[1]), (r2[0], r2[0] + r2[1]), cos)
    assert lo.shape == hi.shape == (6, 7)
    for i, j in itertools.product(range(6), range(7)):
        a, b = (r1[0, i, 0], r1[0, i, 0] + r1[1, i, 0]), (r2[0, 0, j], r2[0, 0, j] + r2[1, 0, j])
        want = _bounds_of_one_pair(a, b, float(cos[i, j]))
        assert distance_bounds(a, b, float(cos[i, j])) == (lo[i, j], hi[i, j])
        assert hi[i, j] == pytest.approx(want[1]) or hi[i, j] == want[1] == np.inf
        assert lo[i, j] <= want[0] + 1e-12 and lo[i, j] >= want[0] - 0.05 * (a[1] + b[1])
    lo, hi = distance_bounds((1.0, np.array([1.5, 2.5])), (1.0, 2.0), 0.5)  # (ends of 2 shapes)
    assert lo.shape == (2,) and hi[1] == pytest.approx(
        _bounds_of_one_pair((1, 2.5), (1, 2), 0.5)[1]
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_hypotheses_are_every_four_fixtures_the_distances_allow(varied, seed):
    """``_quads`` (searched in the order it picks) against every four fixtures of the seeds'
    IDs checked pair by pair: the same sets, in any order the seeds are given."""
    rng = np.random.default_rng(seed)
    pose = pose_at(*rng.uniform([4, 3, 1.0], [16, 7, 1.6]), rng.uniform(0, 360))
    pos = varied.positions
    near = np.flatnonzero(np.hypot(*(pos[:, :2] - pose.position[:2]).T) < 2.5)
    seen = rng.choice(near, 6, replace=False)
    cam = (pos[seen] - pose.position) @ pose.world_from_camera  # (the camera's frame)
    dist = np.linalg.norm(cam, axis=1)
    rho = dist * rng.uniform(0.9, 1.1, len(cam))  # (the discs' sizes say roughly)
    lights = LightsWithIds(
        np.arange(6),
        varied.id_array[seen],
        np.zeros((6, 2)),
        cam / dist[:, None],
        rho,
        3 * rho,
        PLAIN_SLACK,
    )
    bounds = by_geometry._pair_bounds(lights)
    allowed = np.ones(len(varied.fixtures), dtype=bool)
    seeds = (0, 2, 3, 5)
    want = []
    ids = lights.ids
    for quad in itertools.product(*(np.flatnonzero(varied.id_array == ids[s]) for s in seeds)):
        if len(set(quad)) < 4:
            continue
        lo, hi = 1 / PLAIN_SLACK[0], PLAIN_SLACK[1]
        for (a, fa), (b, fb) in itertools.combinations(zip(seeds, quad, strict=True), 2):
            d = np.linalg.norm(pos[fa] - pos[fb])
            lo = max(lo, d / bounds[1][a, b])
            hi = min(hi, d / bounds[0][a, b] if bounds[0][a, b] > 0 else np.inf)
        if lo <= hi:
            want.append(quad)
    assert tuple(seen[list(seeds)]) in want  # (the true fixtures among them)
    for order in itertools.permutations(range(4)):
        got = by_geometry._quads(varied, lights, [seeds[o] for o in order], allowed, bounds)
        back = got[:, np.argsort(order)]
        assert sorted(map(tuple, back.tolist())) == sorted(want)
        assert np.array_equal(got, got[np.lexsort(got.T[::-1])])  # (rows in lexical order)


def test_the_prior_needs_both_parts():
    from camvlp.errors import InputError

    with pytest.raises(InputError, match="near and within go together"):
        LocateSettings(near=(1.0, 2.0))
    with pytest.raises(InputError, match="near must be 2 or 3"):
        LocateSettings(near=(1.0,), within=2.0)
    with pytest.raises(InputError, match="within must be a positive"):
        LocateSettings(near=(1.0, 2.0), within=-1.0)
    assert LocateSettings(near=[1, 2, 3], within=2).near == (1.0, 2.0, 3.0)


@pytest.fixture(scope="module")
def periodic_video(periodic):
    """14 frames (10 per s) of a camera 2.65 to 2.7 m under the periodic site's ceiling,
    moving 0.6 m and turning 6.5 degrees: each alone fits several places of the site."""
    from camvlp.sim.trajectory import Trajectory
    from camvlp.sim.video import iter_frames

    traj = Trajectory(
        np.array([0.0, 1.3]),
        np.array([[8.3, 3.2, 1.3], [8.9, 3.45, 1.33]]),
        np.array([[1.0, -2.0, 35.0], [-0.3, 0.6, 41.5]]),
    )
    render_settings = RenderSettings(chip_rate_hz=CHIP_RATE_HZ, row_time_s=ROW_TIME_S, seed=4)
    return list(iter_frames(site_camera(), periodic, traj, 10.0, render_settings))


def test_a_video_is_tracked_in_a_map_whose_ids_repeat(periodic, periodic_video):
    """Frames 4 to 9 dark (0.6 s, longer than the track outlives without a measurement):
    the first frame is placed by the prior given, the next ones by the track's pose, and
    those after the dark ones near the track's last place."""
    from camvlp.pipeline.track.tracker import Tracker, TrackSettings

    frames = periodic_video
    prior = LocateSettings(near=(8.0, 3.5), within=1.0)
    tracker = Tracker(site_camera(), periodic, TrackSettings(locate=prior))
    results = []
    for k, f in enumerate(frames):
        r = tracker.update(np.zeros_like(f.image) if 4 <= k < 10 else f.image, f.t)
        for b in r.fixtures:  # each ID given is that of the fixture there
            if b.id is not None:
                d = [np.hypot(*(np.nan_to_num(t.pixel, nan=1e9) - b.pixel)) for t in f.fixtures]
                assert b.id == f.fixtures[int(np.argmin(d))].id, (k, b)
        if r.status in ("fix", "tracked"):
            assert np.linalg.norm(r.position - f.pose.position) < 0.02, (k, r.position)
        results.append(r)
    # plain discs, some cut by the border under a dark stripe: no path for glowing lamps,
    # and the photo-wide parameters carried (lights sending IDs of fixtures out of the
    # track's view are read, not left for a refit)
    for r in results[2:]:
        assert not {"radial fit", "glows taken apart", "photo-wide model"} & set(r.paths)
    statuses = [r.status for r in results]
    assert statuses[:4] == ["fix"] * 4, statuses
    assert statuses[9] == "lost", statuses
    assert statuses[10:] == ["fix"] * 4, statuses
    # the frame placed again fits several places of the site alone
    alone = locate(frames[10].image, site_camera(), periodic)
    assert not alone and alone.reason.startswith("ambiguous"), alone.reason


def test_camvlp_track_takes_a_prior_in_a_map_whose_ids_repeat(periodic, periodic_video, tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, f in enumerate(periodic_video[:3]):
        cv2.imwrite(str(folder / f"{k:03d}.png"), f.image)
    save_map(periodic, tmp_path / "site.yaml")
    save_camera(site_camera(), tmp_path / "camera.yaml")
    files = ["--camera", str(tmp_path / "camera.yaml"), "--map", str(tmp_path / "site.yaml")]
    args = ["track", str(folder), *files, "--fps", "10", "--json"]
    assert main([*args, "--out", str(tmp_path / "alone")]) == 1  # ambiguous: not located
    code = main([*args, "--out", str(tmp_path / "out"), "--near", "8,3.5", "--within", "1"])
    assert code == 0
    with (tmp_path / "out" / "trajectory.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["fix"] * 3, rows


def test_a_site_frame_that_fits_no_place_is_not_located(periodic, periodic_photo):
    from camvlp.pipeline.track.tracker import Tracker

    r = Tracker(site_camera(), periodic).update(periodic_photo[0], 0.0)
    assert r.status == "lost" and r.position is None
    # the frame says why, as locate says it of the photo
    assert r.reason == locate(periodic_photo[0], site_camera(), periodic).reason
    assert r.reason.startswith("ambiguous: 5 places of the map fit"), r.reason
    assert not any(b.used for b in r.fixtures)
    assert all(b.id is None or b.reason for b in r.fixtures)


def test_a_site_track_starts_near_the_prior_given(periodic, periodic_photo):
    from camvlp.pipeline.track.tracker import Tracker, TrackSettings

    image, pose = periodic_photo
    near = LocateSettings(near=tuple(pose.position[:2] + 0.3), within=1.0)
    r = Tracker(site_camera(), periodic, TrackSettings(locate=near)).update(image, 0.0)
    assert r.status == "fix", r.reason
    assert np.linalg.norm(r.position - pose.position) < 0.05


def test_the_view_map_keeps_each_id_once_the_one_in_the_picture():
    from camvlp.model.fixtures import Fixture, FixtureMap
    from camvlp.pipeline.identify.placement import view_map

    cam, pose = site_camera(), pose_at(0.0, 0.0, 1.5, 0.0)  # 2.5 m under the ceiling
    # f = 400 px: 1 m is 160 px. Within 2 m of the centre a fixture is in the 640-px
    # picture, 2.2 m is in the margin (a tenth of the width) only, 3 m beyond both.
    spots = {0: [0.0, 1.0], 1: [0.0, 3.0], 2: [-1.0, 2.2], 3: [1.0, -1.0]}
    fixtures = tuple(
        Fixture(fid, np.array([x, -0.9 + 0.6 * fid, 4.0]), 0.3, np.array([0.0, 0.0, -1.0]))
        for fid, xs in spots.items()
        for x in xs
    )
    site = FixtureMap(fixtures, reuse=True)
    out = view_map(site, cam, pose, np.arange(len(fixtures)))
    assert not out.reuse
    kept = {f.id: float(f.position[0]) for f in out.fixtures}
    # ID 0 in the picture twice: neither; ID 1 once in it; ID 2 in it, its twin only in the
    # margin; ID 3 twice in it: neither
    assert kept == {1: 0.0, 2: -1.0}
    # a fixture a light was found to be comes first (the second of ID 0)
    taken = view_map(site, cam, pose, np.arange(len(fixtures)), taken=[1])
    assert {f.id: float(f.position[0]) for f in taken.fixtures}[0] == 1.0


def _disc_outline(camera: Camera, pose: Pose, centre, normal, diameter: float):
    """A disc's image: its centre pixel, its outline's full axes (major first, by
    cv2.fitEllipse of 360 projected rim points) and its filled outline as a mask."""
    from types import SimpleNamespace

    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    t = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    rim = centre + 0.5 * diameter * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b)
    from camvlp.model.camera import project_points

    px = project_points(camera, pose, rim)
    (cx, cy), axes, _ = cv2.fitEllipse(px.astype(np.float32))
    x0, y0 = np.floor(px.min(axis=0)).astype(int) - 2
    mask = np.zeros((int(px[:, 1].max()) - y0 + 3, int(px[:, 0].max()) - x0 + 3), np.uint8)
    cv2.fillPoly(mask, [np.round(px - [x0, y0]).astype(np.int32)], 1)
    return SimpleNamespace(
        pixel=np.array([cx, cy]), axes_px=np.sort(axes)[::-1], mask=mask.astype(bool)
    )


@pytest.mark.parametrize("k1", [0.0, -0.15])
def test_a_disc_s_distance_is_read_from_its_size_whichever_way_it_faces(k1):
    # a ceiling's disc seen off the optical axis is stretched along the radial direction
    # (up to 1.8 times in a wide view): focal times diameter over the major axis took it for
    # one nearer; the disc model reads the distance whichever way the disc faces, through a
    # lens's distortion too (its local map at the disc)
    from camvlp.pipeline.identify.placement import disc_distances

    cam = Camera.from_focal(1920, 1440, 800.0, distortion=np.array([k1, 0.0, 0.0, 0.0, 0.0]))
    rng = np.random.default_rng(4)
    seen = 0
    for tilt in (0.0, 15.0):
        pose = Pose.from_euler([0.0, 0.0, 0.0], [tilt, -tilt / 2, 0.0])
        for _ in range(12):
            centre = np.array([*rng.uniform(-3.0, 3.0, 2), rng.uniform(3.0, 6.0)])
            ray = pose.to_camera(centre[None])[0]
            if abs(ray[0] / ray[2]) > 1.1 or abs(ray[1] / ray[2]) > 0.8:
                continue  # (out of the picture)
            for normal in ([0.0, 0.0, 1.0], pose.world_from_camera @ -ray, [0.3, -0.2, 1.0]):
                blob = _disc_outline(cam, pose, centre, normal, 0.4)
                flat = cv2.undistortPoints(
                    blob.pixel.reshape(1, 1, 2), cam.matrix, cam.dist_or_none
                )
                unit = np.array([*flat.reshape(2), 1.0])
                unit /= np.linalg.norm(unit)
                got = disc_distances(cam, [blob], unit[None], [0.4])[0]
                true = np.linalg.norm(centre - pose.position)
                assert got == pytest.approx(true, rel=0.02), (centre, normal, got, true)
                seen += 1
    assert seen >= 30
    blob = _disc_outline(
        cam, Pose.from_euler([0, 0, 0], [0, 0, 0]), [2.5, 1.5, 3.0], [0, 0, 1], 0.4
    )
    assert np.isinf(disc_distances(cam, [blob], np.array([[0.0, 0.0, 1.0]]), [0.0])[0])


def test_a_photo_of_lights_all_told_plain_holds_their_sizes_to_the_plain_slack():
    # a plain disc's outline is its rim, so its size gives the distance (the disc model)
    # and the scale between the two is held near 1; a glowing lamp's halo widens its
    # outline (the rough estimate, the wide slack), and lights not told either way are
    # taken as such too
    from types import SimpleNamespace

    from camvlp.pipeline.identify.placement import (
        DISTANCE_SLACK,
        PLAIN_SLACK,
        RELATIVE_SLACK,
        lights_with_ids,
    )
    from camvlp.pipeline.solve import PoseProblem

    fmap = site_map(6, 6, spacing=1.0, height=3.0, seed=2)
    cam = Camera.from_focal(1920, 1440, 800.0)
    pose = Pose.from_euler([2.5, 2.5, 1.0], [0.0, 0.0, 0.0])
    blobs, decodes = [], []
    for f in fmap.fixtures[:5]:
        b = _disc_outline(cam, pose, f.position, [0.0, 0.0, 1.0], f.diameter)
        blobs.append(SimpleNamespace(**vars(b), touches_border=False))
        decodes.append(SimpleNamespace(id=f.id, reason=""))
    for glowing, slack in (((False,) * 5, PLAIN_SLACK), ((False,) * 4 + (True,), DISTANCE_SLACK),
                           ((), DISTANCE_SLACK)):  # fmt: skip
        problem = PoseProblem(cam, fmap, tuple(blobs), LocateSettings(), 4.0, None, glowing)
        lights = lights_with_ids(problem, decodes)
        assert lights.slack == slack
        if slack == PLAIN_SLACK:  # the disc model: the distance along the ray
            true = np.linalg.norm(fmap.positions[:5] - pose.position, axis=1)
            assert np.allclose(lights.rho, true, rtol=0.02)
        else:  # a halo's outline: the focal length times the diameter over its major axis
            major = np.array([b.axes_px[0] for b in blobs])
            assert np.allclose(lights.rho, 800.0 * fmap.fixtures[0].diameter / major)
        assert np.allclose(lights.far, lights.rho * slack[1] * np.sqrt(RELATIVE_SLACK))
