"""The declaration words of both flavours, and which one a misspelt word meant."""

from __future__ import annotations

from collections.abc import Iterable

# A layer's relations to others, in the order a declaration lists them (both flavours).
RELATIONS = ("excludes", "requires", "after")


def misspelt(word: str, keywords: Iterable[str]) -> str:
    """The keyword `word` is one edit away from ('' if none, or if it is one)."""
    for keyword in keywords:
        if len(word) >= 3 and _one_edit(word.lower(), keyword.lower()):
            return keyword
    return ""


def found_text(found: str, keywords: Iterable[str]) -> str:
    """`'layr'` as a diagnostic quotes a word found instead of a keyword, with the keyword
    it may have meant: `'layr' (misspelt 'layer'?)`."""
    meant = misspelt(found, keywords)
    return f"{found!r} (misspelt {meant!r}?)" if meant else repr(found)


def _one_edit(a: str, b: str) -> bool:
    """Whether `a` becomes `b` by one deleted, inserted or replaced character."""
    if a == b or abs(len(a) - len(b)) > 1:
        return False
    if len(a) > len(b):
        a, b = b, a
    i = next((k for k in range(len(a)) if a[k] != b[k]), len(a))
    return a[i + (len(a) == len(b)) :] == b[i + 1 :]
