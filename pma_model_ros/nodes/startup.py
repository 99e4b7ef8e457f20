"""Start-up of the nodes: a bad parameter file or value ends the process with one clear line."""
from __future__ import annotations

import re
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy._rclpy_pybind11 import RCLError
from rclpy.logging import LoggingSeverity, get_logger_level, set_logger_level


class StartupError(Exception):
    """Bad parameters at start-up: logged as one line, then a non-zero exit."""


def init(args: list[str] | None) -> None:
    """``rclpy.init(args=args)``; a params file rcl cannot parse raises StartupError.

    rcl's own "Failed to parse global arguments" line is muted during init so the
    caller's single line is the only one.
    """
    level = get_logger_level("rcl")
    set_logger_level("rcl", LoggingSeverity.FATAL)
    try:
        rclpy.init(args=args)
    except RCLError as err:
        text = re.sub(r", at \S+:\d+", "", str(err)).removeprefix("failed to initialize rcl: ")
        raise StartupError(text) from None
    if get_logger_level("rcl") == LoggingSeverity.FATAL:   # not set by --log-level: restore
        set_logger_level("rcl", level)


def fail(node_name: str, err: Exception) -> int:
    """Log ``err`` as one FATAL line of ``node_name``; the exit code for main()."""
    rclpy.logging.get_logger(node_name).fatal(f"invalid parameters: {err}")
    rclpy.try_shutdown()
    return 1


def run(node_name: str, make_node: Callable[[], Node], args: list[str] | None) -> int:
    """Init, build the node, spin until Ctrl-C or shutdown (the Jazzy idiom); the exit code."""
    try:
        init(args)
        node = make_node()
    except StartupError as err:
        return fail(node_name, err)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
