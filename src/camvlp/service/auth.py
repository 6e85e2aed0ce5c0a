"""API keys: made with ``secrets``, stored only as a SHA-256 hash, compared in constant time."""

from __future__ import annotations

import hashlib
import hmac
import secrets

__all__ = ["KEY_PREFIX", "hash_key", "keys_match", "new_key"]

#: Every key starts with this, so that a leaked one is easy to recognise.
KEY_PREFIX = "cvlp_"


def new_key() -> tuple[str, str]:
    """A new API key (256 random bits) and its hash: ``(key, key_hash)``.

    The key is shown to its owner once; only the hash is stored.
    """
    key = KEY_PREFIX + secrets.token_urlsafe(32)
    return key, hash_key(key)


def hash_key(key: str) -> str:
    """The stored form of a key: SHA-256, 64 hex digits.

    A plain hash suffices (no salt, no slow hash): the keys are random 256-bit tokens, not
    passwords, so there is nothing to guess from a dictionary.
    """
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


def keys_match(key: str, stored_hash: str) -> bool:
    """Whether ``key`` hashes to ``stored_hash``, compared in constant time."""
    return hmac.compare_digest(hash_key(key).encode("ascii"), stored_hash.encode("ascii"))
