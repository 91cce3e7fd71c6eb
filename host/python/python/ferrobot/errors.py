"""Ferrobot's exceptions: one hierarchy under :class:`Error`.

Every typed error of the Rust API arrives as the subclass named as its variant (``OutOfLimits``,
``Unreachable``, ``EmergencyStop``, ...), carrying the variant's fields as attributes
(``err.joint``, ``err.value``, ``err.min``, ``err.max``). Errors about the values passed are
also ``ValueError`` (and ``TypeError`` where the type is wrong), so ``except ValueError`` works
as Python programs expect.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "Error",
    "InvalidArgument",
    "UnknownRobot",
    "Config",
    "NoComponent",
    "JointCount",
    "NotFinite",
    "OutOfRange",
    "OutOfLimits",
    "Unreachable",
    "InvalidMap",
    "Calibration",
    "UnknownName",
    "Timeout",
    "Stalled",
    "Rejected",
    "EmergencyStop",
    "Preempted",
    "Fault",
    "Cancelled",
    "VersionMismatch",
    "WrongRobot",
    "JointTableMismatch",
    "StalePlan",
    "Link",
    "Usage",
    "SlamLost",
    "HardwareCheck",
    "PathExists",
    "Scene",
    "Perception",
    "Planning",
    "Navigation",
    "Slam",
    "Io",
    "Skill",
]


class Error(Exception):
    """Every error Ferrobot raises. ``str(err)`` says what, which value and which limit; the
    variant's fields are attributes (listed in ``err.fields``)."""

    def __init__(self, message: str, **fields: Any) -> None:
        super().__init__(message)
        self.message = message
        self.fields = dict(fields)
        for key, value in fields.items():
            setattr(self, key, value)

    def __reduce__(self):  # picklable, fields included (multiprocessing, Jupyter)
        return (_rebuild, (type(self), self.message, self.fields))


def _rebuild(cls, message, fields):
    return cls(message, **fields)


class InvalidArgument(Error, TypeError, ValueError):
    """A value of the wrong type or shape: ``argument`` (its name), ``expected``, ``got``."""


class UnknownRobot(Error, ValueError):
    """No bundled robot of that name: ``name``, ``known``."""


class Config(Error, ValueError):
    """A configuration file or key is missing or invalid: ``file``, ``key``, ``problem``."""


class NoComponent(Error, AttributeError):
    """The robot has no such component (or was built without it): ``robot``, ``component``."""


class JointCount(Error, ValueError):
    """A vector has the wrong number of joints: ``what``, ``expected``, ``got``."""


class NotFinite(Error, ValueError):
    """A NaN or infinite value: ``what``, ``value``."""


class OutOfRange(Error, ValueError):
    """A finite value outside what the API accepts: ``what``, ``value``, ``min``, ``max``."""


class OutOfLimits(Error, ValueError):
    """A joint target beyond the joint's limits (rad): ``joint``, ``value``, ``min``, ``max``."""


class Unreachable(Error):
    """No joint configuration reaches the pose: ``why``."""


class InvalidMap(Error, ValueError):
    """An occupancy-grid map that cannot be used: ``why``."""


class Calibration(Error):
    """Calibration could not determine what it measures: ``why``."""


class UnknownName(Error, KeyError):
    """An unknown joint or frame name: ``what``, ``name``."""

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


class Timeout(Error, TimeoutError):
    """A motion did not finish in time: ``what``, ``after`` (s)."""


class Stalled(Error):
    """A joint stopped short of its target: ``joint``, ``position`` (rad), ``error`` (rad)."""


class Rejected(Error):
    """The firmware refused a command: ``what``, ``reason``."""


class EmergencyStop(Error):
    """An emergency stop is active; call ``bot.resume()`` first."""


class Preempted(Error):
    """A newer motion of the same component took over: ``what``."""


class Fault(Error):
    """A fault stopped the motion: ``kind``, ``detail``."""


class Cancelled(Error):
    """The motion was cancelled (``Motion.cancel()``, ``bot.cancel_motions()``)."""


class VersionMismatch(Error):
    """Host and firmware speak different protocol versions."""


class WrongRobot(Error):
    """The firmware runs another robot's profile than the configuration describes."""


class JointTableMismatch(Error):
    """The firmware's joint table does not match the configuration: ``detail``."""


class StalePlan(Error):
    """The plan no longer holds (the arm moved): plan again. ``why``."""


class Link(Error, ConnectionError):
    """The link to the firmware was lost: ``detail``."""


class Usage(Error, ValueError):
    """A call that does not make sense in the robot's state: ``detail``."""


class SlamLost(Error):
    """SLAM has no confirmed pose for the last ``frames`` frames."""


class HardwareCheck(Error):
    """The hardware check of a robot on its own cables failed; nothing moves until it passes.
    ``faults`` (each with its fix) and ``table`` (as ``ferrobot hardware check`` prints it)."""


class PathExists(Error, FileExistsError):
    """A file that would be replaced: ``path``."""


class Scene(Error, ValueError):
    """A scene that cannot be loaded: ``detail``."""


class Perception(Error):
    """Perception failed (images, clouds, clustering): ``detail``."""


class Planning(Error):
    """Planning failed (no path, a start or goal in collision, ...): ``detail``."""


class Navigation(Error):
    """Navigation failed (no path on the map, a goal in an obstacle, ...): ``detail``."""


class Slam(Error):
    """SLAM failed: ``detail``."""


class Io(Error, OSError):
    """Reading or writing a file failed: ``detail``."""


class Skill(Error):
    """A skill (grasping, pushing, calibration) could not complete: ``detail``."""
