"""Asyncio task helpers the IOC's components share: bounded fan-out and a
cancellation that does not give up."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Collection, Iterable
from typing import Any, Final, TypeVar

_T = TypeVar("_T")
_R = TypeVar("_R")

CANCEL_AGAIN_S: Final = 0.1
"""How long a cancelled task may take before it is cancelled again."""


async def gather_at_most(
    limit: int, work: Callable[[_T], Awaitable[_R]], items: Iterable[_T]
) -> list[_R]:
    """`work(item)` for every item, at most `limit` running at once; the
    results in the items' order (a target's router or a slave's mailbox
    takes only so many requests at a time)."""
    slots = asyncio.Semaphore(limit)

    async def one(item: _T) -> _R:
        async with slots:
            return await work(item)

    return list(await asyncio.gather(*(one(item) for item in items)))


async def cancel_and_wait(tasks: Collection[asyncio.Task[Any]]) -> None:
    """Cancel `tasks` and wait until every one has ended.

    Python 3.11's `asyncio.wait_for` returns its result and drops the
    cancellation when the task is cancelled just as the awaited thing
    finishes (the supervisor's probe and wake-up wait): a task still running
    is cancelled again, else a SIGTERM shortly after start could leave the
    IOC running. A task's own failure is taken (not reported as unretrieved).
    """
    pending = set(tasks)
    while pending:
        for task in pending:
            task.cancel()
        done, pending = await asyncio.wait(pending, timeout=CANCEL_AGAIN_S)
        for task in done:
            if not task.cancelled():
                task.exception()
