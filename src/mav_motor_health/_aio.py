"""``TaskGroup`` on every supported Python: asyncio's own from 3.11, a small stand-in on 3.10."""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Coroutine
from typing import Any, TypeVar

__all__ = ["TaskGroup"]

T = TypeVar("T")

if sys.version_info >= (3, 11):
    from asyncio import TaskGroup
else:  # pragma: no cover - Python 3.10 only

    class TaskGroup:
        """Owns tasks; on exit waits for them, and cancels the rest when one fails (like 3.11's)."""

        def __init__(self) -> None:
            self._tasks: set[asyncio.Task[Any]] = set()

        async def __aenter__(self) -> TaskGroup:
            return self

        def create_task(self, coro: Coroutine[Any, Any, T], *, name: str | None = None) -> asyncio.Task[T]:
            task = asyncio.ensure_future(coro)
            if name is not None:
                task.set_name(name)
            self._tasks.add(task)
            task.add_done_callback(self._done)
            return task

        def _done(self, task: asyncio.Task[Any]) -> None:
            if not task.cancelled() and task.exception() is not None:
                for other in self._tasks:
                    other.cancel()

        async def __aexit__(self, *exc_info: object) -> None:
            if exc_info[0] is not None:
                for task in self._tasks:
                    task.cancel()
            results = await asyncio.gather(*self._tasks, return_exceptions=True)
            errors = [r for r in results if isinstance(r, Exception)]
            if errors:
                raise errors[0]
