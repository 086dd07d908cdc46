"""Log lines to Graylog too, through FastCS's own logging options.

`fastcs-ethercat ioc --graylog-endpoint HOST:PORT [--graylog-static-fields
K:V,...] [--graylog-env-fields K:ENV,...]` takes the options FastCS's
launcher takes, parsed by FastCS's parsers, and sets them with FastCS's
`configure_logging`: FastCS's console sink and a GELF UDP sink. Our modules'
`logging` records are handed to that loguru logger instead of the stderr
handler of `logs.setup_logging`, so every line reaches both, in FastCS's
console format. (The audit's put lines are printed by EPICS on stdout, not
logged: they stay in the container log.)
"""

from __future__ import annotations

import logging

from fastcs_ethercat.errors import UserError

_LOGURU_NAME_KEY = "logger_name"


class _ToLoguru(logging.Handler):
    """A `logging` record into FastCS's loguru logger, under its own name."""

    def emit(self, record: logging.LogRecord) -> None:
        from fastcs.logging import logger

        try:
            message = self.format(record) if record.exc_info else record.getMessage()
            logger.bind(**{_LOGURU_NAME_KEY: record.name}).log(
                record.levelname, message
            )
        except Exception:  # a log line must never stop the IOC
            self.handleError(record)


def send_to_graylog(
    level: str, endpoint: str, static_fields: str | None, env_fields: str | None
) -> None:
    """Every log line of this process to the console and to Graylog."""
    from fastcs.logging import (
        GraylogEndpoint,
        LogLevel,  # configure_logging's own type
        configure_logging,
    )
    from fastcs.logging import parse_graylog_env_fields as parse_env
    from fastcs.logging import parse_graylog_static_fields as parse_static

    try:
        target = GraylogEndpoint.parse_graylog_endpoint(endpoint)
        static = parse_static(static_fields) if static_fields else None
        env = parse_env(env_fields) if env_fields else None
    except ValueError as error:
        raise UserError(f"--graylog-*: {error}") from None
    configure_logging(LogLevel(level.upper()), target, static, env)
    root = logging.getLogger()
    root.handlers[:] = [_ToLoguru()]


__all__ = ["send_to_graylog"]
