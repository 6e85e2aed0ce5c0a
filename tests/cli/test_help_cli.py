"""``camvlp --help``: each command's summary is one plain sentence."""

from __future__ import annotations

import typer

from camvlp.cli import app


def test_every_command_summary_is_one_plain_line():
    """The command list shows each command's first docstring paragraph; track's and
    render-video's ran over several lines with their breaks and RST quotes (``)."""
    commands = typer.main.get_command(app).commands
    assert len(commands) >= 10
    for name, command in commands.items():
        summary = (command.help or "").strip().split("\n\n")[0]
        assert summary and "\n" not in summary and "``" not in summary, (name, summary)
