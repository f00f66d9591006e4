"""The Layer manager as a pure state machine: events in, actions out, time passed in.

Its parts, each in a module named after it: `registry` (who is live, liveness, name
clashes, validating statuses), `command_queue` (validating and executing commands, and
those waiting), `acknowledgements` (synchronous activations and their answers),
`atomic_votes` (the two-phase activation), `recovery` (a (re)started manager's first
state); `base` holds the state they share, `protocol` the events they answer.

Guarantees it keeps (and tests/protocol checks deterministically, also under random loss,
reordering, duplication and crashes):

- every state is a full snapshot with an epoch one above the previous one, and the epoch
  never goes down, not even across restarts (state file, participants' reports);
- nothing is published before the manager knows an epoch (its state file or a participant);
- a command naming a layer neither a live participant implements nor the manager's layer
  files declare (after a grace period for a restarted manager), or breaking a declared
  relation, changes nothing and is answered with a message naming the culprits;
- a synchronous command succeeds only if every participant that was live when it was
  issued, every node it named and at least the count it asked for (one at least, none for
  a command naming a layer the manager applies itself) applied its epoch (or a newer
  one); else it fails naming the nodes and why. Its answer carries its own epoch and that
  epoch's active layers;
- a participant silent for longer than `liveness_timeout` is dropped and reported; two
  live processes under one name are both tracked and neither acknowledges for the other;
- a status that fails validation (bad names, sizes, implausible epochs) changes nothing;
- memory stays bounded whatever the network sends: what is kept about a node name (its
  retired incarnations, the nodes it hosts) is forgotten once it is neither live nor among
  the `keep_dropped` names of dropped nodes, and at most `max_waiting_commands` commands wait.
"""

from contextros.protocol.manager.base import NO_CHANGE
from contextros.protocol.manager.protocol import ManagerProtocol
from contextros.protocol.manager.records import Key, ParticipantRecord
from contextros.protocol.manager.recovery import RECOVERY_REQUESTER
from contextros.protocol.manager.registry import (
    ADOPTABLE_EPOCH,
    ParticipantView,
    RegistryView,
)
from contextros.protocol.manager.settings import ManagerSettings

__all__ = [
    "ADOPTABLE_EPOCH",
    "NO_CHANGE",
    "RECOVERY_REQUESTER",
    "Key",
    "ManagerProtocol",
    "ManagerSettings",
    "ParticipantRecord",
    "ParticipantView",
    "RegistryView",
]
