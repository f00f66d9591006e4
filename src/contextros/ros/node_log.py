"""Log lines from a hot path: rcutils' logging without rclpy's caller lookup.

`node.get_logger().info(...)` finds its caller by walking the stack and reading the source
file's line (`inspect.getframeinfo`): about 0.3 ms a line, longer than a topic round trip.
`NodeLog` hands the same line to the same rcutils logger (same name, same output, same
severity filtering), naming the calling function cheaply.
"""

from __future__ import annotations

import sys
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.impl.logging_severity import LoggingSeverity


class NodeLog:
    def __init__(self, logger: Any) -> None:
        self._logger = logger
        self._name: str = logger.name

    def info(self, message: str) -> None:
        self._log(LoggingSeverity.INFO, message)

    def warning(self, message: str) -> None:
        self._log(LoggingSeverity.WARN, message)

    def error(self, message: str) -> None:
        self._log(LoggingSeverity.ERROR, message)

    def _log(self, severity: LoggingSeverity, message: str) -> None:
        if not self._logger.is_enabled_for(severity):
            return
        caller = sys._getframe(2)
        rclpy_implementation.rclpy_logging_rcutils_log(
            severity,
            self._name,
            message,
            caller.f_code.co_name,
            caller.f_code.co_filename,
            caller.f_lineno,
        )
