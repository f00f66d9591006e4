"""Layer declarations as participants announce them, and the relation check the manager runs.

The manager learns layers and their relations (excludes, requires, group, after, implies)
from the participants, and from its own layer files (`contextros manager --layers`), and
validates every activation against the union of what they declared, so a node cannot be
asked for a configuration another node forbids.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cached_property


@dataclass(frozen=True)
class LayerDeclaration:
    """A layer a participant implements, with the relations it declares for it."""

    name: str
    excludes: frozenset[str] = frozenset()
    requires: frozenset[str] = frozenset()
    group: str = ""
    # Layers this one comes after (outside) when both are active (`layer X after B`).
    after: frozenset[str] = frozenset()
    # Layers active whenever this one is, brought in and taken out with it (`implies`).
    implies: frozenset[str] = frozenset()

    def merged(self, other: LayerDeclaration) -> LayerDeclaration:
        """The union of two nodes' declarations of one layer (the stricter reading)."""
        groups = sorted(self.groups | other.groups)
        return LayerDeclaration(
            name=self.name,
            excludes=self.excludes | other.excludes,
            requires=self.requires | other.requires,
            group=",".join(groups),
            after=self.after | other.after,
            implies=self.implies | other.implies,
        )

    @cached_property
    def groups(self) -> frozenset[str]:
        # Asked on every command for every layer: split once (a frozen value's cache).
        return frozenset(g for g in self.group.split(",") if g)


def merge_declarations(
    declarations: Iterable[LayerDeclaration],
) -> dict[str, LayerDeclaration]:
    merged: dict[str, LayerDeclaration] = {}
    for declaration in declarations:
        known = merged.get(declaration.name)
        merged[declaration.name] = declaration if known is None else known.merged(declaration)
    return merged


def with_layer_files(
    implemented: Mapping[str, LayerDeclaration], layer_files: Iterable[LayerDeclaration]
) -> dict[str, LayerDeclaration]:
    """The declarations the manager composes and validates with: each layer the
    participants implement (`implemented`, merged) and each layer its layer files declare
    (known as declared by the manager itself, implemented by no participant or not), with
    the relations of both merged. The one place where the two meet, live and in a replay."""
    extra = tuple(layer_files)
    if not extra:
        return dict(implemented)
    return merge_declarations([*implemented.values(), *extra])


