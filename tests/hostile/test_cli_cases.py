"""Every hostile command line gives one ``error:`` line, the right exit code, no file left
behind, and stays within 1 GB and 10 s.

The cases that could hang or eat memory if a gate broke (bombs, pipes, devices, a full disk,
worker processes) run in a child process with 1 GB of address space and a 10 s limit; the
others run in this process (fd-level capture, so C libraries' messages count too).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pytest
from bad_inputs import Case, cases, problems, run_case

from camvlp.cli import main

#: Cases run in a child process under resource limits.
ISOLATED = {
    "locate bomb_100000.png",
    "locate bomb_30000.jpg",
    "locate FIFO photo",
    "locate FIFO map",
    "locate /dev/zero",
    "locate -c deep.yaml",
    "locate -m laughs_map.yaml",
    "locate -m idbits12_map.yaml",
    "render huge camera",
    "render-video --frames 2 of a years-long trajectory",
    "study image-error --trials 1e9",
    "encode > /dev/full",
    "render-video --blur 1e6",
    "render-video --blur 1000",
    "render-video --fps 1e9 without --frames",
    "render-video map_2500.json",
    "track FIFO pipe.mp4",
}
#: Cases left to benchmarks/hostile_retry.py: they spawn worker processes (seconds each).
BENCHMARK_ONLY = {"evaluate --jobs 1000"}


@pytest.fixture(scope="module")
def all_cases(tmp_path_factory) -> dict[str, Case]:
    root = tmp_path_factory.mktemp("hostile")
    return {c.name: c for c in cases(root)}


def _names() -> list[str]:
    with tempfile.TemporaryDirectory() as tmp:
        return [c.name for c in cases(Path(tmp))]


_ALL = _names()


@pytest.mark.parametrize("name", sorted(ISOLATED))
def test_isolated_case(all_cases, name):
    case = all_cases[name]
    outcome = run_case(case, timeout_s=10.0, memory_bytes=1 << 30)
    assert not problems(case, outcome), (problems(case, outcome), outcome.stderr)
    assert outcome.seconds < 10.0


@pytest.mark.parametrize("name", [n for n in _ALL if n not in ISOLATED | BENCHMARK_ONLY])
def test_in_process_case(all_cases, name, capfd, monkeypatch):
    case = all_cases[name]
    for variable, value in case.env.items():
        monkeypatch.setenv(variable, value)
    code = main(case.argv)
    out, err = capfd.readouterr()
    lines = err.splitlines()
    assert code == case.code, lines
    errors = [ln for ln in lines if ln.startswith("error: ")]
    assert len(errors) == (0 if case.code == 0 else 1), lines
    assert all(ln.startswith(("error: ", "note: ")) for ln in lines), lines
    for p in case.left_behind:
        assert not Path(p).exists(), p
    if case.json_stdout:
        json.loads(out, parse_constant=lambda c: pytest.fail(f"{c} in JSON output"))


def test_every_case_is_run_somewhere(all_cases):
    assert ISOLATED | BENCHMARK_ONLY <= set(all_cases)
    assert len(all_cases) >= 40
