"""Writing outputs safely: destinations checked first, files written whole, JSON strict.

* :func:`check_output_file` and :func:`check_output_dir` refuse, before any work, a destination
  that cannot be written (a missing or read-only folder, a folder where a file is wanted, a
  file where a folder is wanted).
* :class:`StagedOutputs` writes each file under a temporary name in its own folder and renames
  them into place together when the work has succeeded, so a failure leaves no file behind
  (and never half a file).
* :func:`strict_json` writes NaN and infinities as ``null``: the output is always valid JSON.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from camvlp.errors import InputError

__all__ = [
    "StagedOutputs",
    "check_output_dir",
    "check_output_file",
    "finite_or_none",
    "strict_json",
    "write_text_atomic",
]


def finite_or_none(obj: Any) -> Any:
    """``obj`` with every NaN or infinite float (also inside lists, tuples, dicts and NumPy
    arrays or scalars) replaced by None, and NumPy values turned into Python ones."""
    if isinstance(obj, dict):
        return {k: finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_none(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_or_none(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def strict_json(obj: Any, **kwargs: Any) -> str:
    """``json.dumps`` that never writes ``NaN`` or ``Infinity``: those become ``null``.

    Keyword arguments go to :func:`json.dumps` (``indent=2`` ...).
    """
    return json.dumps(finite_or_none(obj), allow_nan=False, **kwargs)


def _writable_dir(folder: Path, what: str, path: Path) -> None:
    if not folder.exists():
        raise InputError(f"{what}: folder {folder} does not exist", path)
    if not folder.is_dir():
        raise InputError(f"{what}: {folder} is not a folder", path)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{what}: folder {folder} is not writable", path)


def check_output_file(path: str | Path, what: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` if a file can be written there: its folder exists and is writable, and it is
    not a folder (nor a pipe or device); with ``suffixes``, it ends in one of them.

    Raises
    ------
    InputError
        Naming ``what`` (e.g. ``"--out"``) and the path.
    """
    p = Path(path)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise InputError(f"{what} must end in {' or '.join(suffixes)}", p)
    if p.exists() and not p.is_file():
        raise InputError(f"{what} names a folder or a special file, not a file", p)
    if p.exists() and not os.access(p, os.W_OK):
        raise InputError(f"{what} is a read-only file", p)
    _writable_dir(p.parent if str(p.parent) else Path("."), what, p)
    return p


def check_output_dir(path: str | Path, what: str) -> Path:
    """``path`` if files can be written into it: an existing writable folder, or a new one
    whose parent folder exists and is writable.

    Raises
    ------
    InputError
        ``path`` is an existing file, its parent folder is missing, or either is read-only.
    """
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise InputError(f"{what} names an existing file, not a folder", p)
        _writable_dir(p, what, p)
    else:
        _writable_dir(p.parent if str(p.parent) else Path("."), what, p)
    return p


class StagedOutputs:
    """Files written under temporary names, renamed into place together on success.

    Use as a context manager; ask for a temporary path per output with :meth:`file` (same
    folder and suffix as the final file, so encoders chosen by suffix still work) or for a
    temporary folder with :meth:`folder` (every file written into it lands in the final
    folder).  Leaving the block normally commits every output with ``os.replace``; leaving it
    with an exception deletes them all.

    Examples
    --------
    >>> with StagedOutputs() as out:                        # doctest: +SKIP
    ...     cv2.imwrite(str(out.file("photo.png")), image)
    ...     out.file("photo.json").write_text(strict_json(truth))
    """

    def __init__(self) -> None:
        self._files: list[tuple[Path, Path]] = []  # (temporary, final)
        self._folders: list[tuple[Path, Path]] = []

    def __enter__(self) -> StagedOutputs:
        return self

    def file(self, final: str | Path) -> Path:
        """A temporary path for the output ``final``, in ``final``'s folder."""
        p = Path(final)
        for _ in range(100):
            tmp = p.with_name(f".{p.stem[:40]}.{secrets.token_hex(4)}.tmp{p.suffix}")
            try:  # O_EXCL: never another's file; 0o666 and the umask: the usual permissions
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            except FileExistsError:
                continue
            except OSError as exc:
                raise InputError(f"cannot write output: {_reason(exc)}", p) from None
            self._files.append((tmp, p))
            return tmp
        raise InputError("cannot write output: no free temporary name", p)

    def folder(self, final: str | Path) -> Path:
        """A temporary folder whose files are moved into the folder ``final`` (made if
        missing) on commit."""
        p = Path(final)
        parent = p.parent if str(p.parent) else Path(".")
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{p.name[:40]}.", suffix=".tmp", dir=parent))
        except OSError as exc:
            raise InputError(f"cannot write output: {_reason(exc)}", p) from None
        self._folders.append((tmp, p))
        return tmp

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()

    def _moves(self) -> Iterator[tuple[Path, Path]]:
        yield from self._files
        for tmp, final in self._folders:
            for f in sorted(tmp.iterdir()):
                yield f, final / f.name

    def commit(self) -> None:
        """Rename every staged output into place; on a failure, remove what was placed."""
        placed: list[Path] = []
        try:
            for _, final in self._folders:
                final.mkdir(exist_ok=True)
            for tmp, final in list(self._moves()):
                existed = final.exists()
                os.replace(tmp, final)
                if not existed:
                    placed.append(final)
        except OSError as exc:
            for p in placed:
                p.unlink(missing_ok=True)
            self.discard()
            where = exc.filename2 or exc.filename  # the destination, not the temporary name
            raise InputError(f"cannot write output: {_reason(exc)}", where) from None
        self.discard()

    def discard(self) -> None:
        """Delete every staged output that has not been committed."""
        for tmp, _ in self._files:
            tmp.unlink(missing_ok=True)
        for tmp, _ in self._folders:
            shutil.rmtree(tmp, ignore_errors=True)
        self._files.clear()
        self._folders.clear()


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all (a temporary file, then a rename).

    Raises
    ------
    InputError
        The file cannot be written, naming it.
    """
    with StagedOutputs() as out:
        tmp = out.file(path)
        try:
            tmp.write_text(text, encoding="utf-8")
        except OSError as exc:
            raise InputError(f"cannot write output: {_reason(exc)}", path) from None


def _reason(exc: OSError) -> str:
    return exc.strerror or exc.__class__.__name__
