"""The ``camvlp`` Typer application and its shared error handling.

Imported whenever the command line starts (``--help`` too): it loads typer and the standard
library only, the heavier modules when a command runs.
"""

from __future__ import annotations

import inspect
import math
import os
import re
import sys
import warnings
from collections.abc import Callable
from functools import wraps
from typing import Annotated, Any, NoReturn, TypeVar

import typer
from typer.core import TyperGroup

from camvlp.errors import InputError, one_line
from camvlp.model.readout import Readout

#: A line that starts a list item in a help text: ``- item``, ``* item``, ``1. item``, ``2) item``.
_LIST_ITEM = re.compile(r"([-*]|\d+[.)])\s")


def reflow(text: str | None) -> str | None:
    """A help text with each paragraph's lines joined into one line, which the terminal then
    wraps to its width; paragraph breaks (a blank line), list items (lines that start with
    ``- ``, ``* ``, ``1. `` or ``1) ``, their continuation lines joined to them) and
    paragraphs that start with ``\\b`` (click's "keep as written") are kept."""
    if not text:
        return text
    paragraphs = []
    for paragraph in re.split(r"\n[ \t]*\n", inspect.cleandoc(text)):
        if paragraph.startswith("\b"):
            paragraphs.append(paragraph)
            continue
        lines: list[str] = []
        for line in paragraph.splitlines():
            line = line.strip()
            if lines and line and not _LIST_ITEM.match(line):
                lines[-1] += " " + line
            elif line:
                lines.append(line)
        paragraphs.append("\n".join(lines))
    return "\n\n".join(p for p in paragraphs if p)


def reflow_help(command: Any) -> None:
    """:func:`reflow` the help of ``command``, of its options and arguments, and of its
    subcommands, all the way down (in place); flags are shown without a value's type."""
    command.help = reflow(command.help)
    for param in command.params:
        if getattr(param, "help", None):
            param.help = reflow(param.help)
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""  # a flag takes no value: no "<bool>" after its name
    for sub in getattr(command, "commands", {}).values():
        reflow_help(sub)


class ReflowedHelpGroup(TyperGroup):
    """The command group of ``camvlp``: every help text reflowed (:func:`reflow`) once, when
    the group is built, so that docstrings written across several lines wrap cleanly at any
    terminal width."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        reflow_help(self)


app = typer.Typer(
    name="camvlp",
    cls=ReflowedHelpGroup,
    help="Visible light positioning with a rolling-shutter camera.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)

#: Exit codes (docs/reliability.md): located / not located / bad input or usage.
EXIT_OK, EXIT_NOT_LOCATED, EXIT_BAD_INPUT = 0, 1, 2
#: Exit code when stdout was closed early (``camvlp ... | head -1``): 128 + SIGPIPE, what a
#: shell shows for a tool that SIGPIPE ended (as 130 = 128 + SIGINT after Ctrl-C).
EXIT_BROKEN_PIPE = 141

#: Largest magnitude of a number option (a float, or an item of a comma-separated list).
MAX_OPTION_MAGNITUDE = 1e9
#: Largest magnitude of an integer option.
MAX_OPTION_INTEGER = 2**53

F = TypeVar("F", bound=Callable)


def fail(what: str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    """Print ``error: <what>`` on stderr (one line: newlines and other control characters
    escaped) and exit with ``code``."""
    print(f"error: {one_line(str(what))}", file=sys.stderr)
    raise typer.Exit(code)


def handle_errors(func: F) -> F:
    """Turn bad input anywhere below a command into one line on stderr and exit code 2.

    The library's ValueError (InputError and the checks of its arguments), a number too large
    to compute with, a nesting too deep, memory exhausted and a file that cannot be read or
    written all end as ``error: <what>``; stdout closed early (a broken pipe) is left to
    :func:`camvlp.cli.main`.  Library warnings (NumPy's RuntimeWarning on a
    degenerate value ...) are silenced: the command's checks report what matters, once.
    """

    @wraps(func)
    def wrapper(*args, **kwargs):
        import numpy as np  # (the commands' work imports it anyway)

        check_numbers(kwargs)
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                return func(*args, **kwargs)
        except (InputError, ValueError) as exc:
            fail(_first_line(exc))
        except (OverflowError, ZeroDivisionError) as exc:
            fail(f"a number out of range: {_first_line(exc)}")
        except RecursionError:
            fail("input nested too deeply")
        except MemoryError:
            fail("out of memory; use a smaller input or option value")
        except BrokenPipeError:  # stdout closed early: main() ends quietly, EXIT_BROKEN_PIPE
            raise
        except OSError as exc:
            reason = exc.strerror or exc.__class__.__name__
            where = f" ({exc.filename})" if exc.filename else ""
            fail(f"cannot read or write: {reason}{where}")
        except KeyboardInterrupt:
            fail("interrupted", 130)

    return wrapper  # type: ignore[return-value]


def check_numbers(options: dict[str, Any]) -> None:
    """Fail (exit 2) when a number option is NaN, infinite or of magnitude over
    ``MAX_OPTION_MAGNITUDE`` (floats) or ``MAX_OPTION_INTEGER`` (integers), naming it."""
    for name, value in options.items():
        option = "--" + name.replace("_", "-")
        if isinstance(value, float) and not (
            math.isfinite(value) and abs(value) <= MAX_OPTION_MAGNITUDE
        ):
            fail(
                f"{option} must be a finite number of magnitude at most "
                f"{MAX_OPTION_MAGNITUDE:g}, got {value}"
            )
        if isinstance(value, int) and not isinstance(value, bool):
            if abs(value) > MAX_OPTION_INTEGER:
                fail(f"{option} must be at most {MAX_OPTION_INTEGER:,}, got {_cut(str(value))}")


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else exc.__class__.__name__


def parse_floats(text: str, n: int, name: str) -> list[float]:
    """Parse ``"a,b,c"`` into ``n`` floats, or fail with a usage error naming ``name``."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        values = []
    if len(values) != n:
        fail(f"{name} must be {n} comma-separated numbers, got {_cut(text)!r}")
    if not all(math.isfinite(v) and abs(v) <= MAX_OPTION_MAGNITUDE for v in values):
        fail(
            f"{name} must be finite numbers of magnitude at most {MAX_OPTION_MAGNITUDE:g}, "
            f"got {_cut(text)!r}"
        )
    return values


