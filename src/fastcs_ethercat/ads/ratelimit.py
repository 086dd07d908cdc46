"""A logger wrapper that says each kind of message at most once per interval.

A misbehaving peer can send thousands of bad frames a second; one line per
kind per second (with how many were held back) keeps the log readable and
the disk safe, and still shows that it goes on.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(slots=True)
class _Kind:
    last: float
    suppressed: int = 0


@dataclass
class RateLimitedLog:
    """Log through `logger`, each `kind` at most once per `interval_s`.

    A line after a quiet spell says how many of its kind were held back.
    """

    logger: logging.Logger
    interval_s: float = 1.0
    clock: Callable[[], float] = time.monotonic
    _kinds: dict[str, _Kind] = field(default_factory=dict, repr=False)

    def log(self, level: int, kind: str, message: str, *args: object) -> bool:
        """Log `message % args` unless `kind` was logged within the interval;
        return whether it was logged."""
        now = self.clock()
        seen = self._kinds.get(kind)
        if seen is not None and now - seen.last < self.interval_s:
            seen.suppressed += 1
            return False
        held = seen.suppressed if seen is not None else 0
        self._kinds[kind] = _Kind(now)
        if held:
            message = f"{message} (and {held} more since the last such line)"
        self.logger.log(level, message, *args)
        return True

    def warning(self, kind: str, message: str, *args: object) -> bool:
        return self.log(logging.WARNING, kind, message, *args)

    def info(self, kind: str, message: str, *args: object) -> bool:
        return self.log(logging.INFO, kind, message, *args)


__all__ = ["RateLimitedLog"]
