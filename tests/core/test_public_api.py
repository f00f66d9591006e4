"""The public surface is deliberate: this test changes when the API does."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import contextros
from contextros import errors

EXPECTED = {
    "DispatchError",
    "HookError",
    "Layer",
    "LayerDefinitionError",
    "LayerError",
    "NoImplementationError",
    "ProceedError",
    "RelationError",
    "SwitchEvent",
    "SwitchResult",
    "UnknownLayerError",
    "__version__",
    "activate",
    "activate_for",
    "activated",
    "active_layers",
    "critical",
    "current_epoch",
    "defined_layers",
    "in_critical_section",
    "deactivate",
    "deactivate_for",
    "deactivated",
    "layer_named",
    "layered",
    "layers_for",
    "proceed",
    "remove_layer",
    "reset_for",
    "set_active",
    "subscribe",
    "switch",
}


def test_exported_names() -> None:
    assert set(contextros.__all__) >= EXPECTED
    for name in contextros.__all__:
        assert hasattr(contextros, name), name


def test_every_error_derives_from_layer_error() -> None:
    classes = [v for v in vars(errors).values() if isinstance(v, type) and issubclass(v, Exception)]
    assert len(classes) >= 8
    assert all(issubclass(cls, errors.LayerError) for cls in classes)


def test_core_imports_and_runs_without_ros() -> None:
    script = textwrap.dedent(
        """
        import sys
        class Block:
            def find_spec(self, name, path=None, target=None):
                if name.split('.')[0] in ('rclpy', 'std_msgs', 'rcl_interfaces'):
                    raise ImportError('ROS is made unimportable for this test: ' + name)
        sys.meta_path.insert(0, Block())
        import contextros
        from contextros import Layer, layered, activate
        L = Layer('L')
        @layered
        def f(): return 'base'
        @f.partial(L)
        def f(): return 'L'
        activate(L)
        assert f() == 'L'
        loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'std_msgs'))
        print('ROS-MODULES', loaded)
        """
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert "ROS-MODULES []" in result.stdout


def test_names_are_imported_lazily_and_all_resolve() -> None:
    """`import contextros` loads no core or language module until a name is used (a fast
    CLI start), and every exported name of each lazy package resolves."""
    script = textwrap.dedent(
        """
        import sys
        import contextros
        print('EAGER', sorted(m for m in sys.modules if m.startswith('contextros.')
                              and m not in ('contextros.errors', 'contextros._exports')))
        import contextros.language as language
        for name in contextros.__all__ + language.__all__:
            getattr(contextros if name in contextros.__all__ else language, name)
        print('RESOLVED')
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert "EAGER []" in result.stdout and "RESOLVED" in result.stdout
