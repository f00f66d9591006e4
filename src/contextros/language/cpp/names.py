"""The C++ flavour's words: its declaration keywords, C++'s keywords, and which names a layer
or a group may have in generated C++."""

from __future__ import annotations

from contextros.language.cpp.tokens import identifier_char
from contextros.language.words import LINE_WORDS, misspelt

LAYER_WORDS = ("Layer", "layer")
DECLARATION_WORDS = (*LAYER_WORDS, "group", "base", *LINE_WORDS)
# The words a misspelt declaration word is compared with (`Layr`, `grou`).
BLOCK_WORDS = ("Layer", "group", "base")

CPP_KEYWORDS = frozenset(
    {
        "alignas",
        "alignof",
        "and",
        "and_eq",
        "asm",
        "auto",
        "bitand",
        "bitor",
        "bool",
        "break",
        "case",
        "catch",
        "char",
        "char8_t",
        "char16_t",
        "char32_t",
        "class",
        "compl",
        "concept",
        "const",
        "consteval",
        "constexpr",
        "constinit",
        "const_cast",
        "continue",
        "co_await",
        "co_return",
        "co_yield",
        "decltype",
        "default",
        "delete",
        "do",
        "double",
        "dynamic_cast",
        "else",
        "enum",
        "explicit",
        "export",
        "extern",
        "false",
        "float",
        "for",
        "friend",
        "goto",
        "if",
        "inline",
        "int",
        "long",
        "mutable",
        "namespace",
        "new",
        "noexcept",
        "not",
        "not_eq",
        "nullptr",
        "operator",
        "or",
        "or_eq",
        "private",
        "protected",
        "public",
        "register",
        "reinterpret_cast",
        "requires",
        "return",
        "short",
        "signed",
        "sizeof",
        "static",
        "static_assert",
        "static_cast",
        "struct",
        "switch",
        "template",
        "this",
        "thread_local",
        "throw",
        "true",
        "try",
        "typedef",
        "typeid",
        "typename",
        "union",
        "unsigned",
        "using",
        "virtual",
        "void",
        "volatile",
        "wchar_t",
        "while",
        "xor",
        "xor_eq",
    }
)
# Names the generated code uses for itself.
RESERVED = frozenset({"proceed", "base"})


def name_problem(name: str) -> str:
    """Why `name` cannot name a layer or a group in generated C++ ('' if it can)."""
    if not name or not name.isascii() or not (name[0].isalpha() or name[0] == "_"):
        return "is not a C++ identifier"
    if not all(identifier_char(c) for c in name):
        return "is not a C++ identifier"
    if name in CPP_KEYWORDS:
        return "is a C++ keyword"
    if name in RESERVED or name.startswith("contextros_"):
        return "is reserved by the generated code"
    return ""


def misspelt_declaration(word: str) -> str:
    """The declaration word `word` is one edit away from ('' if none)."""
    return misspelt(word, BLOCK_WORDS)
