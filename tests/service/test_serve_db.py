"""Where ``camvlp serve`` keeps its database: the user's data folder unless --db or CAMVLP_DB
say otherwise; never the folder it runs in."""

from __future__ import annotations

from pathlib import Path

import pytest

from camvlp.cli import main
from camvlp.service import ServiceSettings
from camvlp.service.settings import database_url, default_db_url, sqlite_file
from conftest import one_error_line


@pytest.fixture
def elsewhere(tmp_path: Path, monkeypatch) -> Path:
    """A user whose data folder (XDG_DATA_HOME) and home are under ``tmp_path``, running in
    an empty folder ``tmp_path / "here"``, with no CAMVLP_DB; returns ``tmp_path``."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("CAMVLP_DB", raising=False)
    (tmp_path / "here").mkdir()
    monkeypatch.chdir(tmp_path / "here")
    return tmp_path


def test_the_default_database_is_in_the_user_data_folder(elsewhere: Path, capsys):
    """``camvlp serve`` (here its --migrate, which stops before serving) makes its database
    in $XDG_DATA_HOME/camvlp (the folder created) and says where; nothing in the folder it
    runs in."""
    assert main(["serve", "--migrate"]) == 0
    out = capsys.readouterr().out
    db = elsewhere / "data" / "camvlp" / "camvlp.db"
    assert db.is_file()
    assert f"database      {db}" in out.splitlines()
    assert list((elsewhere / "here").iterdir()) == []


def test_the_data_folder_falls_back_to_the_home(elsewhere: Path, monkeypatch):
    monkeypatch.delenv("XDG_DATA_HOME")
    home_db = elsewhere / "home" / ".local" / "share" / "camvlp" / "camvlp.db"
    assert default_db_url() == f"sqlite:///{home_db}"
    assert ServiceSettings().db == f"sqlite:///{home_db}"  # the library's default too


@pytest.mark.parametrize("how", ["--db", "CAMVLP_DB"])
def test_a_database_given_as_a_path_or_in_the_environment(elsewhere, monkeypatch, capsys, how):
    """A path (no ``://``) is a SQLite file, its folder created; CAMVLP_DB as --db."""
    db = elsewhere / "sites" / "vlp.db"
    args = ["serve", "--migrate"]
    if how == "--db":
        args += ["--db", str(db)]
    else:
        monkeypatch.setenv("CAMVLP_DB", str(db))
    assert main(args) == 0
    assert db.is_file()
    assert f"database      {db}" in capsys.readouterr().out.splitlines()
    assert not (elsewhere / "data").exists()  # the default was not touched
    relative = ServiceSettings(db="sites/vlp.db").db  # a relative path: from where it runs
    assert relative == f"sqlite:///{elsewhere / 'here' / 'sites' / 'vlp.db'}"


def test_a_bad_database_is_one_error_line(elsewhere: Path, capsys):
    (elsewhere / "a_file").write_text("not a folder")
    cases = [
        (str(elsewhere / "a_file" / "x.db"), "cannot create the database's folder"),
        (f"sqlite:///{elsewhere / 'a_file' / 'x.db'}", "a file is there"),
        ("nosuchdb://x", "cannot open the database"),
        ("  ", "the database is empty"),
        (str(elsewhere / "here"), "is not a file"),
    ]
    for db, words in cases:
        assert main(["serve", "--db", db, "--migrate"]) == 2, db
        assert words in one_error_line(capsys.readouterr().err), db


def test_sqlite_file_and_database_url():
    assert sqlite_file("sqlite:////srv/vlp/camvlp.db") == Path("/srv/vlp/camvlp.db")
    assert sqlite_file("sqlite+pysqlite:///rel/x.db") == Path("rel/x.db")
    assert sqlite_file("sqlite://") is None and sqlite_file("sqlite:///:memory:") is None
    assert sqlite_file("postgresql+psycopg://u@h/camvlp") is None
    assert sqlite_file("not a url") is None
    url = "postgresql+psycopg://u@h/camvlp"
    assert database_url(url) == url and database_url("sqlite:///x.db") == "sqlite:///x.db"
    with pytest.raises(ValueError, match="empty"):
        database_url("")


def test_what_the_commands_write_where_they_run_is_ignored_by_git():
    """An older version's ``camvlp.db`` (and its SQLite journals) and ``camvlp calibrate``'s
    default ``camera.yaml``, in a checkout's top folder, are not offered to a commit."""
    import shutil
    import subprocess

    repo = Path(__file__).resolve().parents[2]
    if shutil.which("git") is None or not (repo / ".git").exists():
        pytest.skip("not a git checkout")
    names = ["camvlp.db", "camvlp.db-wal", "camvlp.db-shm", "camera.yaml"]
    done = subprocess.run(
        ["git", "check-ignore", "--no-index", *names],
        cwd=repo,
        capture_output=True,
        text=True,
        check=False,
    )
    assert sorted(done.stdout.split()) == sorted(names), done.stderr