def relation_violations(
    active: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> list[str]:
    """Every relation the configuration `active` breaks, as sentences naming the layers."""
    active_set = set(active)
    problems: list[str] = []
    for name in sorted(active_set):
        declaration = declarations.get(name)
        if declaration is None:
            continue
        for excluded in sorted(declaration.excludes & active_set):
            # Report each mutually exclusive pair once.
            mutual = name in _excludes_of(excluded, declarations)
            if excluded != name and (excluded > name or not mutual):
                problems.append(f"{name} excludes {excluded}, both would be active")
        for required in sorted(declaration.requires - active_set):
            problems.append(f"{name} requires {required}, which would not be active")
    members: dict[str, list[str]] = {}
    for name in sorted(active_set):
        declaration = declarations.get(name)
        for group in sorted(declaration.groups) if declaration else ():
            members.setdefault(group, []).append(name)
    for group, names in sorted(members.items()):
        if len(names) > 1:
            listing = ", ".join(names)
            problems.append(f"group {group!r} allows one active layer, would have {listing}")
    return problems


def _excludes_of(name: str, declarations: Mapping[str, LayerDeclaration]) -> frozenset[str]:
    declaration = declarations.get(name)
    return declaration.excludes if declaration else frozenset()


def implied_layers(name: str, declarations: Mapping[str, LayerDeclaration]) -> tuple[str, ...]:
    """What `name` implies, transitively, in activation order: each implied layer before the
    layer implying it, depth first, by name (`name` itself not included, cycles cut).
    Iterative: a chain of any length (declarations come from the network) is no recursion."""
    declaration = declarations.get(name)
    if declaration is None or not declaration.implies:
        return ()  # most layers imply nothing: the common case costs one look-up
    found: list[str] = []
    seen = {name}
    # Each entry: a layer and the layers it implies still to visit (reversed: pop the next).
    stack = [(name, _implied_of(name, declarations))]
    while stack:
        layer, pending = stack[-1]
        if not pending:
            stack.pop()
            if layer != name:
                found.append(layer)
            continue
        implied = pending.pop()
        if implied not in seen:
            seen.add(implied)
            stack.append((implied, _implied_of(implied, declarations)))
    return tuple(found)


def _implied_of(name: str, declarations: Mapping[str, LayerDeclaration]) -> list[str]:
    declaration = declarations.get(name)
    return sorted(declaration.implies, reverse=True) if declaration else []


def with_implied(
    explicit: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> tuple[str, ...]:
    """The layers `explicit` make active: each with what it implies just before it."""
    layers: dict[str, None] = {}
    for name in explicit:
        layers.update(dict.fromkeys((*implied_layers(name, declarations), name)))
    return tuple(layers)


def implied_by(
    active: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> dict[str, tuple[str, ...]]:
    """For each layer of `active` that another active layer implies, those layers (directly
    implying it), by name: `{"Propulsion": ("Flight",)}`."""
    active_set = set(active)
    found: dict[str, list[str]] = {}
    for name in sorted(active_set):
        declaration = declarations.get(name)
        for implied in sorted(declaration.implies & active_set) if declaration else ():
            if implied != name:
                found.setdefault(implied, []).append(name)
    return {name: tuple(by) for name, by in sorted(found.items())}


def listed_with_implied(active: Iterable[str], by: Mapping[str, Iterable[str]]) -> str:
    """`CameraHigh (implied by Flight), Flight (implied by Mission), Mission`: the active
    layers as status and watch show them (`by`: what `implied_by` gives)."""
    return ", ".join(
        f"{name} (implied by {', '.join(by[name])})" if by.get(name) else name for name in active
    )


def implication_problems(name: str, declarations: Mapping[str, LayerDeclaration]) -> list[str]:
    """Why `name` cannot be active with what it implies: an `implies` cycle among them, two
    of them in one exclusive group, or one excluding another. Sentences naming the layers
    (at most `MAX_PROBLEMS`), each said of the innermost layer implying both (`Flight implies
    CameraHigh and CameraLow, ...` when Mission implies Flight)."""
    implied = implied_layers(name, declarations)
    if not implied:
        return []
    members = (name, *implied)
    cycle = _cycle_members(members, declarations)
    if cycle:
        shown = ", ".join(cycle[:10]) + (f" and {len(cycle) - 10} more" if len(cycle) > 10 else "")
        return [f"the declared 'implies' of {shown} form a cycle"]
    member_set = set(members)
    brings: dict[str, set[str]] = {}

    def pair(a: str, b: str) -> str:
        # `implied` lists the deeper layers first: the innermost one bringing both.
        for by in (*implied, name):
            if by not in brings:
                brings[by] = {by, *implied_layers(by, declarations)}
            if {a, b} <= brings[by]:
                break
        if by in (a, b):
            return f"{by} implies {b if a == by else a}"
        first, second = sorted((a, b))
        return f"{by} implies {first} and {second}"

    problems: list[str] = []
    in_group: dict[str, str] = {}
    for member in members:
        declaration = _declaration(member, declarations)
        for group in sorted(declaration.groups):
            other = in_group.setdefault(group, member)
            if other != member:
                problems.append(f"{pair(other, member)}, both in exclusive group {group!r}")
        for excluded in sorted(declaration.excludes & member_set - {member}):
            problems.append(f"{pair(member, excluded)}, and {member} excludes {excluded}")
        if len(problems) >= MAX_PROBLEMS:
            break
    return list(dict.fromkeys(problems))[:MAX_PROBLEMS]


# How many contradictions one refusal names at most (answers stay small).
MAX_PROBLEMS = 5


def _cycle_members(
    members: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> list[str]:
    """The layers among `members` (a layer and what it implies) on an `implies` cycle:
    those reachable from themselves, found by one iterative depth-first search (Tarjan's
    strongly connected components), so long chains cost linear time."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    cyclic: list[str] = []
    for root in members:
        if root in index:
            continue
        work = [(root, _implied_of(root, declarations))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            layer, pending = work[-1]
            if pending:
                implied = pending.pop()
                if implied not in index:
                    index[implied] = low[implied] = len(index)
                    stack.append(implied)
                    on_stack.add(implied)
                    work.append((implied, _implied_of(implied, declarations)))
                elif implied in on_stack:
                    low[layer] = min(low[layer], index[implied])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[layer])
            if low[layer] == index[layer]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == layer:
                        break
                if len(component) > 1 or layer in _declaration(layer, declarations).implies:
                    cyclic += component
    return sorted(set(cyclic))


def _declaration(name: str, declarations: Mapping[str, LayerDeclaration]) -> LayerDeclaration:
    return declarations.get(name) or LayerDeclaration(name)


@dataclass(frozen=True)
class Switched:
    """A configuration after a switch, before it is ordered: the active layers (implied
    ones included) and those asked for explicitly (the rest is there because implied)."""

    layers: tuple[str, ...]
    explicit: tuple[str, ...]


def switched(
    active: Iterable[str],
    explicit: Iterable[str],
    activate: Iterable[str],
    deactivate: Iterable[str],
    declarations: Mapping[str, LayerDeclaration],
) -> Switched:
    """As the core's `switch`: deactivate, then activate; an active layer keeps its place, a
    new one becomes outermost (what it implies just inside it), and activating a group member
    (implied or not) drops the others. What no explicitly asked layer implies any more
    leaves; what one implies and is missing comes back (a contradiction the checks report)."""
    off = set(deactivate)
    asked = [name for name in explicit if name not in off]
    layers = [name for name in active if name not in off]
    for name in dict.fromkeys(activate):
        for member in (*implied_layers(name, declarations), name):
            groups = _declaration(member, declarations).groups
            if groups:
                rivals = {
                    other
                    for other in layers
                    if other != member and _declaration(other, declarations).groups & groups
                }
                layers = [other for other in layers if other not in rivals]
                asked = [other for other in asked if other not in rivals]
            if member not in layers:
                layers.append(member)
        if name not in asked:
            asked.append(name)
    asked_set = set(asked)
    if all(name in asked_set and not _implies_anything(name, declarations) for name in layers):
        return Switched(tuple(layers), tuple(layers))  # nothing implied: the usual case
    position = {name: index for index, name in enumerate(layers)}
    asked.sort(key=lambda name: position.get(name, len(position)))
    wanted = with_implied(asked, declarations)
    wanted_set = set(wanted)
    kept = [name for name in layers if name in wanted_set]
    kept += [name for name in wanted if name not in position]
    return Switched(tuple(kept), tuple(asked))


def _implies_anything(name: str, declarations: Mapping[str, LayerDeclaration]) -> bool:
    declaration = declarations.get(name)
    return declaration is not None and bool(declaration.implies)


def explicit_roots(
    active: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> tuple[str, ...]:
    """The layers of `active` no other active layer implies: what was asked for explicitly,
    as far as the configuration alone tells (a manager that recovered it from a node)."""
    active = tuple(active)
    implied = implied_by(active, declarations)
    return tuple(name for name in active if name not in implied)


@dataclass(frozen=True)
class DeclaredOrder:
    """An active set composed in the order the `after` relations declare."""

    layers: tuple[str, ...]
    # (later, earlier) pairs whose requested order contradicted a declaration: moved.
    moved: tuple[tuple[str, str], ...] = ()
    # Layers whose declared orders form a cycle (then `layers` is the requested order).
    cycle: tuple[str, ...] = ()


def declared_order(
    active: Iterable[str], declarations: Mapping[str, LayerDeclaration]
) -> DeclaredOrder:
    """`active` reordered so that every declared `after` holds (the later layer outermost);
    layers unrelated by `after` keep their requested order (a stable topological sort)."""
    wanted = list(dict.fromkeys(active))
    position = {name: index for index, name in enumerate(wanted)}
    must_follow: dict[str, set[str]] = {name: set() for name in wanted}
    for name in wanted:
        declaration = declarations.get(name)
        for earlier in declaration.after if declaration else ():
            if earlier in must_follow and earlier != name:
                must_follow[name].add(earlier)
    ordered: list[str] = []
    placed: set[str] = set()
    remaining = list(wanted)
    while remaining:
        ready = next((n for n in remaining if must_follow[n] <= placed), None)
        if ready is None:
            return DeclaredOrder(tuple(wanted), cycle=tuple(sorted(remaining)))
        ordered.append(ready)
        placed.add(ready)
        remaining.remove(ready)
    moved = tuple(
        (later, earlier)
        for later in wanted
        for earlier in sorted(must_follow[later])
        if position[earlier] > position[later]
    )
    return DeclaredOrder(tuple(ordered), moved)


# How the manager's answers say that it reordered the requested layers (clients quote it).
ORDER_NOTE = "; composed as declared: "


def order_note(moved: Iterable[tuple[str, str]]) -> str:
    """'; composed as declared: Rubble after Flooded, ...' ("" when nothing moved)."""
    moved = list(moved)
    if not moved:
        return ""
    return ORDER_NOTE + ", ".join(f"{later} after {earlier}" for later, earlier in moved)
