"""Context rules: layers activated from conditions on the robot's own topics (ROS-free).

    rule Battery: LowBattery while battery.percentage < 20 for 2 s hysteresis 5

The grammar is the layer language's (`contextros.language.rules`); this package checks rule
sets and evaluates them (`RuleEngine`); `contextros.ros.rules` binds them to topics inside
the Layer manager. See docs/rules.md.
"""

from contextros.rules.engine import (
    Firing,
    RuleEngine,
    RuleFailed,
    RuleReport,
    compile_condition,
    resolve,
)
from contextros.rules.ruleset import Rule, RuleSet

__all__ = [
    "Firing",
    "Rule",
    "RuleEngine",
    "RuleFailed",
    "RuleReport",
    "RuleSet",
    "compile_condition",
    "resolve",
]
