"""Making a PV segment fit its room: the last resorts of `naming`, in order.

A name over its room loses the inner lower-case vowels of its longest words
first (`Underrange` -> `Undrrng`), then its words are cut short, longest
first (`EnblAtmtcClbrtn` -> `EnblAtmtClbr`; digits are never cut, so
`Filter1` and `Filter2` stay apart), and only then is it cut and marked with
`X` and a hash of its TwinCAT name (`AIStdCh1StsUX3F2A`), stable for that
name. `naming` reports every one.
"""

from __future__ import annotations

import hashlib
import re
from typing import Final, NamedTuple

HASH_MARK: Final = "X"
HASH_LENGTHS: Final = (4, 6, 8, 10)
"""Hex digits of the hash, growing while siblings still clash."""
_MIN_WORD = 2
_WORD_RE = re.compile(r"[A-Z][a-z]*|[a-z]+|[0-9]+")
_INNER_VOWELS_RE = re.compile(r"(?<=.)[aeiou]")


class Fitted(NamedTuple):
    segment: str
    reason: str
    """Why it differs from the readable name ("" when it does not)."""
    hashed: bool = False
    """Cut and marked with a hash, not only made shorter."""


def fit(readable: str, cap: int, hash_source: str) -> Fitted:
    """`readable` if it fits `cap`; else vowels dropped; else its words cut
    short; else cut and hashed (the hash of `hash_source`)."""
    if not readable:
        return Fitted(with_hash("", cap, hash_source), "empty name", True)
    if len(readable) <= cap:
        return Fitted(readable, "")
    compressed = drop_inner_vowels(readable, cap)
    if len(compressed) <= cap:
        return Fitted(compressed, f"vowels dropped to fit {cap} characters")
    abbreviated = _cut_words(compressed, cap)
    if len(abbreviated) <= cap:
        return Fitted(abbreviated, f"words cut short to fit {cap} characters")
    return Fitted(
        with_hash(compressed, cap, hash_source), f"cut to {cap} characters", True
    )


def drop_inner_vowels(segment: str, cap: int) -> str:
    """Drop inner lower-case vowels, longest word first, until it fits."""
    words = _WORD_RE.findall(segment)
    order = sorted(range(len(words)), key=lambda i: (-len(words[i]), i))
    for index in order:
        if sum(map(len, words)) <= cap:
            break
        words[index] = _INNER_VOWELS_RE.sub("", words[index])
    return "".join(words)


def with_hash(
    base: str, cap: int, hash_source: str, length: int = HASH_LENGTHS[0]
) -> str:
    """`base` cut so that `X` and `length` hex digits of the hash fit in `cap`."""
    digest = hashlib.sha1(hash_source.encode("utf-8")).hexdigest().upper()
    tag = HASH_MARK + digest[:length]
    return (base or "N")[: cap - len(tag)] + tag


def numbered(base: str, cap: int, taken: set[str] | frozenset[str]) -> str:
    """Last resort when hashes collide: `base` with the first `X<n>` tag whose
    result (without case) is not `taken`."""
    number = 0
    while True:
        tag = f"{HASH_MARK}{number:X}"
        candidate = (base or "N")[: cap - len(tag)] + tag
        if candidate.lower() not in taken:
            return candidate
        number += 1


def _cut_words(segment: str, cap: int) -> str:
    """Cut the longest word by one letter (the first of equals) until it fits
    or every word is down to `_MIN_WORD` letters."""
    words = _WORD_RE.findall(segment)
    while sum(map(len, words)) > cap:
        index = max(range(len(words)), key=lambda i: (len(words[i]), -i))
        if len(words[index]) <= _MIN_WORD or words[index].isdigit():
            break
        words[index] = words[index][:-1]
    return "".join(words)
