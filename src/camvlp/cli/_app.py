"""The ``camvlp`` Typer application and its shared error handling."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from functools import wraps
from typing import Annotated, NoReturn, TypeVar

import typer

from camvlp.geometry import pnp
from camvlp.io import InputError
from camvlp.model.readout import Readout

app = typer.Typer(
    name="camvlp",
    help="Visible light positioning with a rolling-shutter camera.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)

#: Exit codes (docs/cli.md): located / not located / bad input or usage.
EXIT_OK, EXIT_NOT_LOCATED, EXIT_BAD_INPUT = 0, 1, 2

F = TypeVar("F", bound=Callable)


def fail(what: str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    """Print ``error: <what>`` on stderr and exit with ``code``."""
    print(f"error: {what}", file=sys.stderr)
    raise typer.Exit(code)


def handle_errors(func: F) -> F:
    """Turn bad input anywhere below a command into one line on stderr and exit code 2."""

    @wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            fail(str(exc))
        except KeyboardInterrupt:
            fail("interrupted", 130)

    return wrapper  # type: ignore[return-value]


def parse_floats(text: str, n: int, name: str) -> list[float]:
    """Parse ``"a,b,c"`` into ``n`` floats, or fail with a usage error naming ``name``."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        values = []
    if len(values) != n:
        fail(f"{name} must be {n} comma-separated numbers, got {text!r}")
    return values


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


#: ``--gravity-sigma-deg``: the accelerometer's uncertainty (checked by :func:`check_positive`).
GravitySigmaOption = Annotated[
    float | None,
    typer.Option(
        "--gravity-sigma-deg",
        help="Uncertainty of the gravity direction, degrees (default: the sidecar's, else 1).",
    ),
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


def check_solver(solver: str, *, allow_locate: bool = False) -> str:
    """``solver`` if it names a PnP method, else a usage error (exit 2)."""
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
