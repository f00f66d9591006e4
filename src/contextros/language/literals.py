"""String literals of the one-line declarations (`rule`, `parameter`): one decoder for both.

A quoted string in a rule or a parameter value is read like a Python string literal without
a prefix (`'charging'`, `"a\\tb"`, `"\\u00e9"`, `"é"`), in every flavour. A malformed escape
(`"\\x"`, `"\\N{no such name}"`) is an error at the escape's column, never an exception; an
escape Python does not know (`"\\d"`) is kept as written, with a warning, as Python does.
"""

from __future__ import annotations

import ast
import re
import warnings

from contextros.language.diagnostics import DiagnosticSink

# One backslash escape, as far as its form goes (`\N{...}`, `\xHH`, `\uHHHH`, `\UHHHHHHHH`,
# or a backslash and one character); whether it is valid is Python's to say.
_ESCAPE = re.compile(
    r"\\(?:N\{[^}]*\}?|N|x[0-9A-Fa-f]{0,2}|u[0-9A-Fa-f]{0,4}|U[0-9A-Fa-f]{0,8}|.)", re.DOTALL
)


def _evaluate(literal: str) -> tuple[str | None, str, list[str]]:
    """Python's value of `literal` (None when it is refused), why it is refused, and the
    warnings it gives."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            value = ast.literal_eval(literal)
        except (SyntaxError, ValueError, MemoryError, RecursionError) as error:
            reason = error.msg if isinstance(error, SyntaxError) else str(error)
            # "(unicode error) 'unicodeescape' codec can't decode bytes ...: truncated \xXX
            # escape": the part after the last colon says what is wrong.
            return None, (reason or "").rsplit(": ", 1)[-1], []
    messages = [
        str(w.message)
        for w in caught
        if issubclass(w.category, (SyntaxWarning, DeprecationWarning))
    ]
    return (value if isinstance(value, str) else None), "", messages


def string_literal(token: str, line: int, col: int, sink: DiagnosticSink) -> str | None:
    """The value of the quoted string `token` (quotes included, no prefix), which starts at
    `line`:`col` (1-based) of the file. Errors and warnings go to `sink` at the column of the
    escape they concern; an error gives None."""
    if len(token) < 2 or token[0] not in "\"'" or token[-1] != token[0]:
        sink.error("expected a quoted string", line, col)
        return None
    value, reason, found = _evaluate(token)
    quote = token[0]
    body = token[1:-1]
    if value is None or found:
        # Say which escape: Python's own message gives only a byte offset.
        for escape in _ESCAPE.finditer(body):
            escape_col = col + 1 + escape.start()
            one, one_reason, one_found = _evaluate(quote + escape.group() + quote)
            if value is None and one is None:
                sink.error(
                    f"invalid escape '{escape.group()}' in a string: {one_reason or reason}",
                    line,
                    escape_col,
                )
                return None
            if value is not None and one_found:
                sink.warning(
                    f"{one_found[0]} in a string: kept as written (write "
                    f"'\\{escape.group()}' for a backslash followed by {escape.group()[1:]!r})",
                    line,
                    escape_col,
                )
    if value is None:
        sink.error(f"invalid string: {reason or 'not a string literal'}", line, col)
        return None
    return value
