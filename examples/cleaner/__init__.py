"""The paper's cleaning robot (Table 1) as separate ROS 2 nodes around a Layer manager.

`location.layers` holds everything that differs between indoors and outdoors; the
localization and cleaning nodes follow the manager's Indoor/Outdoor layers; `world.py`
simulates the drive; the rule `GpsFix` of `location.layers`, run by the manager
(`contextros manager --rules location.layers`), decides the context from the GPS.
`python -m examples.demo` runs it all.
"""
