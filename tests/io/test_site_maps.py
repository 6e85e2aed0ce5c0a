"""Maps whose IDs repeat (``frame: reuse: true``): read, written, refused without it, and their
spatial index."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from camvlp.io import InputError, load_map, save_map
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.site import site_map

TWICE = "  - {id: 5, position: [0, 0, 3]}\n  - {id: 5, position: [1, 0, 3]}\n"


def _map(tmp_path: Path, frame: str, body: str = TWICE) -> Path:
    path = tmp_path / "site.yaml"
    path.write_text(f"units: m\nframe: {{{frame}}}\nfixtures:\n{body}")
    return path


def test_a_repeated_id_is_an_error_without_reuse(tmp_path):
    for frame in ("id_bits: 4", "id_bits: 4, reuse: false"):
        with pytest.raises(InputError) as info:
            load_map(_map(tmp_path, frame))
        message = str(info.value)
        assert "\n" not in message and "site.yaml" in message
        assert "duplicate ID in fixture 5" in message and "reuse: true" in message
    with pytest.raises(ValueError, match="duplicate fixture ID 5"):
        FixtureMap((Fixture(5, [0, 0, 3]), Fixture(5, [1, 0, 3])))


def test_reuse_lets_an_id_name_many_fixtures(tmp_path):
    fmap = load_map(_map(tmp_path, "id_bits: 4, reuse: true"))
    assert fmap.reuse and fmap.ids == [5, 5] and fmap.distinct_ids == [5]
    assert fmap.with_id(5).tolist() == [0, 1] and fmap.with_id(6).size == 0
    assert fmap.get(5) is None  # an ID of two fixtures names neither
    # written and read back, it still says so; the same position twice is still refused
    save_map(fmap, tmp_path / "again.yaml")
    assert load_map(tmp_path / "again.yaml").reuse
    twin = "  - {id: 5, position: [0, 0, 3]}\n  - {id: 6, position: [0, 0, 3]}\n"
    with pytest.raises(InputError, match="fixtures 5 and 6 are both at position"):
        load_map(_map(tmp_path, "reuse: true", twin))


@pytest.mark.parametrize(
    ("frame", "words"),
    [
        ("reuse: yes please", "frame reuse must be true or false"),
        ("reusse: true", "did you mean 'reuse'"),
        ("mode: frequency, reuse: true", "reuse (one ID for many fixtures) needs the manchester"),
    ],
)
def test_a_malformed_reuse_is_one_clear_error(tmp_path, frame, words):
    body = TWICE.replace("}", ", frequency_hz: 100}") if "frequency" in frame else TWICE
    with pytest.raises(InputError, match=None) as info:
        load_map(_map(tmp_path, frame, body))
    assert words in str(info.value) and "\n" not in str(info.value)


def test_the_index_finds_the_fixtures_near_a_point():
    fmap = site_map(30, 20, spacing=2.0, height=5.0, seed=3)
    assert len(fmap.fixtures) == 600 and set(fmap.distinct_ids) == set(range(16))
    near = sorted(fmap.index.query_ball_point([10.0, 10.0, 5.0], 2.01))
    brute = np.flatnonzero(np.linalg.norm(fmap.positions - [10.0, 10.0, 5.0], axis=1) <= 2.01)
    assert near == brute.tolist() and len(near) == 5
    # no two fixtures within two grid steps (along both axes) share an ID
    for f in fmap.fixtures:
        close = fmap.index.query_ball_point(f.position, 2 * 2.0 * np.sqrt(2) + 1e-6)
        assert [fmap.fixtures[j].id for j in close].count(f.id) == 1
        assert len(close) == 25 or not (4 <= f.position[0] <= 54 and 4 <= f.position[1] <= 34)
    assert not fmap.positions.flags.writeable
