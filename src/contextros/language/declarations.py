"""The layers and relations that layer files declare, as the protocol's LayerDeclarations.

The manager given layer files (`contextros manager --layers`) and `contextros rules replay`
both compose and validate with these, merged with the participants' own declarations
(`contextros.protocol.relations.with_layer_files`), so the two compose alike.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from contextros.language.flavours import parse_files
from contextros.protocol.relations import LayerDeclaration


def declarations_from_files(paths: Iterable[str | os.PathLike[str]]) -> list[LayerDeclaration]:
    """Each layer of the files with its declared excludes, requires, after and implies, each
    group's members and each layer a binding names (`parameter L:`, `lifecycle L:`: its
    effect, even with no `layer L` anywhere), in file order (files whose parse failed
    contribute nothing: their errors are reported where the files are checked)."""
    parsed, _ = parse_files(paths)
    found: list[LayerDeclaration] = []
    for _, _, layer_file in parsed:
        for group in layer_file.groups:
            found += [LayerDeclaration(m.name, group=group.name) for m in group.members]
        for layer in layer_file.layers:
            found.append(
                LayerDeclaration(
                    layer.name,
                    excludes=frozenset(r.name for r in layer.excludes),
                    requires=frozenset(r.name for r in layer.requires),
                    after=frozenset(r.name for r in layer.after),
                    implies=frozenset(r.name for r in layer.implies),
                )
            )
        found += [LayerDeclaration(binding.layer.name) for binding in layer_file.parameters]
        found += [LayerDeclaration(binding.layer.name) for binding in layer_file.lifecycles]
    return found
