"""Merging the layer declarations of several nodes (protocol/relations.py)."""

from __future__ import annotations

from contextros.protocol.relations import LayerDeclaration, merge_declarations


def test_a_group_declared_by_several_nodes_is_named_once() -> None:
    """status showed `cam2,camera,camera` for a layer two nodes put in group camera."""
    merged = merge_declarations(
        [
            LayerDeclaration("CameraHigh", group="camera"),
            LayerDeclaration("CameraHigh", group="cam2"),
            LayerDeclaration("CameraHigh", group="camera"),
        ]
    )
    assert merged["CameraHigh"].group == "cam2,camera"
