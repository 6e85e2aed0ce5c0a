"""Command-line interface: a thin layer that parses arguments and calls the library.

The command modules are imported here, where they declare their commands; each imports the
library modules it needs when it runs, so that starting ``camvlp`` (``--help`` too) loads
typer and the declarations only (tests/cli/test_startup.py).
"""

from __future__ import annotations

import ctypes
import functools
import os
import re
import sys
from typing import TYPE_CHECKING, TextIO

import typer

from . import assign_ids as _assign_ids  # noqa: F401  (registers commands)
from . import calibrate as _calibrate  # noqa: F401  (registers commands)
from . import encode  # noqa: F401  (registers commands)
from . import evaluate as _evaluate  # noqa: F401  (registers commands)
from . import locate as _locate  # noqa: F401  (registers commands)
from . import render as _render  # noqa: F401  (registers commands)
from . import serve as _serve  # noqa: F401  (registers commands)
from . import study as _study  # noqa: F401  (registers commands)
from . import track as _track  # noqa: F401  (registers commands)
from ._app import EXIT_BAD_INPUT, EXIT_BROKEN_PIPE, app

if TYPE_CHECKING:
    import click

__all__ = ["app", "command", "keep_freed_blocks", "main"]


@functools.cache
def command() -> click.Command:
    """The parser typer builds from ``app``'s commands, built once a process (about 27 ms:
    typer reads every command's signature and type hints), not at each :func:`main` call."""
    return typer.main.get_command(app)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``camvlp`` console script.

    Usage errors (an unknown option, a missing argument, a value of the wrong type) are
    printed as one line, ``error: ...``, with exit code 2, like every other bad input.  Stdout
    closed early (``camvlp ... | head -1``) ends the command quietly with status 141
    (128 + SIGPIPE), as a Unix tool that the signal ended.
    """
    if argv is None:  # the process is the command's own
        keep_freed_blocks()
    stdout = sys.stdout
    try:
        code = command().main(args=argv, prog_name="camvlp", standalone_mode=False)
    except typer.TyperException as exc:  # usage errors (the parser's ClickException)
        retry = _negative_numbers_as_arguments(exc, sys.argv[1:] if argv is None else argv)
        if retry is not None:  # ``camvlp encode -1``: -1 is the ID, not an unknown option
            code = main(retry)
            if argv is None:
                sys.exit(code)
            return code
        ctx = getattr(exc, "ctx", None)
        where = f" (camvlp {ctx.info_name})" if ctx is not None and ctx.parent else ""
        message = " ".join(exc.format_message().split())
        if not message:  # no arguments at all: show the help
            return main(["--help"]) if argv is None or argv else EXIT_BAD_INPUT
        print(f"error: {message}{where}; see --help", file=sys.stderr)
        code = getattr(exc, "exit_code", EXIT_BAD_INPUT) or EXIT_BAD_INPUT
    except typer.Abort:
        print("error: interrupted", file=sys.stderr)
        code = 130
    except SystemExit as exc:
        # The parser's and rich's own answer to a closed stdout (a command's output, the help
        # text): exit 1, which here means "not located".  The parser wraps sys.stdout first;
        # rich exits while handling the BrokenPipeError.
        if sys.stdout is stdout and not isinstance(exc.__context__, BrokenPipeError):
            raise
        code = EXIT_BROKEN_PIPE
    code = code if isinstance(code, int) else 0
    try:  # stdout to a full device or a closed pipe: one line, not a traceback at exit
        sys.stdout.flush()
    except BrokenPipeError:
        code = EXIT_BROKEN_PIPE
    except OSError as exc:
        _stdout_to_devnull(stdout)
        print(f"error: cannot write the output: {exc.strerror or exc}", file=sys.stderr)
        code = EXIT_BAD_INPUT
    if code == EXIT_BROKEN_PIPE:
        _stdout_to_devnull(stdout)
    if argv is None:
        sys.exit(code)
    return code


#: A negative number as a command line writes it (``-1``, ``-0.5``, ``-2e-3``).
_NEGATIVE_NUMBER = re.compile(r"-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def _negative_numbers_as_arguments(exc: Exception, args: list[str]) -> list[str] | None:
    """``args`` with its negative numbers moved after ``--``, where they are arguments, when
    the parser took one for an unknown option of a command that has one argument (so moving
    them keeps the arguments' order); None otherwise.  An option's value stays in place."""
    name, ctx = getattr(exc, "option_name", None), getattr(exc, "ctx", None)
    if not (name and _NEGATIVE_NUMBER.match(name)) or ctx is None or "--" in args:
        return None
    params = ctx.command.params
    arguments = [p for p in params if p.param_type_name == "argument"]
    if len(arguments) != 1 or arguments[0].nargs != 1:
        return None
    valued = {o for p in params if p.param_type_name == "option" and not p.is_flag for o in p.opts}
    free = [
        i
        for i, a in enumerate(args)
        if _NEGATIVE_NUMBER.fullmatch(a) and (i == 0 or args[i - 1] not in valued)
    ]
    if not free:
        return None
    return [a for i, a in enumerate(args) if i not in free] + ["--"] + [args[i] for i in free]


def _stdout_to_devnull(stdout: TextIO) -> None:
    """Send stdout to the null device: the interpreter's last flush at exit then has nothing
    to complain about.  The process's own stdout (``stdout`` the interpreter's) has its file
    descriptor pointed there too, which catches what its buffer still holds."""
    if stdout is sys.__stdout__:  # not a test's capture or an embedding's stream
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, stdout.fileno())
        except (OSError, ValueError):  # no file descriptor after all
            pass
        finally:
            os.close(devnull)
    sys.stdout = open(os.devnull, "w")


#: glibc's ``mallopt`` parameters (malloc.h) and what the command sets them to: blocks up to
#: 32 MB (glibc's largest mapping threshold) from the heap, which keeps up to 64 MB free.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD, _TRIM_THRESHOLD = 32 << 20, 64 << 20
#: Environment variables by which a user sets glibc's malloc; then the command leaves it be.
_MALLOC_ENV = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")


def keep_freed_blocks() -> bool:
    """Keep freed memory blocks of up to 32 MB in the heap (glibc's malloc; elsewhere, or
    when the environment sets malloc's thresholds, nothing); whether it did.

    glibc maps each block over 128 KB afresh and hands it back when freed, until a larger
    one has been freed.  The radial fits of glowing lamps allocate thousands of arrays of a
    few hundred kilobytes, whose pages then fault in one by one: a 1080p photo of 14 lamps
    whose glows join took 9.3 and 8.4 s to locate, 7.6 and 7.6 s with the blocks kept (the
    same peak memory, 247 MB).
    """
    if not sys.platform.startswith("linux") or any(k in os.environ for k in _MALLOC_ENV):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's C library
    except (OSError, AttributeError):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD)) and bool(
        mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD)
    )
