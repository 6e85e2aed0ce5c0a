"""YAML read from the parser's events, with the checks of :mod:`camvlp.io.textfiles` on the
way: a map of 10,000 fixtures in a fifth of a second rather than the seconds that PyYAML's
node graph and constructors take.

The values are those of PyYAML's safe loader (its resolver says each plain scalar's type,
its constructors build the value; both cached by the scalar's text, since a map repeats its
numbers): :func:`load_events` gives what ``yaml.load(text, Loader=...)`` gives, or says
(by returning :data:`UNUSUAL`) that the text uses what only the loader itself builds (an
explicit tag on a list or mapping, a merge key, a list or mapping as a key, more than one
document), which the caller then loads the slow way.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import yaml

__all__ = ["SAFE_LOADER", "UNUSUAL", "load_events"]

#: YAML's safe loader, LibYAML's (C) where PyYAML was built with it.
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: What :func:`load_events` returns for a text it leaves to the loader.
UNUSUAL = object()

_RESOLVER = yaml.resolver.Resolver()
_CONSTRUCTOR = yaml.constructor.SafeConstructor()
_PLAIN = (None, "!")
_SIMPLE = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", None, "!")
_MERGE = "tag:yaml.org,2002:merge"


@lru_cache(maxsize=4096)
def _scalar(tag: str | None, value: str, implicit: tuple[bool, bool]) -> Any:
    """A scalar's value as the safe loader makes it (:data:`UNUSUAL` for a merge key, a
    value key, a tag it does not know)."""
    if tag in _PLAIN:
        tag = _RESOLVER.resolve(yaml.ScalarNode, value, implicit)
    make = _CONSTRUCTOR.yaml_constructors.get(tag)
    if make is None or tag in (_MERGE, "tag:yaml.org,2002:value"):
        return UNUSUAL
    return make(_CONSTRUCTOR, yaml.ScalarNode(tag, value))


class _Mapping:
    """A mapping being read: its items so far and the key waiting for its value."""

    __slots__ = ("items", "key")

    def __init__(self) -> None:
        self.items: dict = {}
        self.key: Any = _NO_KEY


_NO_KEY = object()


def _add(stack: list, value: Any, mark) -> None:
    """Put ``value`` into the open list or mapping (a mapping takes a key, then its value)."""
    top = stack[-1]
    if isinstance(top, list):
        top.append(value)
    elif top.key is _NO_KEY:
        if value in top.items:
            raise yaml.constructor.ConstructorError(
                None, None, f"the key {value!r} is given twice (line {mark.line + 1})", mark
            )
        top.key = value
    else:
        top.items[top.key] = value
        top.key = _NO_KEY


def load_events(text: str, check=None) -> Any:
    """The document of ``text``, built from the parser's events (see the module's words).

    Parameters
    ----------
    text : str
        A YAML document.
    check : callable, optional
        Called with every event before it is used (raising stops the read): the caller's
        limits (anchors, nesting).

    Returns
    -------
    object
        The document's value (None for an empty text), or :data:`UNUSUAL`.

    Raises
    ------
    yaml.YAMLError
        A malformed text, or a mapping that gives a key twice.
    """
    stack: list = [[]]  # the root: a list of the documents
    for event in yaml.parse(text, Loader=SAFE_LOADER):
        if check is not None:
            check(event)
        if isinstance(event, yaml.ScalarEvent):
            value = _scalar(event.tag, event.value, event.implicit)
            if value is UNUSUAL:
                return UNUSUAL
            _add(stack, value, event.start_mark)
        elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            top = stack[-1]
            if event.tag not in _SIMPLE or (isinstance(top, _Mapping) and top.key is _NO_KEY):
                return UNUSUAL  # a tagged collection, or a collection as a key
            stack.append([] if isinstance(event, yaml.SequenceStartEvent) else _Mapping())
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            done = stack.pop()
            _add(stack, done.items if isinstance(done, _Mapping) else done, event.start_mark)
        elif isinstance(event, yaml.AliasEvent):
            return UNUSUAL
    documents = stack[0]
    if len(documents) > 1:
        return UNUSUAL  # (the loader says what is wrong)
    return documents[0] if documents else None
