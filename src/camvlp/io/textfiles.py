"""Small text input files (camera, map, survey, sidecar, trajectory): read within the size
limit as UTF-8, and parsed into a mapping (YAML, JSON, OpenCV's FileStorage YAML) after a
check for what a parser would spend unbounded time, memory or stack on.

Every reader raises :class:`InputError` (a ValueError) with one readable line that names the
file.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from camvlp.errors import InputError
from camvlp.io.limits import limit, read_regular_file
from camvlp.io.yaml_events import SAFE_LOADER, UNUSUAL, load_events

__all__ = [
    "MAX_DIGITS",
    "expect_mapping",
    "parse_mapping",
    "read_mapping",
    "read_text_file",
    "unique_keys",
]

#: Longest run of digits accepted in a file parsed here (int64 has 19).
MAX_DIGITS = 30


def read_text_file(path: str | Path, kind: str) -> str:
    """A small text input file (camera, map, survey, sidecar, trajectory), as UTF-8 text.

    Read through :func:`camvlp.io.limits.read_regular_file`: a regular file only, within
    ``CAMVLP_MAX_FILE_BYTES``.

    Raises
    ------
    InputError
        Not a regular file, too large, unreadable or not UTF-8 (naming the file).
    """
    p = Path(path)
    data = read_regular_file(p, f"{kind} file", limit("CAMVLP_MAX_FILE_BYTES"))
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{kind} file is not UTF-8 text (byte {exc.start})", p) from None


def _line_of(text: str, index: int) -> int:
    return text.count("\n", 0, index) + 1


def _check_text(text: str, path: Path, kind: str, as_json: bool) -> None:
    """Refuse, before parsing, what a parser would spend unbounded time, memory or stack on:
    numbers of too many digits, brackets nested deeper than CAMVLP_MAX_DEPTH (a YAML file's
    anchors, aliases and block nesting are checked as it is read: :func:`_event_check`).
    """
    long_number = re.search(rf"\d{{{MAX_DIGITS + 1},}}", text)
    if long_number:
        raise InputError(
            f"{kind} file has a number of {long_number.end() - long_number.start()} digits at "
            f"line {_line_of(text, long_number.start())} (at most {MAX_DIGITS})",
            path,
        )
    max_depth = limit("CAMVLP_MAX_DEPTH")
    # brackets outside quoted strings: JSON's nesting, and YAML's flow nesting (a YAML scanner
    # would look far ahead through 100,000 open brackets before its first event)
    bare = np.frombuffer(_STRING.sub("", text).encode("utf-8"), dtype=np.uint8)
    step = np.isin(bare, _OPENERS).astype(np.int32) - np.isin(bare, _CLOSERS)
    depth = int(np.cumsum(step).max()) if step.size else 0
    if depth > max_depth:
        raise InputError(f"{kind} file is nested {depth} deep (at most {max_depth})", path)


def _event_check(path: Path, kind: str) -> Callable[[Any], None]:
    """A check of each YAML event in turn (:func:`~camvlp.io.yaml_events.load_events`):
    InputError at an anchor or alias, or nesting deeper than CAMVLP_MAX_DEPTH."""
    max_depth = limit("CAMVLP_MAX_DEPTH")
    depth = 0

    def check(event) -> None:
        nonlocal depth
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
            mark = event.start_mark
            raise InputError(
                f"{kind} file uses a YAML anchor or alias at line {mark.line + 1} "
                "(not accepted: write the values out)",
                path,
            )
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > max_depth:
                raise InputError(
                    f"{kind} file is nested more than {max_depth} deep at line "
                    f"{event.start_mark.line + 1}",
                    path,
                )
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1

    return check


def _load_yaml(text: str, path: Path, kind: str) -> Any:
    """The YAML document, built from its events as they are checked; a text that uses what
    only PyYAML's loader builds is checked whole, then loaded by it."""
    data = load_events(text, _event_check(path, kind))
    if data is UNUSUAL:
        check = _event_check(path, kind)
        for event in yaml.parse(text, Loader=SAFE_LOADER):
            check(event)
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader
    return data


_STRING = re.compile(r'"(?:[^"\\\n]|\\.)*"' + r"|'(?:[^'\n]|'')*'")
_OPENERS = np.frombuffer(b"[{", dtype=np.uint8)
_CLOSERS = np.frombuffer(b"]}", dtype=np.uint8)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else exc.__class__.__name__


class _UniqueKeyLoader(SAFE_LOADER):
    """YAML's safe loader, refusing a mapping that gives a key twice (YAML says keys are
    unique; PyYAML would keep the last one silently, e.g. a fixture's second ``position``)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, (str, int, float, bool)) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    f"the key {key!r} is given twice (line {key_node.start_mark.line + 1})",
                    key_node.start_mark,
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """A JSON object as a dict, refusing a key given twice (``json`` keeps the last one)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {key!r} is given twice")
        out[key] = value
    return out


def parse_mapping(text: str, path: Path, kind: str) -> dict:
    """Parse JSON, YAML, or OpenCV FileStorage YAML (``%YAML:1.0``, ``!!opencv-matrix``).

    A mapping that gives a key twice is refused (naming the key), in YAML and in JSON.
    """
    if text.lstrip().startswith("%YAML"):  # drop the directive, keep its line (line numbers)
        lead = len(text) - len(text.lstrip())
        end = text.find("\n", lead)
        text = text[:lead] + (text[end:] if end >= 0 else "")
        text = text.replace("!!opencv-matrix", "").replace("!!opencv-nd-matrix", "")
    as_json = path.suffix.lower() == ".json"
    _check_text(text, path, kind, as_json)
    try:
        if as_json:
            data = json.loads(text, object_pairs_hook=unique_keys)
        else:
            data = _load_yaml(text, path, kind)
    except (json.JSONDecodeError, yaml.YAMLError, ValueError, RecursionError) as exc:
        raise InputError(f"malformed {kind} file: {_first_line(exc)}", path) from None
    expect_mapping(data, f"{kind} file", path)
    return data


#: What a parsed value that is not a mapping is, for an error message, by type.
_KINDS = ((bool, "true or false"), ((int, float), "a number"), (str, "a string"), (list, "a list"))


def expect_mapping(data: Any, what: str, source: str | Path) -> Mapping[str, Any]:
    """``data`` if it is a mapping, else an InputError "malformed ``what``: expected a mapping
    of keys, got a list" (saying what it is: a list, a string, a number, nothing...)."""
    if isinstance(data, Mapping):
        return data
    got = "nothing" if data is None else next((k for t, k in _KINDS if isinstance(data, t)), None)
    got = got or type(data).__name__
    raise InputError(f"malformed {what}: expected a mapping of keys, got {got}", source)


def read_mapping(path: str | Path, kind: str) -> dict:
    """Read and parse the ``kind`` file (``"camera"``, ``"map"``...) at ``path`` into a dict.

    Raises
    ------
    InputError
        Missing, oversized or malformed file, naming it.
    """
    p = Path(path)
    return parse_mapping(read_text_file(p, kind), p, kind)
