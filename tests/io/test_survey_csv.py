"""Tests for camvlp.io.survey_csv: the survey file, written by the simulator, read back."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.io import InputError
from camvlp.io.survey_csv import SURVEY_COLUMNS, read_survey, write_survey


def test_read_survey_keeps_extra_columns_and_resolves_paths(tmp_path):
    path = tmp_path / "s.csv"
    path.write_text(
        "# a comment\nphoto, x, y, z, note\nsub/a.jpg,1,2,3,first\n\n/abs/b.jpg,4,5,6,second\n"
    )
    survey = read_survey(path)
    assert survey.photos == ("sub/a.jpg", "/abs/b.jpg")
    assert survey.positions.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert survey.euler_deg is None
    assert survey.extra_columns == ("note",) and survey.extra == (("first",), ("second",))
    assert survey.photo_path(0) == tmp_path / "sub" / "a.jpg"
    assert str(survey.photo_path(1)) == "/abs/b.jpg"
    path.write_text("photo,x,y,z\na.jpg,nan,0,0\n")
    with pytest.raises(InputError, match="finite"):
        read_survey(path)
    # within +-1e9 as every number of camera and map files (1e300 was evaluated as given)
    for row in ("a.jpg,1e300,0,0,90,0,0", "a.jpg,0,0,0,-1e12,0,0"):
        path.write_text(f"photo,x,y,z,theta_x,theta_y,theta_z\n{row}\n")
        with pytest.raises(InputError, match=r"within \+-1e\+09"):
            read_survey(path)


def test_some_but_not_all_angle_columns_are_refused(tmp_path):
    """theta_x and theta_y without theta_z: refused, not read as a survey without angles
    (whose orientation error evaluate then leaves out without a word)."""
    path = tmp_path / "s.csv"
    path.write_text("photo,x,y,z,theta_x,theta_y\na.jpg,0,0,0,90,0\n")
    with pytest.raises(InputError, match="theta_x, theta_y but not theta_z"):
        read_survey(path)


def test_a_written_survey_reads_back(tmp_path):
    pos = np.array([[0.1234567, -1.0, 2.0], [3.0, 4.0, -5.5]])
    eul = np.array([[90.0, 0.0, 12.34567], [70.0, 20.0, 0.0]])
    path = write_survey(tmp_path / "survey.csv", ["a.jpg", "b.png"], pos, eul, [7, 8])
    assert path.read_text().splitlines()[0] == ",".join(SURVEY_COLUMNS)
    survey = read_survey(path)
    assert survey.photos == ("a.jpg", "b.png")
    np.testing.assert_allclose(survey.positions, pos, atol=5e-7)
    np.testing.assert_allclose(survey.euler_deg, eul, atol=5e-5)
    assert survey.extra_columns == ("seed",) and survey.extra == (("7",), ("8",))


def test_writing_into_a_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot write the survey file"):
        write_survey(tmp_path / "no" / "survey.csv", ["a.jpg"], [[0, 0, 0]], [[0, 0, 0]], [0])
