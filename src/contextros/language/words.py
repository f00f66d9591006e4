"""The declaration words of both flavours, and which one a misspelt word meant."""

from __future__ import annotations

from collections.abc import Iterable

# A layer's relations to others, in the order a declaration lists them (both flavours).
RELATIONS = ("excludes", "requires", "after", "implies")


def relation_words(last: str) -> str:
    """`'excludes', 'requires', 'after', 'implies' or ':'`: what may follow a layer's name."""
    return ", ".join(repr(word) for word in RELATIONS) + f" or {last!r}"


# The one-line declarations, alike in every flavour (lines.py parses them).
LINE_WORDS = ("rule", "parameter", "lifecycle", "topic")


def declaration_words(layer_word: str) -> tuple[str, ...]:
    """Every declaration word of the flavour whose layer word is `layer_word`."""
    return (layer_word, "base", "group", *LINE_WORDS)


def a_declaration(layer_word: str) -> str:
    """`a declaration ('layer', 'base', ... or 'topic')`: what may start a line."""
    words = [repr(word) for word in declaration_words(layer_word)]
    return f"a declaration ({', '.join(words[:-1])} or {words[-1]})"


def expected_declaration(layer_word: str, found: str) -> str:
    """`expected a declaration (...), found 'ule' (misspelt 'rule'?)`: every declaration
    word, and the one `found` may have meant."""
    meant = found_text(found, declaration_words(layer_word))
    return f"expected {a_declaration(layer_word)}, found {meant}"


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
