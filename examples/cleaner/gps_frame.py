"""The local frame of the demo's GPS: metres east (x) and north (y) of a fixed origin.

An equirectangular approximation, exact enough over the few metres the robot drives.
"""

from __future__ import annotations

import math

ORIGIN_LATITUDE = 35.6812  # Tokyo Station
ORIGIN_LONGITUDE = 139.7671
METRES_PER_DEGREE = 111_320.0


def to_fix(x: float, y: float) -> tuple[float, float]:
    """(latitude, longitude) of the local point (x, y)."""
    latitude = ORIGIN_LATITUDE + y / METRES_PER_DEGREE
    longitude = ORIGIN_LONGITUDE + x / (METRES_PER_DEGREE * math.cos(math.radians(ORIGIN_LATITUDE)))
    return latitude, longitude


def to_local(latitude: float, longitude: float) -> tuple[float, float]:
    """The local point (x, y) of a fix; the inverse of `to_fix`."""
    x = (longitude - ORIGIN_LONGITUDE) * METRES_PER_DEGREE * math.cos(math.radians(ORIGIN_LATITUDE))
    y = (latitude - ORIGIN_LATITUDE) * METRES_PER_DEGREE
    return x, y
