"""One way to validate the numbers of a configuration dataclass, with errors naming the field.

Every config class of the package checks its fields in ``__post_init__`` through
:func:`require`, so a bad value (a string, a bool, NaN, a negative count) fails where it is
given, with ``section.field`` in the message, never later inside MuJoCo or torch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

_RULES: dict[str, tuple[Callable[[float], bool], str]] = {
    "positive": (lambda v: v > 0, "> 0"),
    "non_negative": (lambda v: v >= 0, ">= 0"),
    "unit": (lambda v: 0 < v <= 1, "in (0, 1]"),
    "fraction": (lambda v: 0 <= v <= 1, "in [0, 1]"),
}


def is_number(value: object) -> bool:
    """True for an int or float that is finite (bools and strings are not numbers here)."""
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value))


def require(config: object, prefix: str, error: type[Exception],
            **rules: tuple[str, ...]) -> None:
    """Raises ``error`` unless every named field is a finite number obeying its rule.

    Args:
        config: The dataclass instance.
        prefix: How the user names the fields' section (``"optim"`` gives ``optim.lr``);
            empty for top-level fields.
        error: The exception class to raise (the config module's own error).
        **rules: Rule name (``positive``, ``non_negative``, ``unit``, ``fraction``) to the
            field names it applies to. A tuple-valued field must hold such numbers only, a
            mapping-valued field such values; ``None`` values are skipped (optional fields).
    """
    for rule, names in rules.items():
        test, text = _RULES[rule]
        for name in names:
            value = getattr(config, name)
            if value is None:
                continue
            items = (tuple(value.values()) if isinstance(value, Mapping)
                     else value if isinstance(value, tuple) else (value,))
            if not all(is_number(v) and test(v) for v in items):
                where = f"{prefix}.{name}" if prefix else name
                raise error(f"{where} must be {text}, got {value!r}.")


def require_ranges(config: object, prefix: str, error: type[Exception],
                   names: tuple[str, ...]) -> None:
    """Raises ``error`` unless every named field is a ``(lowest, highest)`` pair of finite
    numbers with ``0 <= lowest <= highest``; a list (as read from YAML or JSON) is stored as
    a tuple first (on a frozen dataclass too)."""
    for name in names:
        value = getattr(config, name)
        if isinstance(value, list):
            value = tuple(value)
            object.__setattr__(config, name, value)
        if not (isinstance(value, tuple) and len(value) == 2 and all(map(is_number, value))
                and 0 <= value[0] <= value[1]):
            raise error(f"{prefix}.{name} must be (lowest, highest) with 0 <= lowest <= "
                        f"highest, got {value!r}.")


def check_schema_version(data: Mapping[str, Any], supported: int, source: str,
                         error: type[Exception]) -> None:
    """Raises ``error`` naming ``source`` and both versions if the file content ``data`` was
    written in a newer layout than ``supported`` (a file without ``schema_version`` is 1)."""
    version = data.get("schema_version", 1)
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise error(f"{source}: schema_version must be a positive integer, got {version!r}.")
    if version > supported:
        raise error(
            f"{source} has layout version {version}, newer than the version {supported} this "
            "sim4endor reads: upgrade sim4endor, or rebuild the folder with this one."
        )
