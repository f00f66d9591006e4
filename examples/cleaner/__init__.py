"""The paper's cleaning robot (Table 1) as separate ROS 2 nodes around a Layer manager.

`location.layers` holds everything that differs between indoors and outdoors; the
localization and cleaning nodes follow the manager's Indoor/Outdoor layers; `world.py`
simulates the drive; `context_detector.py` decides the context from the GPS and asks the
manager to switch. `python -m examples.demo` runs it all.
"""
