"""``camvlp --help``: each command's summary is one plain sentence, and every help text wraps
cleanly at any terminal width."""

from __future__ import annotations

import itertools
import re

import pytest
import typer

from camvlp.cli import app, main
from camvlp.cli._app import reflow

#: Terminal widths the help is read at: a narrow terminal and a wide one.
WIDTHS = (80, 140)
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_LIST_ITEM = re.compile(r"([-*]|\d+[.)])\s")


def test_every_command_summary_is_one_plain_line():
    """The command list shows each command's first docstring paragraph; track's and
    render-video's ran over several lines with their breaks and RST quotes (``)."""
    commands = typer.main.get_command(app).commands
    assert len(commands) >= 10
    for name, command in commands.items():
        summary = (command.help or "").strip().split("\n\n")[0]
        assert summary and "\n" not in summary and "``" not in summary, (name, summary)


def _all_commands() -> list[tuple[list[str], object]]:
    """``(words, command)`` of the root, each command, each group's subcommands."""
    found = []

    def walk(words: list[str], command) -> None:
        found.append((words, command))
        for name, sub in getattr(command, "commands", {}).items():
            walk([*words, name], sub)

    walk([], typer.main.get_command(app))
    return found


def _help_text(words: list[str], width: int, capsys, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", str(width))
    capsys.readouterr()
    assert main([*words, "--help"]) == 0
    return _ANSI.sub("", capsys.readouterr().out)


def _description(text: str) -> list[list[str]]:
    """The paragraphs (lists of lines, padding stripped) between the usage line and the first
    panel of a rendered help."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith("Usage:")) + 1
    end = next((i for i in range(start, len(lines)) if lines[i].startswith("╭")), len(lines))
    paragraphs: list[list[str]] = [[]]
    for line in lines[start:end]:
        if line.strip():
            paragraphs[-1].append(line.strip())
        elif paragraphs[-1]:
            paragraphs.append([])
    return [p for p in paragraphs if p]


def _early_breaks(paragraph: list[str], width: int) -> list[str]:
    """Lines of ``paragraph`` broken before the terminal's edge: the next line's first word
    would have fitted after them (the help's text is ``width - 2`` columns wide), and the
    next line starts no list item."""
    early = []
    for line, following in itertools.pairwise(paragraph):
        if _LIST_ITEM.match(following):
            continue
        if len(line) + 1 + len(following.split()[0]) <= width - 2:
            early.append(line)
    return early


@pytest.mark.parametrize("width", WIDTHS)
def test_help_texts_wrap_at_the_terminal_edge_only(width, capsys, monkeypatch):
    """Every command's --help: no paragraph is broken mid-sentence (docstrings are written
    wrapped at 92 columns; shown as written, their lines broke early on a wide terminal and
    left a short line after each on a narrow one), and its paragraphs are all there."""
    commands = _all_commands()
    assert len(commands) >= 15  # the root, the commands, study's subcommands
    for words, command in commands:
        paragraphs = _description(_help_text(words, width, capsys, monkeypatch))
        name = " ".join(["camvlp", *words])
        for paragraph in paragraphs:
            assert not _early_breaks(paragraph, width), (name, width, paragraph)
        assert len(paragraphs) == len(command.help.strip().split("\n\n")), (name, paragraphs)


def test_reflow_joins_lines_and_keeps_paragraphs_and_lists():
    text = """First line
    goes on.

    Writes:

    - one item
      that goes on;
    - two.

    \b
    kept   as
    written
    """
    assert reflow(text) == (
        "First line goes on.\n\nWrites:\n\n- one item that goes on;\n- two.\n\n"
        "\b\nkept   as\nwritten"
    )
    assert reflow(None) is None and reflow("") == ""
