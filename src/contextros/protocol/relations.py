"""Layer declarations as participants announce them, and the relation check the manager runs.

The manager knows no layer by itself: it learns layers and their relations (excludes,
requires, group) from the participants, and validates every activation against the union
of what they declared, so a node cannot be asked for a configuration another node forbids.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class LayerDeclaration:
    """A layer a participant implements, with the relations it declares for it."""

    name: str
    excludes: frozenset[str] = frozenset()
    requires: frozenset[str] = frozenset()
    group: str = ""
    # Layers this one comes after (outside) when both are active (`layer X after B`).
    after: frozenset[str] = frozenset()

    def merged(self, other: LayerDeclaration) -> LayerDeclaration:
        """The union of two nodes' declarations of one layer (the stricter reading)."""
        groups = sorted({g for g in (self.group, other.group) if g})
        return LayerDeclaration(
            name=self.name,
            excludes=self.excludes | other.excludes,
            requires=self.requires | other.requires,
            group=",".join(groups),
            after=self.after | other.after,
        )

    @property
    def groups(self) -> frozenset[str]:
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
    participants implement (`implemented`, merged), with the relations the manager's layer
    files declare for it added. The one place where the two meet, live and in a replay."""
    extra = [d for d in layer_files if d.name in implemented]
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
