"""Bounded fan-out and a cancellation that does not give up."""

from __future__ import annotations

import asyncio

from fastcs_ethercat.ioc.tasks import cancel_and_wait, gather_at_most


def test_gather_at_most_keeps_the_limit_and_the_order() -> None:
    running = 0
    most = 0

    async def work(item: int) -> int:
        nonlocal running, most
        running += 1
        most = max(most, running)
        await asyncio.sleep(0.001 * (5 - item % 5))
        running -= 1
        return item * 10

    results = asyncio.run(gather_at_most(3, work, range(12)))

    assert results == [item * 10 for item in range(12)]
    assert most == 3


def test_a_task_that_drops_its_first_cancellation_is_cancelled_again() -> None:
    """Like Python 3.11's `wait_for` when its awaitable finishes as the
    cancellation arrives: the task goes on, and is cancelled again."""
    dropped = 0

    async def stubborn() -> None:
        nonlocal dropped
        while True:
            try:
                await asyncio.sleep(10)
            except asyncio.CancelledError:
                if dropped:
                    raise
                dropped += 1

    async def failing() -> None:
        raise RuntimeError("gone")

    async def main() -> tuple[bool, bool]:
        tasks = [asyncio.create_task(stubborn()), asyncio.create_task(failing())]
        await asyncio.sleep(0)
        await asyncio.wait_for(cancel_and_wait(tasks), 2)
        return tasks[0].cancelled(), tasks[1].done()

    assert asyncio.run(main()) == (True, True)
    assert dropped == 1
