"""The console script keeps freed memory blocks in the heap (glibc's malloc)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

import camvlp.cli as cli


class _Libc:
    def __init__(self):
        self.calls = []

    def mallopt(self, param, value):
        self.calls.append((param, value))
        return 1


@pytest.fixture
def libc(monkeypatch):
    fake = _Libc()
    monkeypatch.setattr(cli.ctypes, "CDLL", lambda name: fake)
    monkeypatch.setattr(cli.sys, "platform", "linux")
    for k in cli._MALLOC_ENV:
        monkeypatch.delenv(k, raising=False)
    return fake


def test_blocks_up_to_32_mb_stay_in_the_heap(libc):
    assert cli.keep_freed_blocks()
    assert libc.calls == [(-3, 32 << 20), (-1, 64 << 20)]  # M_MMAP_, M_TRIM_THRESHOLD


@pytest.mark.parametrize("name", ["MALLOC_MMAP_THRESHOLD_", "GLIBC_TUNABLES"])
def test_a_users_own_malloc_settings_are_left_be(libc, monkeypatch, name):
    monkeypatch.setenv(name, "1048576")
    assert not cli.keep_freed_blocks()
    assert libc.calls == []


def test_the_console_script_sets_them_and_a_call_from_python_does_not(monkeypatch):
    calls = []
    monkeypatch.setattr(cli, "keep_freed_blocks", lambda: calls.append(1) or True)
    assert cli.main(["encode", "5"]) == 0
    assert calls == []
    monkeypatch.setattr(sys, "argv", ["camvlp", "encode", "5"])
    with pytest.raises(SystemExit) as exc:
        cli.main()
    assert exc.value.code == 0 and calls == [1]


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's malloc")
def test_glibc_takes_them():
    code = "import camvlp.cli as c; print(c.keep_freed_blocks())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"
