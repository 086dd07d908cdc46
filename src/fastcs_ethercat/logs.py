"""One log format for every command: time, level, source, message, one line.

Our modules log through `logging` (a module logger each); FastCS logs through
loguru. Both end in the one stderr handler set up here, so an operator reads
one format. Loguru's records are handed to `logging` without loguru's
variable-dumping tracebacks, and an exception is shown as one line
(`... : ConnectionError: target not connected`) unless the level is DEBUG,
where the traceback follows. Stdout stays for what a command answers (PV
lists, ready lines, the demo's hints).
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from enum import StrEnum
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from loguru import Message

LOG_FORMAT: Final = "%(asctime)s.%(msecs)03d %(levelname)-7s %(name)s: %(message)s"
DATE_FORMAT: Final = "%Y-%m-%d %H:%M:%S"
_LOGURU_NAME_KEY: Final = "logger_name"
NAMES_SHOWN: Final = 3
"""Names a warning lists before it counts the rest (`first_names`)."""


class LogLevel(StrEnum):
    """The levels `--log-level` accepts (any case)."""

    DEBUG = "DEBUG"
    INFO = "INFO"
    WARNING = "WARNING"
    ERROR = "ERROR"
    CRITICAL = "CRITICAL"


class OneLineFormatter(logging.Formatter):
    """`LOG_FORMAT`; an exception joins its line unless DEBUG is on."""

    def __init__(self, tracebacks: bool) -> None:
        super().__init__(LOG_FORMAT, DATE_FORMAT)
        self.tracebacks = tracebacks

    def format(self, record: logging.LogRecord) -> str:
        if self.tracebacks:
            return super().format(record)
        if record.exc_info:
            error = record.exc_info[1]
            record = logging.makeLogRecord(record.__dict__)
            if error is not None:
                record.msg = f"{record.getMessage()}: {one_line_error(error)}"
                record.args = None
            record.exc_info = None
            record.exc_text = None
        return " ".join(super().format(record).splitlines())


def one_line_error(error: BaseException) -> str:
    """`TypeName: message` on one line (the type alone if there is no message)."""
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def setup_logging(level: str | LogLevel = LogLevel.INFO) -> None:
    """Send every log record of this process to stderr in `LOG_FORMAT`.

    Safe to call again (a command's `--log-level` after the root's): the
    handlers are replaced, never added twice.
    """
    name = str(level).upper()
    if name not in LogLevel.__members__:
        raise ValueError(f"unknown log level {level!r}")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(OneLineFormatter(tracebacks=name == LogLevel.DEBUG))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(name)
    logging.captureWarnings(True)
    _route_loguru(name)


def _route_loguru(level: str) -> None:
    """FastCS's loguru logger into `logging`, without loguru's backtraces."""
    from loguru import logger

    logger.remove()
    logger.add(
        _to_logging, level=level, format="{message}", backtrace=False, diagnose=False
    )


def _to_logging(message: Message) -> None:
    record = message.record
    extra = dict(record["extra"])
    name = str(extra.pop(_LOGURU_NAME_KEY, None) or record["name"] or "loguru")
    text = record["message"]
    # FastCS passes the values it formats into the message as extras too.
    fields = " ".join(
        f"{key}={value}"
        for key, value in extra.items()
        if not key.startswith("_") and str(value) not in text
    )
    if fields:
        text = f"{text} {fields}"
    exception = record["exception"]
    exc_info = None
    if exception is not None and exception.value is not None:
        exc_info = (exception.type, exception.value, exception.traceback)
    target = logging.getLogger(name)
    level = record["level"].no
    if not (target.isEnabledFor(level) and _module_allows(record["name"], level)):
        return
    target.handle(
        target.makeRecord(
            name,
            level,
            record["file"].path,
            record["line"],
            text,
            (),
            exc_info,  # pyright: ignore[reportArgumentType]
            record["function"],
        )
    )


def _module_allows(module: str | None, level: int) -> bool:
    """The level of the `logging` logger of a loguru record's module (FastCS's
    `fastcs.transports.epics.ca.ioc`, say) holds for its records too, though
    they are shown under the name FastCS binds (`fastcs`)."""
    return not module or logging.getLogger(module).isEnabledFor(level)


def first_names(names: Sequence[str], shown: int = NAMES_SHOWN) -> str:
    """`a, b, c and 4 more`: names a warning can carry in one line."""
    text = ", ".join(names[:shown])
    if len(names) > shown:
        text += f" and {len(names) - shown} more"
    return text


def log_at_most(
    logger: logging.Logger,
    level: int,
    messages: Sequence[str],
    limit: int,
    rest: str,
) -> None:
    """The first `limit` messages, then one line for the rest: a start that
    has 10 000 things to say about names stays readable.

    `rest` completes "... and N more <rest>", e.g. "PV names shortened (all
    of them at DEBUG)"; at DEBUG every message is logged.
    """
    shown = len(messages) if logger.isEnabledFor(logging.DEBUG) else limit
    for message in messages[:shown]:
        logger.log(level, "%s", message)
    hidden = len(messages) - shown
    if hidden > 0:
        logger.log(level, "... and %d more %s", hidden, rest)


__all__ = [
    "DATE_FORMAT",
    "LOG_FORMAT",
    "NAMES_SHOWN",
    "LogLevel",
    "OneLineFormatter",
    "first_names",
    "log_at_most",
    "one_line_error",
    "setup_logging",
]
