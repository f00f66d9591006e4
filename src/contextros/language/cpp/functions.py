"""C++ function definitions, read from tree-sitter's tree: a layer's implementations (name,
owner, signature, `proceed` calls, the spans the back end rewrites) and the shapes of the
header part's declarations, which they must match."""

from __future__ import annotations

from dataclasses import dataclass, field

import tree_sitter

from contextros.language.cpp.reading import Reader
from contextros.language.cpp.tokens import first_problem, leaves
from contextros.language.cpp.tree import CppFunction, Shape, Span
from contextros.language.syntax import Function, Guard, ProceedCall, Signature


@dataclass(frozen=True)
class GuardSpan:
    """`when (CONDITION)` between a definition's declarator and its body."""

    when: int  # at `when`
    close: int  # after its ')'
    condition: Span  # CONDITION, between the parentheses


@dataclass(frozen=True)
class Problem:
    """Why a definition cannot be layered, and where."""

    offset: int
    message: str


@dataclass
class Parameters:
    """A parameter list as the dispatch function needs it."""

    types: list[str] = field(default_factory=list)
    names: list[str | None] = field(default_factory=list)  # None: unnamed
    defaults: list[Span] = field(default_factory=list)  # ` = value`, cut from layers' copies
    problem: Problem | None = None


@dataclass(frozen=True)
class ReadSignature:
    shape: Shape
    parameters: Parameters


