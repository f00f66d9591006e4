"""The simulated fleet (contextros.protocol.simulation): a short sweep of seeds finds no
violated guarantee, a seed replays exactly (also from the command line, whatever Python's
hash seed), and the checks catch a manager that breaks a guarantee."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    PublishState,
    Reply,
)
from contextros.protocol.manager import ManagerProtocol
from contextros.protocol.simulation import (
    Faults,
    InvariantViolation,
    Scenario,
    Simulation,
    main,
    simulate,
)

SMALL = 6
HARSH = Faults(loss=0.5, duplication=0.3, partitions=4, crashes=6, manager_restarts=3)


@pytest.mark.parametrize("seed", range(40))
def test_a_sweep_of_seeds_keeps_every_guarantee(seed: int) -> None:
    report = simulate(Scenario(SMALL, seed))
    assert report.commands > report.scenario.clean_activations
    assert report.time_to_converge <= report.scenario.converge_within


@pytest.mark.parametrize("seed", range(100, 120))
def test_harsh_faults_keep_every_guarantee(seed: int) -> None:
    simulate(Scenario(SMALL, seed, faults=HARSH))


def test_a_seed_replays_exactly_and_seeds_differ() -> None:
    first, again = simulate(Scenario(SMALL, 7)), simulate(Scenario(SMALL, 7))
    other = simulate(Scenario(SMALL, 8))
    assert first.trace == again.trace and first.events == again.events
    assert first.trace != other.trace


def test_the_command_line_replays_a_seed_whatever_the_hash_seed() -> None:
    root = Path(__file__).resolve().parents[2]
    outputs = []
    for hash_seed in ("1", "2"):
        env = {**os.environ, "PYTHONHASHSEED": hash_seed, "PYTHONPATH": str(root / "src")}
        command = [sys.executable, "-m", "contextros.protocol.simulation", "--seed", "3"]
        done = subprocess.run(
            [*command, "--participants", "5"], env=env, capture_output=True, text=True, check=True
        )
        outputs.append(done.stdout.split("; trace ")[1])
    assert outputs[0] == outputs[1]


def test_messages_per_clean_activation_are_one_state_and_one_status_per_node() -> None:
    report = simulate(Scenario(20, 1))
    assert report.messages_per_activation == pytest.approx(40, abs=2)


class _ReusesEpochs(ManagerProtocol):
    """Publishes every new configuration under the epoch it has already."""

    def _publish(
        self, active: tuple[str, ...], requester: str, reason: str, now: float, above: int
    ) -> PublishState:
        epoch = self._state.epoch
        published = super()._publish(active, requester, reason, now, above)
        if not epoch:
            return published
        self._state = dataclasses.replace(self._state, epoch=epoch)
        return PublishState(self._state)


class _ClaimsEveryNode(ManagerProtocol):
    """Answers a synchronous command at once, claiming every live node applied it."""

    def receive_command(self, command: ActivationCommand, now: float) -> list[ManagerAction]:
        actions = super().receive_command(command, now)
        if not command.synchronous:
            return actions
        self._pending.clear()
        result = ActivationResult(True, "", self._state.epoch + 1, (), self.live_nodes)
        return [*actions, Reply(command.request_id, result)]


@pytest.mark.parametrize(
    ("broken", "complaint"),
    [(_ReusesEpochs, "names two layer sets"), (_ClaimsEveryNode, "never applied it")],
)
def test_a_broken_manager_is_caught_and_the_seed_named(
    broken: type[ManagerProtocol], complaint: str
) -> None:
    with pytest.raises(InvariantViolation) as caught:
        Simulation(Scenario(SMALL, 5), manager_class=broken).run()
    assert complaint in str(caught.value)
    assert "--seed 5 --participants 6" in str(caught.value)


def test_the_command_line_runs_a_seed(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--seed", "4", "--participants", "4"]) == 0
    assert "seed 4: 4 participants" in capsys.readouterr().out