def _cut(text: str, most: int = 60) -> str:
    return text if len(text) <= most else text[: most - 3] + "..."


def cap_jobs(jobs: int | None, option: str = "--jobs") -> int | None:
    """``jobs`` capped at the machine's cores (a note on stderr when it was higher); None passes.

    Fails (exit 2) when ``jobs`` is below 1.
    """
    if jobs is None:
        return None
    if jobs < 1:
        fail(f"{option} must be at least 1, got {jobs}")
    try:
        cores = max(1, len(os.sched_getaffinity(0)))  # the cores this process may run on
    except AttributeError:  # not on Linux
        cores = max(1, os.cpu_count() or 1)
    if jobs > cores:
        print(f"note: {option} {jobs} capped at {cores}, the number of cores", file=sys.stderr)
        return cores
    return jobs


@app.callback()
def _root() -> None:
    """camvlp: find a camera's position from one photograph of coded ceiling lights."""


#: ``--solver``: the OpenCV PnP method (checked by :func:`check_solver`).
SolverOption = Annotated[
    str, typer.Option("--solver", help="PnP solver: iterative, sqpnp, ippe or epnp.")
]
#: ``--outlier-px``: the locator's reprojection tolerance (checked by :func:`check_positive`).
OutlierOption = Annotated[
    float | None,
    typer.Option(
        "--outlier-px",
        help="Drop a fixture whose reprojection error exceeds this (px); with only four "
        "fixtures the photo is then not located. Default: 1 % of the focal length, >= 4 px.",
    ),
]
#: ``--max-sigma``: the least sure position the locator reports (checked by
#: :func:`check_positive`).
MaxSigmaOption = Annotated[
    float | None,
    typer.Option(
        "--max-sigma",
        metavar="S",
        help="Do not report a position whose standard deviation along an axis exceeds S (map "
        "units): the photo is then not located, and the reason gives it. Default: no limit.",
    ),
]


#: ``--gravity-sigma-deg``: the accelerometer's uncertainty (checked by :func:`check_positive`).
GravitySigmaOption = Annotated[
    float | None,
    typer.Option(
        "--gravity-sigma-deg",
        help="Uncertainty of the gravity direction about each axis across it, degrees "
        "(default: the sidecar's, else 1).",
    ),
]

#: ``--near X,Y[,Z]`` and ``--within R``: a prior on the camera's place (checked by
#: :func:`parse_prior`).
NearOption = Annotated[
    str | None,
    typer.Option(
        "--near",
        metavar="X,Y[,Z]",
        help="A prior on where the camera is, map units (with --within): in a map whose IDs "
        "repeat (reuse: true), only the places within R of it are searched (X,Y compares "
        "the map's x and y only).",
    ),
]
WithinOption = Annotated[
    float | None, typer.Option("--within", metavar="R", help="The prior's radius, map units.")
]


def parse_gravity(text: str | None) -> list[float] | None:
    """``--gravity GX,GY,GZ``: three finite numbers, not all zero (None passes)."""
    if text is None:
        return None
    values = parse_floats(text, 3, "--gravity")
    if not all(math.isfinite(v) for v in values):
        fail(f"--gravity must be finite, got {text!r}")
    if not any(values):
        fail("--gravity has zero length: its direction is not known")
    return values


def parse_prior(
    near: str | None, within: float | None
) -> tuple[tuple[float, ...] | None, float | None]:
    """``--near X,Y[,Z] --within R``: two or three numbers and a positive radius, given
    together (both None passes), else a usage error."""
    if (near is None) != (within is None):
        fail("--near and --within go together: give both or neither")
    if near is None:
        return None, None
    n = 3 if near.count(",") >= 2 else 2
    values = parse_floats(near, n, "--near")
    return tuple(values), check_positive(within, "--within")


def check_solver(solver: str, *, allow_locate: bool = False) -> str:
    """``solver`` if it names a PnP method, else a usage error (exit 2)."""
    from camvlp.geometry import pnp

    try:
        return pnp.check_solver(solver, allow_locate=allow_locate)
    except ValueError as exc:
        fail(f"--{exc}")


def parse_readout(value: str | None, option: str = "--readout") -> Readout | None:
    """The readout named by ``value`` (None passes), else a usage error naming ``option``."""
    try:
        return Readout.parse_optional(value, option)
    except ValueError as exc:
        fail(str(exc))


def check_positive(value: float | None, option: str) -> float | None:
    """``value`` if it is None or positive, else a usage error naming ``option`` (exit 2)."""
    if value is not None and not value > 0:
        fail(f"{option} must be a positive number, got {value}")
    return value