class FunctionReader(Reader):
    def definitions(
        self, first: int, last: int, layer: str | None, owner_text: str, guards: list[GuardSpan]
    ) -> list[Function]:
        """The function definitions between two offsets (after a block's '[', at its ']');
        anything else there is reported."""
        tree = self.text.parse(first, last)
        functions: list[Function] = []
        for child in tree.root_node.named_children:
            start, _ = self.text.span(child)
            if child.type == "comment" or start < first or start >= last:
                continue
            if child.type != "function_definition":
                what = "a template" if child.type == "template_declaration" else None
                problem = first_problem(child) if child.type != "ERROR" else _stray(child)
                if what:
                    self.error(
                        f"{what} cannot be layered (its dispatch would need one layered "
                        f"function per instantiation) in {owner_text}: write a plain function "
                        "per type you need (name_int, name_double), layer those, and have the "
                        "template in the header part call them",
                        start,
                    )
                elif problem is not None and problem is not child:
                    self.syntax_error(problem)
                else:
                    self.error(
                        "expected a C++ function definition (a free function or Class::method) "
                        f"in {owner_text}",
                        start,
                    )
                continue
            function = self.function(child, layer)
            if function is not None:
                self._attach_guard(function, guards)
                functions.append(function)
        return functions

    def _attach_guard(self, function: CppFunction, guards: list[GuardSpan]) -> None:
        for guard in guards:
            if function.declarator_end <= guard.when < function.body_start:
                function.when_span = (guard.when, guard.close)
                function.condition_span = guard.condition
                start, end = guard.condition
                text = self.source[start:end]
                offset = start + len(text) - len(text.lstrip())
                function.guard = Guard(text.strip(), self.at(offset))
                if None in function.parameter_names:
                    self.error(
                        f"a guarded implementation of {function.key} must name every "
                        "parameter: the calls its guard turns away go on with them to the next "
                        "implementation",
                        offset,
                    )
                return

    def syntax_error(self, node: tree_sitter.Node) -> None:
        start, end = self.text.span(node)
        if node.is_missing:
            self.error(f"C++ syntax error: missing {node.type!r}", start)
            return
        if _unterminated(node):
            text = self.source[start:end]
            self.error(f"C++ syntax error: missing ';' after {text[-40:]!r}", end)
            return
        stray = _stray(node, in_body=False) if node.type == "ERROR" else node
        if stray is not node:
            start, end = self.text.span(stray)
        text = self.source[start:end].split("\n")[0].strip()
        self.error(f"C++ syntax error: unexpected {text[:40]!r}", start)

    def function(self, node: tree_sitter.Node, layer: str | None) -> CppFunction | None:
        """A layer's (or the base block's) implementation, or None where it is reported."""
        start, end = self.text.span(node)
        problem = first_problem(node)
        if problem is not None:
            self.syntax_error(problem)
            return None
        ref = _ref_qualifier(node.child_by_field_name("declarator"))
        if ref is not None:
            self.error(
                f"a ref-qualified method ('{self.text.text(ref)}') cannot be layered: its dispatch "
                "is a plain method; drop the qualifier, or layer a plain method "
                "(name_layered) and call it from this one in the class",
                self.text.span(ref)[0],
            )
            return None
        for child in node.children:
            if child.type in ("storage_class_specifier", "virtual", "explicit"):
                self.error(
                    f"{self.text.text(child)!r} is not allowed on a layer's function: the "
                    "dispatch function is what others call",
                    self.text.span(child)[0],
                )
                return None
        declarator = function_declarator(node.child_by_field_name("declarator"))
        body = node.child_by_field_name("body")
        if declarator is None or body is None:
            self.error("expected a function definition with a body", start)
            return None
        target = declarator.child_by_field_name("declarator")
        parameters = declarator.child_by_field_name("parameters")
        assert target is not None and parameters is not None
        owner: str | None = None
        name_node = target
        if target.type == "qualified_identifier":
            while name_node.type == "qualified_identifier":
                inner_name = name_node.child_by_field_name("name")
                if inner_name is None:
                    break
                name_node = inner_name
            scope_end = self.text.span(name_node)[0]
            owner = "".join(self.source[self.text.span(target)[0] : scope_end].split())
            owner = owner.removesuffix("::")
        if name_node.type != "identifier" or (owner is not None and not owner):
            self.error(
                f"cannot layer {self.text.text(target)!r}: expected a function name or "
                "Class::method",
                self.text.span(target)[0],
            )
            return None
        name = self.text.text(name_node)
        name_start, name_end = self.text.span(name_node)
        signature = self.signature(node, declarator, target, parameters)
        read = signature.parameters
        if read.problem is not None:
            self.error(read.problem.message, read.problem.offset)
            return None
        key = f"{owner}::{name}" if owner else name
        calls = tuple(
            ProceedCall(self.at(self.text.span(call)[0]))
            for call in _calls(body)
            if self.text.text(call.child_by_field_name("function") or call) == "proceed"
        )
        stem = f"{owner.replace('::', '_')}_{name}" if owner else name
        open_start, close_start = self.text.span(parameters)
        return CppFunction(
            name=name,
            owner=owner,
            layer=layer,
            at=self.at(name_start),
            generated_name=f"{stem}_{layer}" if layer is not None else f"{stem}_base",
            signature=Signature(signature.shape, signature.shape.text(key)),
            proceed_calls=calls,
            takes_instance=True,
            instance_name="this",
            start=start,
            end=end,
            target_start=self.text.span(target)[0],
            name_start=name_start,
            name_end=name_end,
            params_open=open_start + 1,
            params_close=close_start - 1,
            no_parameters=not read.types,
            declarator_end=self.text.span(declarator)[1],
            defaults=tuple(read.defaults),
            exception_specs=tuple(
                self.text.span(child)
                for child in declarator.children
                if child.type in ("noexcept", "throw_specifier")
            ),
            parameter_names=tuple(read.names),
            body_start=self.text.span(body)[0],
        )

    def signature(
        self,
        node: tree_sitter.Node,
        declarator: tree_sitter.Node,
        target: tree_sitter.Node,
        parameters: tree_sitter.Node,
    ) -> ReadSignature:
        """What callers rely on: the return type, the parameter types, the qualifiers (of a
        definition or of a declaration in the header part)."""
        target_start = self.text.span(target)[0]
        # The return type: every token before the declarator's name, less what only a
        # declaration in a class says (virtual, static...).
        attributes = [
            self.text.span(child)
            for child in node.children
            if child.type in ("attribute_declaration", "attribute_specifier", "comment")
        ]
        returns = [
            self.text.text(leaf)
            for leaf in leaves(node)
            if self.text.span(leaf)[0] < target_start
            and self.text.text(leaf) not in _SPECIFIERS
            and not any(a <= self.text.span(leaf)[0] < b for a, b in attributes)
        ]
        read = self.parameters(parameters)
        parameters_end = self.text.span(parameters)[1]
        qualifiers = [
            self.text.text(leaf)
            for child in declarator.children
            if self.text.span(child)[0] >= parameters_end and child.type != "virtual_specifier"
            for leaf in leaves(child)
        ]
        shape = Shape(_normalized(returns), tuple(read.types), _normalized(qualifiers))
        return ReadSignature(shape, read)

    def parameters(self, parameters: tree_sitter.Node) -> Parameters:
        read = Parameters()
        named = parameters.named_children
        for child in parameters.children:
            if child.type == "...":
                where = self.text.span(child)[0]
                return Parameters(
                    problem=Problem(where, "C-style variadic functions cannot be layered")
                )
        for parameter in named:
            start = self.text.span(parameter)[0]
            if parameter.type == "comment":
                continue
            if parameter.type not in ("parameter_declaration", "optional_parameter_declaration"):
                like = self.text.text(parameter)
                message = f"cannot layer a function with a parameter like {like!r}"
                return Parameters(problem=Problem(start, message))
            declarator = parameter.child_by_field_name("declarator")
            name_node = _declared_name(declarator) if declarator is not None else None
            default = parameter.child_by_field_name("default_value")
            cut = self.text.span(default)[1] if default is not None else None
            type_end = self.text.span(declarator)[1] if declarator is not None else None
            parts = [
                self.text.text(leaf)
                for leaf in leaves(parameter)
                if (name_node is None or leaf.start_byte != name_node.start_byte)
                and (type_end is None or default is None or self.text.span(leaf)[0] < type_end)
            ]
            if parts == ["void"] and len(named) == 1:
                break
            read.types.append(_normalized(parts))
            read.names.append(self.text.text(name_node) if name_node is not None else None)
            if default is not None and cut is not None and type_end is not None:
                read.defaults.append((type_end, cut))
        return read


