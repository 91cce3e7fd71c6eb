"""PyRobot's ``configs``: nested, read-only, read by attribute (``bot.configs.BASE.MAX_ABS_FWD_SPEED``)
or by key, built from the robot's description (TOML and URDF) when the robot starts."""

from __future__ import annotations

from typing import Any, Mapping


class CfgNode(dict):
    """A read-only dictionary whose keys are also attributes, like PyRobot's frozen yacs nodes."""

    def __init__(self, values: Mapping[str, Any]) -> None:
        super().__init__(
            (k, CfgNode(v) if isinstance(v, Mapping) else v) for k, v in values.items()
        )

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(f"configs have no key {name!r}; keys: {', '.join(self)}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("configs are read-only; pass overrides= to Robot(...) instead")

    def _readonly(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("configs are read-only; pass overrides= to Robot(...) instead")

    __setitem__ = __delitem__ = update = pop = popitem = clear = setdefault = _readonly  # type: ignore[assignment]
