"""Generate the documentation site's reference pages at build time (mkdocs-gen-files).

* ``reference/api/``: one page per public module of ``src/camvlp`` (mkdocstrings renders
  it), found by walking the package tree, and its ``SUMMARY.md`` (mkdocs-literate-nav reads
  it as that section's navigation): a module added or moved appears without editing the nav.
* ``reference/cli.md``: every ``camvlp`` command with its usage and options, read from the
  Typer application itself (the same records ``--help`` prints), so it cannot drift from it.

Run by ``mkdocs build`` (``scripts/docs.sh``); not meant to be run alone.
"""

from __future__ import annotations

import html
import inspect
import re
from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"

#: Packages left out of the API reference (with their sub-modules, and the names the package
#: ``camvlp`` re-exports from them); none today.
SKIP: set[str] = set()

#: Where the names ``camvlp`` re-exports from a skipped package are described (from the
#: ``camvlp`` page of the reference).
GUIDE = "../../../locating.md#from-python"

#: Folders under ``src/camvlp`` that hold no library code (the service's schema migrations).
NOT_MODULES = {"migrations", "static"}


def _skipped(module: str) -> bool:
    """Whether ``module`` (a dotted name) is in :data:`SKIP` or below an entry of it."""
    return any(module == s or module.startswith(s + ".") for s in SKIP)


def public_modules() -> list[tuple[str, ...]]:
    """Dotted-name parts of every public module and package of ``camvlp``, in tree order.

    A module or package whose name starts with ``_`` is private, and so is all below it.
    """
    found = []
    for path in sorted((SRC / "camvlp").rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts) or NOT_MODULES.intersection(parts):
            continue
        if not _skipped(".".join(parts)):
            found.append(parts)
    return found


def write_api_pages() -> None:
    """One page per public module under ``reference/api/``, and its navigation."""
    nav = mkdocs_gen_files.Nav()
    for parts in public_modules():
        module = ".".join(parts)
        package = (SRC.joinpath(*parts) / "__init__.py").exists()
        doc = Path(*parts, "index.md") if package else Path(*parts).with_suffix(".md")
        nav[parts] = doc.as_posix()
        with mkdocs_gen_files.open(Path("reference/api") / doc, "w") as page:
            page.write(f"# `{module}`\n\n::: {module}\n")
            if module == "camvlp":  # its names are documented where they are defined
                page.write("    options:\n      members: false\n\n" + _top_level_summary())
    with mkdocs_gen_files.open("reference/api/SUMMARY.md", "w") as summary:
        summary.writelines(nav.build_literate_nav())


def _top_level_summary() -> str:
    """A table of the names ``camvlp`` exports, each linked to the page that documents it."""
    import camvlp

    rows = ["| name | defined in |", "|---|---|"]
    for name in camvlp.__all__:
        obj = getattr(camvlp, name)
        home = getattr(obj, "__module__", None) or "camvlp"
        if _skipped(home):  # described with the guides instead
            rows.append(f"| `camvlp.{name}` | `{home}` ([Locating a photo]({GUIDE})) |")
        else:
            rows.append(f"| [`camvlp.{name}`][{home}.{name}] | `{home}` |")
    return "## Its names\n\nImport these from `camvlp` itself:\n\n" + "\n".join(rows) + "\n"


def _cell(text: str) -> str:
    """``text`` as one cell of a Markdown table: one line, its specials escaped."""
    text = html.escape(" ".join(text.split()), quote=False)
    return re.sub(r"([\\`*_\[\]|])", r"\\\1", text)


def _command_section(command, ctx, path: str, level: int) -> list[str]:
    """The Markdown of one command (and of its sub-commands, one level deeper)."""
    import typer

    lines = [f"{'#' * level} {path}", ""]
    doc = inspect.cleandoc(command.help or "")
    lines += ["```text", command.get_usage(ctx).strip(), "```", ""]
    if doc:
        lines += [html.escape(doc, quote=False), ""]
    records = [p.get_help_record(ctx) for p in command.params]
    records = [r for r in records if r is not None]
    if records:
        lines += ["| argument or option | meaning |", "|---|---|"]
        lines += [f"| `{opts}` | {_cell(meaning)} |" for opts, meaning in records]
        lines.append("")
    if hasattr(command, "list_commands"):  # a group: its commands follow
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            sub_ctx = typer.Context(sub, info_name=name, parent=ctx)
            lines += _command_section(sub, sub_ctx, f"{path} {name}", level + 1)
    return lines


def write_cli_page() -> None:
    """``reference/cli.md``: every command of the ``camvlp`` Typer application."""
    import typer

    from camvlp.cli import app

    group = typer.main.get_command(app)
    ctx = typer.Context(group, info_name="camvlp")
    lines = [
        "# CLI reference",
        "",
        "Every `camvlp` command with its arguments and options, as `camvlp COMMAND --help`",
        "prints them (this page is generated from the command-line application itself).",
        "Exit codes and the one-line errors are described in",
        "[Reliability](../reliability.md#exit-codes-and-errors).",
        "",
    ]
    lines += ["| command | what it does |", "|---|---|"]
    for name in group.list_commands(ctx):
        summary = group.get_command(ctx, name).get_short_help_str(limit=200)
        lines.append(f"| [`camvlp {name}`](#camvlp-{name}) | {_cell(summary)} |")
    lines.append("")
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        lines += _command_section(
            command, typer.Context(command, info_name=name, parent=ctx), f"camvlp {name}", 2
        )
    with mkdocs_gen_files.open("reference/cli.md", "w") as page:
        page.write("\n".join(lines))


write_api_pages()
write_cli_page()