# Said only where a member function is declared in its class, not where it is defined.
_SPECIFIERS = frozenset({"virtual", "static", "inline", "explicit", "friend", "constexpr"})


def _normalized(parts: list[str]) -> str:
    text = ""
    for part in parts:
        glue = "" if not text or text.endswith(("::", "(", "<", "~")) else " "
        if part in ("::", ",", ")", ">", "&", "&&", "*") or part.startswith("("):
            glue = "" if part in ("::", ",", ")", ">") else glue
        text += glue + part
    return text


def _unterminated(error: tree_sitter.Node) -> bool:
    """A statement tree-sitter could not end: one line ending in a complete expression (`f(x)`,
    `x`), the next statement on a later line. Its ';' is missing."""
    if error.type != "ERROR" or error.parent is None or error.parent.type != "compound_statement":
        return False
    following = error.next_sibling
    last = error.children[-1] if error.children else None
    return (
        error.start_point.row == error.end_point.row
        and following is not None
        and following.start_point.row > error.end_point.row
        and last is not None
        and (last.type in ("call_expression", "identifier") or last.type.endswith("literal"))
    )


# Tokens that may stand anywhere in broken code: keywords, brackets, ';'.
_NOT_STRAY = frozenset({"{", "}", ";", "(", ")", "[", "]"})


def _stray(error: tree_sitter.Node, *, in_body: bool = True) -> tree_sitter.Node:
    """In code tree-sitter could not read, the first punctuation that fits nowhere
    (`return x:`; in a definition: in its body), else the whole of it."""
    inside = not in_body
    for child in error.children:
        if child.type == "{":
            inside = True
        elif (
            inside
            and not child.is_named
            and not child.type.isidentifier()
            and (child.type not in _NOT_STRAY)
        ):
            return child
    return error


def function_declarator(node: tree_sitter.Node | None) -> tree_sitter.Node | None:
    """The function declarator under pointer and reference declarators (`T& f()`), if any."""
    while node is not None and node.type in ("pointer_declarator", "reference_declarator"):
        inner = node.child_by_field_name("declarator")
        if inner is None:
            named = [c for c in node.named_children if c.type.endswith("declarator")]
            inner = named[0] if named else None
        node = inner
    return node if node is not None and node.type == "function_declarator" else None


def _ref_qualifier(node: tree_sitter.Node | None) -> tree_sitter.Node | None:
    """The `&` or `&&` after a method's parameters, if any."""
    declarator = function_declarator(node)
    if declarator is None:
        return None
    return next((c for c in declarator.children if c.type == "ref_qualifier"), None)


def _declared_name(node: tree_sitter.Node) -> tree_sitter.Node | None:
    """The identifier a (possibly nested) parameter declarator declares."""
    current: tree_sitter.Node | None = node
    while current is not None:
        if current.type == "identifier":
            return current
        inner = current.child_by_field_name("declarator")
        if inner is None:
            nested = [
                c
                for c in current.named_children
                if c.type == "identifier" or c.type.endswith("declarator")
            ]
            inner = nested[0] if nested else None
        current = inner
    return None


def _calls(node: tree_sitter.Node) -> list[tree_sitter.Node]:
    found: list[tree_sitter.Node] = []
    stack = [node]
    while stack:
        current = stack.pop()
        if current.type == "call_expression":
            found.append(current)
        stack.extend(current.named_children)
    found.sort(key=lambda n: n.start_byte)
    return found
