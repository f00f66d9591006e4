"""The checker: consistency errors and the warnings of the layer interaction problem.

Errors make a file uncompilable (unknown layers, duplicate definitions, incompatible
signatures). Warnings point at behaviour that depends on something the file does not
say: two layers refining the same method that may be active together with no declared
order, `requires` cycles, and layers that the declared relations make impossible to
activate.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterable, Sequence
from itertools import combinations
from pathlib import Path
from types import MethodDescriptorType, WrapperDescriptorType
from typing import TYPE_CHECKING

from contextros.language.bindings import LifecycleBinding, ParameterBinding, ParameterValue
from contextros.language.diagnostics import (
    Diagnostic,
    DiagnosticSink,
    LayerSyntaxError,
    sorted_diagnostics,
)
from contextros.language.flavours import parse_with_diagnostics, read_source, unreadable
from contextros.language.python_syntax import guard_name
from contextros.language.syntax import Function, LayerDecl, LayerFile, Position, Ref
from contextros.language.words import RELATIONS

if TYPE_CHECKING:
    from contextros.rules.ruleset import MessageTypes

# Names the compiled module defines besides the generated functions and the layers
# (compiler.py), each with what it is; a layer or a method of that name would replace it.
RESERVED_NAMES = frozenset({"proceed"})
PYTHON_RESERVED_NAMES = {
    "proceed": "a name the compiled module imports",
    "_Layer": "a name the compiled module imports",
    "_layered": "a name the compiled module imports",
    "_layered_method": "a name the compiled module imports",
    "__layers__": "the compiled module's list of its layers",
    "__layer_order__": "the compiled module's list of its 'after' orders",
    # Set on every module by Python's import system.
    **dict.fromkeys(
        (
            "__name__",
            "__file__",
            "__doc__",
            "__builtins__",
            "__spec__",
            "__loader__",
            "__package__",
            "__cached__",
            "__path__",
        ),
        "a name Python sets on every module",
    ),
}
# Decorators that turn a function into something the core cannot layer.
DESCRIPTORS = frozenset({"staticmethod", "classmethod", "property"})
# What every class inherits from `object` that is not an instance method (a static method,
# class methods, attributes): `def C.__new__(cls)` could never be layered.
_OBJECT_ATTRIBUTES = {
    name: {
        "builtin_function_or_method": "a static method",
        "classmethod_descriptor": "a class method",
    }.get(type(value).__name__, f"a {type(value).__name__!r} attribute")
    for name, value in vars(object).items()
    if not isinstance(value, (WrapperDescriptorType, MethodDescriptorType))
}


def check_source(
    source: str,
    path: str = "<layers>",
    language: str | None = None,
    message_types: MessageTypes | None = None,
) -> list[Diagnostic]:
    """Every diagnostic of a layer file, sorted by position. Never raises them.

    `language` ("python" or "cpp") overrides the flavour the file name implies. With
    `message_types` (a message type's field lookup by name), the rules' fields are checked
    against their topics' declared types, as the Layer manager checks them at run time.
    """
    layer_file, found = parse_with_diagnostics(source, path, language)
    return sorted_diagnostics([*found, *check(layer_file, message_types)])


def check_file(
    path: str | Path, language: str | None = None, message_types: MessageTypes | None = None
) -> list[Diagnostic]:
    """`check_source` for a file on disk (an unreadable file is an error at 1:1)."""
    return check_files([path], language, message_types)


def check_files(
    paths: Iterable[str | os.PathLike[str]],
    language: str | None = None,
    message_types: MessageTypes | None = None,
) -> list[Diagnostic]:
    """Every diagnostic of layer files a Layer manager runs together: each file's, as
    `check_file` finds them, then the errors only the files together have (a rule name or
    a topic's type declared in two of them, a rule's fields against another file's topic
    declaration). File by file in the order given, each sorted by position."""
    from contextros.rules.ruleset import RuleSet

    by_file: dict[str, list[Diagnostic]] = {}
    parsed: list[tuple[str, str, LayerFile]] = []
    for path in paths:
        name = os.fspath(path)
        try:
            source = read_source(name)
        except (OSError, UnicodeDecodeError) as error:
            by_file[name] = unreadable(name, error)
            continue
        layer_file, found = parse_with_diagnostics(source, name, language)
        by_file[name] = [*found, *check(layer_file)]
        parsed.append((name, source, layer_file))
    rules = RuleSet.from_parsed(parsed)
    # Across the files, errors only (a rule name or a topic's type declared twice: each
    # file's warnings stand); the declared topics' fields once, against every declaration.
    together = [d for d in rules.check() if d.is_error]
    if message_types is not None:
        together += rules.check_declared_fields(message_types)
    for diagnostic in together:
        by_file.setdefault(diagnostic.path, []).append(diagnostic)
    return [d for found in by_file.values() for d in sorted_diagnostics(found)]


def checked(
    source: str, path: str = "<layers>", language: str | None = None
) -> tuple[LayerFile, list[Diagnostic]]:
    """Parse and check; raise `LayerSyntaxError` on errors, else return the tree and warnings."""
    layer_file, found = parse_with_diagnostics(source, path, language)
    diagnostics = sorted_diagnostics([*found, *check(layer_file)])
    errors = [d for d in diagnostics if d.is_error]
    if errors:
        raise LayerSyntaxError(errors)
    return layer_file, diagnostics


def check(layer_file: LayerFile, message_types: MessageTypes | None = None) -> list[Diagnostic]:
    """The semantic checks of a parsed (possibly partial) layer file (`message_types`: see
    `check_source`)."""
    return _Checker(layer_file, message_types).run()


def check_activation_order(
    layer_file: LayerFile, activation: Sequence[str], where: str = "activation order"
) -> list[Diagnostic]:
    """Warnings where `activation` (layers in the order they would be activated, the last
    outermost) contradicts the file's `after` declarations: the Layer manager composes in the
    declared order instead, so the requested order would not be the one that runs."""
    checker = _Checker(layer_file)
    checker._declarations()
    after = {name: checker._closure(name, "after") for name in checker.layers}
    order = list(dict.fromkeys(activation))
    for index, earlier in enumerate(order):
        for later in order[index + 1 :]:
            if later not in after.get(earlier, set()):
                continue
            # `earlier` is declared after `later`, yet requested before it.
            layer = checker.layers[earlier]
            ref = next((r for r in layer.after if r.name == later), None)
            at = ref.at if ref is not None else layer.at
            declared = (
                f"'layer {earlier} after {later}' is declared here"
                if ref is not None
                else f"{earlier} comes after {later} through the 'after' declarations from here"
            )
            checker.sink.warning(
                f"{where} {', '.join(order)} activates {earlier} before {later}, but "
                f"{declared}: the Layer manager "
                f"composes {later} first and {earlier} outermost; list {later} first",
                at.line,
                at.col,
            )
    return checker.sink.items


# Why a cycle of a relation is an error.
_CYCLE_ERRORS = {
    "after": "an order cannot go both ways",
    "implies": "a layer cannot imply itself",
}


class _Checker:
    def __init__(self, layer_file: LayerFile, message_types: MessageTypes | None = None) -> None:
        self.file = layer_file
        self.message_types = message_types
        self.sink = DiagnosticSink(layer_file.path, layer_file.source)
        self.layers: dict[str, LayerDecl] = {}
        self.group_of: dict[str, str] = {}
        self.excluded: set[frozenset[str]] = set()
        self.broken: set[str] = set()  # layers whose relations are already errors
        # Filled by _interaction: the closures of 'requires' and 'after', and which layers
        # can be activated at all.
        self.requires: dict[str, set[str]] = {}
        self.after: dict[str, set[str]] = {}
        self.possible: dict[str, bool] = {}

    def run(self) -> list[Diagnostic]:
        self._declarations()
        self._groups()
        self._relations()
        self._functions()
        self._names()
        self._interaction()
        self._rules()
        self._bindings()
        return self.sink.items

    # -- context rules (language-neutral) ------------------------------------------------

    def _rules(self) -> None:
        if not self.file.rules and not self.file.topics:
            return
        from contextros.rules.ruleset import RuleSet

        for rule in self.file.rules:
            for ref in (rule.layer, rule.otherwise):
                if ref is not None and self.layers and ref.name not in self.layers:
                    self.sink.warning(
                        f"rule {rule.name} switches layer {ref.name!r}, which this file does "
                        f"not declare{self._did_you_mean(ref.name)}: the Layer manager "
                        "refuses it unless a node implements it",
                        ref.at.line,
                        ref.at.col,
                    )
        relations = {
            name: (
                frozenset({self.group_of[name]}) if name in self.group_of else frozenset(),
                frozenset(
                    other for pair in self.excluded if name in pair for other in pair - {name}
                ),
            )
            for name in self.layers
        }
        rules = RuleSet(self.file.rules, {self.file.path: self.file.source}, self.file.topics)
        self.sink.items += rules.check(relations, self.message_types)

    # -- declarations and relations ---------------------------------------------------

    def _declarations(self) -> None:
        for layer in self.file.layers:
            first = self.layers.get(layer.name)
            if first is not None:
                self.sink.error(
                    f"layer {layer.name!r} is already declared at line {first.at.line}",
                    layer.at.line,
                    layer.at.col,
                )
                continue
            self.layers[layer.name] = layer

    def _known(self, ref: Ref, context: str) -> bool:
        if ref.name in self.layers:
            return True
        known = ", ".join(self.layers) or "none"
        self.sink.error(
            f"unknown layer {ref.name!r} in {context} (declared layers: {known})",
            ref.at.line,
            ref.at.col,
        )
        return False

    def _groups(self) -> None:
        seen: dict[str, int] = {}
        for group in self.file.groups:
            if group.name in seen:
                self.sink.error(
                    f"group {group.name!r} is already declared at line {seen[group.name]}",
                    group.at.line,
                    group.at.col,
                )
                continue
            seen[group.name] = group.at.line
            members: set[str] = set()
            for ref in group.members:
                if not self._known(ref, f"group {group.name!r}"):
                    continue
                if ref.name in members:
                    self.sink.error(
                        f"layer {ref.name!r} is listed twice in group {group.name!r}",
                        ref.at.line,
                        ref.at.col,
                    )
                    continue
                other = self.group_of.get(ref.name)
                if other is not None:
                    self.sink.error(
                        f"layer {ref.name!r} is already in group {other!r}; "
                        "a layer belongs to at most one group",
                        ref.at.line,
                        ref.at.col,
                    )
                    continue
                members.add(ref.name)
                self.group_of[ref.name] = group.name
            for a, b in combinations(sorted(members), 2):
                self.excluded.add(frozenset((a, b)))

    def _relations(self) -> None:
        for layer in self.layers.values():
            for relation in RELATIONS:
                refs: list[Ref] = getattr(layer, relation)
                for ref in refs:
                    if not self._known(ref, f"'{relation}' of layer {layer.name!r}"):
                        continue
                    if ref.name == layer.name:
                        self.broken.add(layer.name)
                        self.sink.error(
                            f"layer {layer.name!r} names itself in '{relation}'",
                            ref.at.line,
                            ref.at.col,
                        )
                    elif relation == "excludes":
                        self.excluded.add(frozenset((layer.name, ref.name)))
                    elif relation in ("requires", "implies") and ref.name in {
                        r.name for r in layer.excludes
                    }:
                        self.broken.add(layer.name)
                        self.sink.error(
                            f"layer {layer.name!r} both {relation} and excludes {ref.name!r}",
                            ref.at.line,
                            ref.at.col,
                        )

    def _refs(self, layer: str, relation: str) -> list[str]:
        decl = self.layers[layer]
        names = [r.name for r in getattr(decl, relation)]
        return [n for n in names if n in self.layers and n != layer]

    def _closure(self, layer: str, relation: str) -> set[str]:
        found: set[str] = set()
        pending = self._refs(layer, relation)
        while pending:
            name = pending.pop()
            if name not in found:
                found.add(name)
                pending.extend(self._refs(name, relation))
        return found

    # -- functions ----------------------------------------------------------------------

    def _functions(self) -> None:
        names, star = set(self.file.header_names), self.file.header_opaque
        first_impl: dict[str, Function] = {}
        for block_name, functions in self._function_blocks():
            seen: dict[str, Function] = {}
            for function in functions:
                earlier = seen.get(function.key)
                if earlier is not None:
                    self.sink.error(
                        f"{function.key} is already defined in {block_name} "
                        f"at line {earlier.at.line}"
                        + _overload_hint(earlier, function, self.file.language),
                        function.at.line,
                        function.at.col,
                    )
                    continue
                seen[function.key] = function
                self._owner(function, names, star)
                self._decorators(function)
                first = first_impl.setdefault(function.key, function)
                if first is not function:
                    self._compatible(first, function)
                self._proceed_arguments(function)
                if function.layer is None and function.proceed_calls:
                    self.sink.warning(
                        f"proceed() in the base implementation of {function.key} has no next "
                        "implementation to run: it raises at run time",
                        function.at.line,
                        function.at.col,
                    )

    def _function_blocks(self) -> Iterable[tuple[str, list[Function]]]:
        base = [f for block in self.file.bases for f in block.functions]
        if base:
            yield "the base block", base
        seen: set[str] = set()
        for layer in self.file.layers:
            if layer.name in seen:
                continue  # a duplicate layer is already an error
            seen.add(layer.name)
            yield f"layer {layer.name!r}", layer.functions

    def _owner(self, function: Function, names: set[str], star: bool) -> None:
        if function.owner is None:
            return
        is_namespace = getattr(self.file, "is_namespace", None)
        if is_namespace is not None and is_namespace(function.owner):
            return  # refused where the namespace is found (cpp/parser.py)
        if function.owner not in names and not star:
            self.sink.error(
                f"class {function.owner!r} is not defined in the header: "
                f"{'include' if self.file.language == 'cpp' else 'import'} it or define "
                "it above the first declaration",
                function.at.line,
                function.at.col,
            )
        if not function.takes_instance:
            self.sink.error(
                f"method {function.key} takes no parameters: it needs one for the instance (self)",
                function.at.line,
                function.at.col,
            )
        inherited = _OBJECT_ATTRIBUTES.get(function.name)
        if self.file.language == "python" and inherited is not None:
            self.sink.error(
                f"{function.key} cannot be layered: every class has {function.name} from "
                f"object, as {inherited}, and a layer refines only instance methods "
                "(plain functions such as __init__ or __repr__)",
                function.at.line,
                function.at.col,
            )

    def _proceed_arguments(self, function: Function) -> None:
        """`proceed` takes the method's own arguments, the instance first (Python)."""
        if function.owner is None or function.layer is None or not function.takes_instance:
            return
        for call in function.proceed_calls:
            if call.passes_instance:
                continue
            self.sink.warning(
                f"proceed() in {function.key} does not pass the instance first: the next "
                f"implementation is called with the method's arguments, as "
                f"proceed({function.instance_name}, ...)",
                call.at.line,
                call.at.col,
            )

    def _decorators(self, function: Function) -> None:
        for decorator in function.decorators:
            if decorator.text in DESCRIPTORS:
                self.sink.error(
                    f"@{decorator.text} makes {function.key} a {decorator.text} object; layered "
                    "implementations must stay plain functions",
                    function.at.line,
                    function.at.col,
                )
            else:
                # Whatever a decorator returns (functools.cache: a cache object; a wrapper:
                # a function whose body is not the one calling proceed) would be layered
                # in place of the implementation; the checker cannot know it is a plain
                # function, so none is accepted.
                self.sink.error(
                    f"decorators are not supported on implementations: @{decorator.text} "
                    f"would replace {function.key} by what it returns, and the core layers "
                    "only the plain function; decorate a helper in the header and call it "
                    "from the body",
                    decorator.at.line,
                    decorator.at.col,
                )

    def _compatible(self, first: Function, other: Function) -> None:
        where = f"layer {first.layer}" if first.layer else "the base block"
        if first.is_async != other.is_async:
            self.sink.error(
                f"{other.signature.text} is {'' if other.is_async else 'not '}async, but "
                f"{first.key} in {where} (line {first.at.line}) is "
                f"{'' if first.is_async else 'not '}async",
                other.at.line,
                other.at.col,
            )
        elif first.signature.shape != other.signature.shape:
            self.sink.error(
                f"incompatible signature: {other.signature.text} does not match "
                f"{first.signature.text} in {where} (line {first.at.line})"
                + _overload_hint(first, other, self.file.language),
                other.at.line,
                other.at.col,
            )

    def _names(self) -> None:
        """Names the compiled module defines must not collide with each other or the header."""
        header = self.file.header_names
        taken = dict.fromkeys(header, "a name defined in the header")
        reserved = (
            PYTHON_RESERVED_NAMES
            if self.file.language == "python"
            else dict.fromkeys(RESERVED_NAMES, "a name the compiled module imports")
        )
        for name, what in reserved.items():
            taken.setdefault(name, what)
        for layer in self.layers.values():
            if layer.name in taken:
                self.sink.error(
                    f"layer {layer.name!r} would shadow {layer.name!r}, {taken[layer.name]}",
                    layer.at.line,
                    layer.at.col,
                )
            taken[layer.name] = f"layer {layer.name!r}"
            # Hooks compile to functions of the module (on_activate_<Layer>, ...).
            hook_lines: dict[str, int] = {}
            for hook in layer.hooks:
                if hook.event in hook_lines:
                    self.sink.error(
                        f"layer {layer.name!r} already has an 'on {hook.event}' hook at line "
                        f"{hook_lines[hook.event]}",
                        hook.at.line,
                        hook.at.col,
                    )
                    continue
                hook_lines[hook.event] = hook.at.line
                claimant = f"the 'on {hook.event}' hook of layer {layer.name!r}"
                owner = taken.setdefault(hook.generated_name, claimant)
                if owner != claimant:
                    self.sink.error(
                        f"the compiled name {hook.generated_name!r} of the 'on {hook.event}' "
                        f"hook of layer {layer.name!r} is already {owner}; rename the layer",
                        hook.at.line,
                        hook.at.col,
                    )
        seen: set[tuple[str | None, str]] = set()
        for function in sorted(self.file.all_functions(), key=lambda f: (f.at.line, f.at.col)):
            if (function.layer, function.key) in seen:
                continue  # a duplicate definition, already reported
            seen.add((function.layer, function.key))
            key = function.key
            dispatch = (
                function.name if function.owner is None else f"{function.owner}_{function.name}"
            )
            claims = [(dispatch, f"the dispatch function of {key}", "the dispatch function")]
            if function.layer is not None:
                claims.append(
                    (
                        function.generated_name,
                        f"{key} in layer {function.layer}",
                        "the compiled name",
                    )
                )
                if function.guard is not None and self.file.language == "python":
                    claims.append(
                        (
                            guard_name(function),
                            f"the guard of {key} in layer {function.layer}",
                            "the compiled name of the guard",
                        )
                    )
            elif function.guard is not None:
                self.sink.error(
                    f"a guard ('when ...') belongs to a layer's partial; the base "
                    f"implementation of {key} always applies: move the condition to a layer",
                    function.guard.at.line,
                    function.guard.at.col,
                )
            for name, claimant, what in claims:
                owner = taken.setdefault(name, claimant)
                if owner != claimant:
                    self.sink.error(
                        f"{what} {name!r} of {key} is already {owner}; rename the method or "
                        "the layer",
                        function.at.line,
                        function.at.col,
                    )

    # -- the layer interaction problem ---------------------------------------------------

    def _conflict(self, names: set[str]) -> tuple[str, str] | None:
        for a, b in combinations(sorted(names), 2):
            if frozenset((a, b)) in self.excluded:
                return a, b
        return None

    def _unordered(self, a: str, b: str) -> bool:
        """Whether declared layers `a` and `b` may be active together with no declared order
        between them: then what both define depends on which was activated last."""
        if a == b or not (self.possible.get(a) and self.possible.get(b)):
            return False
        if self._conflict({a, b, *self.requires[a], *self.requires[b]}) is not None:
            return False
        return b not in self.after[a] and a not in self.after[b]

    def _interaction(self) -> None:
        implies = {name: self._closure(name, "implies") for name in self.layers}
        required = {name: self._closure(name, "requires") for name in self.layers}
        self._cycles("requires", required, error=False)
        # What a layer implies is active whenever it is, as what it requires must be.
        requires = self.requires = {name: required[name] | implies[name] for name in self.layers}
        after = self.after = {name: self._closure(name, "after") for name in self.layers}
        self._cycles("after", after, error=True)
        self._cycles("implies", implies, error=True)
        self._implications(implies)
        possible = self.possible
        for name, layer in self.layers.items():
            needed = {name, *requires[name]}
            conflict = self._conflict(needed)
            possible[name] = conflict is None
            if conflict is not None and name not in self.broken:
                a, b = conflict
                via = f"it requires {', '.join(sorted(requires[name]))}; " if requires[name] else ""
                self.sink.warning(
                    f"layer {name!r} can never be activated: {via}{a!r} and {b!r} exclude "
                    "each other",
                    layer.at.line,
                    layer.at.col,
                )
        by_method: dict[str, list[Function]] = {}
        for layer in self.layers.values():
            for function in layer.functions:
                by_method.setdefault(function.key, []).append(function)
        keyword = "Layer" if self.file.language == "cpp" else "layer"
        for key, functions in by_method.items():
            for first, second in combinations(functions, 2):
                a, b = first.layer or "", second.layer or ""
                if not self._unordered(a, b):
                    continue
                self.sink.warning(
                    f"{key} is refined by layers {a!r} (line {first.at.line}) and {b!r}, which "
                    "may be active together with no declared order, so the result depends on "
                    f"which was activated last; declare '{keyword} {b} after {a}' (or the "
                    "reverse), or make them exclusive ('excludes', 'group')",
                    second.at.line,
                    second.at.col,
                )

    def _cycles(self, relation: str, closure: dict[str, set[str]], *, error: bool) -> None:
        reported: set[frozenset[str]] = set()
        for name, layer in self.layers.items():
            if name not in closure[name]:
                continue
            members = frozenset(n for n in closure[name] if name in closure[n])
            if members in reported:
                continue
            reported.add(members)
            refs: list[Ref] = getattr(layer, relation)
            ref = next((r for r in refs if r.name in members), layer)
            cycle = " -> ".join([*sorted(members), sorted(members)[0]])
            message = f"'{relation}' cycle: {cycle}"
            if error:
                if relation == "implies":
                    self.broken.update(members)
                why = _CYCLE_ERRORS[relation]
                self.sink.error(f"{message}; {why}", ref.at.line, ref.at.col)
            else:
                self.sink.warning(
                    message + "; these layers can only be activated together, in one switch",
                    ref.at.line,
                    ref.at.col,
                )

    def _implications(self, implies: dict[str, set[str]]) -> None:
        """A layer implying two layers of one group, a layer it excludes, or a layer that
        excludes another it implies: an error at the 'implies' entry that brings the
        contradiction in, said once, of the innermost layer implying both."""
        contradictory: set[str] = set()
        # Innermost first: a layer whose implied layers are settled comes after them.
        pending = [name for name in self.layers if name not in self.broken]
        while pending:
            ready = [n for n in pending if not (implies[n] & set(pending)) or n in implies[n]]
            ready = ready or pending  # a cycle, reported already
            for name in ready:
                pending.remove(name)
                if implies[name] & (contradictory | self.broken) or name in implies[name]:
                    contradictory.add(name)  # said of the implied layer already
                    self.broken.add(name)
                    continue
                problem = self._contradiction(name, implies)
                if problem is not None:
                    contradictory.add(name)
                    self.broken.add(name)
                    message, ref = problem
                    self.sink.error(message, ref.at.line, ref.at.col)

    def _contradiction(self, name: str, implies: dict[str, set[str]]) -> tuple[str, Ref] | None:
        members = sorted({name, *implies[name]})
        for a, b in combinations(members, 2):
            if frozenset((a, b)) not in self.excluded:
                continue
            # The last 'implies' entry of `name` that brings a or b: where it contradicts.
            ref = [
                r
                for r in self.layers[name].implies
                if r.name in (a, b) or {a, b} & implies.get(r.name, set())
            ][-1]
            other = b if a == name else a if b == name else ""
            group = self.group_of.get(a)
            if other:
                what = f"layer {name!r} implies {other!r}"
            else:
                what = f"layer {name!r} implies {a!r} and {b!r}"
            if group is not None and group == self.group_of.get(b):
                why = f"both in group {group!r}, of which at most one is active"
            elif not other:
                why = "which exclude each other"
            else:
                excluded = {r.name for r in self.layers[name].excludes}
                why = "which it excludes" if other in excluded else "which excludes it"
            return f"{what}, {why}", ref
        return None

    # -- parameter and lifecycle bindings (language-neutral) ------------------------------

    def _bindings(self) -> None:
        """Bindings naming layers the file does not declare, and two bindings of one node
        parameter (one lifecycle node) to different values by layers that may be active
        together with no declared order: the value would depend on the activation order."""
        items: list[tuple[str, str, ParameterValue, Ref, Position]] = [
            ("parameter", f"{p.node} {p.name}", p.value, p.layer, p.at)
            for p in self.file.parameters
        ]
        items += [("lifecycle", c.node, c.state, c.layer, c.at) for c in self.file.lifecycles]
        warned: set[Position] = set()
        for kind, _, _, layer, _ in items:
            if self.layers and layer.name not in self.layers and layer.at not in warned:
                warned.add(layer.at)
                self.sink.warning(
                    f"{kind} of layer {layer.name!r}, which this file does not declare"
                    f"{self._did_you_mean(layer.name)}: the Layer manager given this file "
                    "knows it as a layer of its own that only binds ROS nodes",
                    layer.at.line,
                    layer.at.col,
                )
        keyword = "Layer" if self.file.language == "cpp" else "layer"
        # What each layer binds first, per node parameter / lifecycle node, in file order.
        bound: dict[tuple[str, str], dict[str, tuple[ParameterValue, Position]]] = {}
        for kind, key, value, layer, at in items:
            what = f"parameter {key}" if kind == "parameter" else f"lifecycle node {key}"
            by_layer = bound.setdefault((kind, key), {})
            for other, (other_value, other_at) in by_layer.items():
                if _same(other_value, value):
                    continue
                if other == layer.name:
                    self.sink.warning(
                        f"{what} is already bound to {_shown(other_value, kind)} by layer "
                        f"{other!r} at line {other_at.line}: the later line wins",
                        at.line,
                        at.col,
                    )
                elif self._unordered(other, layer.name):
                    self.sink.warning(
                        f"{what} is bound to {_shown(other_value, kind)} by layer {other!r} (line "
                        f"{other_at.line}) and to {_shown(value, kind)} by layer {layer.name!r}, "
                        "which may be active together with no declared order, so it depends "
                        f"on which was activated last; declare '{keyword} {layer.name} after "
                        f"{other}' (or the reverse), or make them exclusive ('excludes', "
                        "'group')",
                        at.line,
                        at.col,
                    )
            by_layer.setdefault(layer.name, (value, at))
        self._nothing_to_infer(bound)

    def _did_you_mean(self, name: str) -> str:
        """' (did you mean 'Slow'?)' for a name close to a layer the file declares."""
        close = difflib.get_close_matches(name, self.layers, n=1)
        return f" (did you mean {close[0]!r}?)" if close else ""

    def _nothing_to_infer(
        self, bound: dict[tuple[str, str], dict[str, tuple[ParameterValue, Position]]]
    ) -> None:
        """`on drift infer` on a binding whose node parameter (lifecycle node) no other layer
        of the file binds: no layer can ever be inferred from its drift."""
        policies: list[tuple[str, str, ParameterBinding | LifecycleBinding]] = [
            ("parameter", f"{p.node} {p.name}", p) for p in self.file.parameters
        ]
        policies += [("lifecycle", c.node, c) for c in self.file.lifecycles]
        for kind, key, binding in policies:
            if binding.policy == "infer" and set(bound[(kind, key)]) == {binding.layer.name}:
                what = f"parameter {key}" if kind == "parameter" else f"lifecycle node {key}"
                self.sink.warning(
                    f"on drift infer: no other layer of this file binds {what}, so no layer "
                    "can be inferred from its drift (it is only reported)",
                    binding.at.line,
                    binding.at.col,
                )


def _same(a: ParameterValue, b: ParameterValue) -> bool:
    """The same value as ROS receives it (1 and 1.0 and true are not the same)."""
    return type(a) is type(b) and a == b


def _shown(value: ParameterValue, kind: str) -> str:
    """A value as written in a layer file (a lifecycle state unquoted: `active`)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str) and kind == "parameter":
        return repr(value)
    return str(value)


def _overload_hint(first: Function, other: Function, language: str) -> str:
    """What to write instead when two C++ implementations differ in their parameter types:
    overloads, which cannot be layered (the dispatch is found by name)."""
    if language != "cpp" or first.signature.shape[1] == other.signature.shape[1]:
        return ""
    types = other.signature.shape[1]
    words = "_".join(_type_word(t) for t in types) if isinstance(types, tuple) else ""
    return (
        f"; C++ overloads cannot be layered: give this overload its own name "
        f"({other.name}_{words or 'void'}) "
        f"and layer it, and overload {other.name} in the header part to call it"
    )


def _type_word(type_text: object) -> str:
    return "".join(c if c.isalnum() else "_" for c in str(type_text).split("::")[-1]).strip("_")
