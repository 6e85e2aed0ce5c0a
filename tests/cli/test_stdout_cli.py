"""What the command line does with its standard output closed early (``camvlp ... | head -1``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[2] / "src")


def _run_into_closed_pipe(args: list[str], *, unbuffered: bool) -> subprocess.CompletedProcess:
    """Run ``python -m camvlp ARGS`` with its stdout a pipe whose reading end is already
    closed: every write to it fails with EPIPE, as after ``| head -1`` has read its line."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    if unbuffered:  # each print reaches the pipe at once, inside the command
        env["PYTHONUNBUFFERED"] = "1"
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run(
            [sys.executable, "-m", "camvlp", *args],
            stdin=subprocess.DEVNULL,
            stdout=write_end,
            stderr=subprocess.PIPE,
            env=env,
            text=True,
            timeout=60,
            check=False,
        )
    finally:
        os.close(write_end)


@pytest.mark.parametrize("unbuffered", [False, True], ids=["buffered", "unbuffered"])
@pytest.mark.parametrize(
    "args",
    [["encode", "5"], ["encode", "5", "--json"], ["--help"], ["locate", "--help"]],
    ids=" ".join,
)
def test_a_closed_stdout_ends_quietly_with_the_sigpipe_status(args, unbuffered):
    """Like a Unix tool killed by SIGPIPE: no message, status 128 + 13 (what a shell shows)."""
    done = _run_into_closed_pipe(args, unbuffered=unbuffered)
    assert done.stderr == ""
    assert done.returncode == 141  # the hostile cases check a full disk: one error, 2
