"""JSON text that every parser reads: no ``NaN`` or ``Infinity`` tokens.

Python's :func:`json.dumps` writes non-finite floats as ``NaN`` / ``Infinity``, which are not
JSON (RFC 8259): ``jq``, JavaScript and most other parsers reject the whole line. A diverged
episode or a loss that blew up produces such values, so what reports measurements goes through
:func:`dumps`, which writes them as ``null`` (no value): the CLI's ``--json`` lines, a run's
evaluation files and the benchmarks' output. Vessel folders' data files and exported policies'
contracts keep :func:`json.dumps`: they hold geometry and settings, never a measurement.
"""

from __future__ import annotations

import json
import math
from typing import Any


def dumps(obj: Any, **kwargs: Any) -> str:
    """:func:`json.dumps` of ``obj`` with non-finite floats written as ``null``."""
    return json.dumps(_finite(obj), allow_nan=False, **kwargs)


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {key: _finite(value) for key, value in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(value) for value in obj]
    return obj
