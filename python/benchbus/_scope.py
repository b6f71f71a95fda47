"""The ``with`` block of the objects that hold something until they are ended.

A device closes the Bus it opened, a keepalive stops its thread, a gateway stops serving:
each class says what its block ends with (``_leave``) and, if entering does more than give
the object, what entering does (``_enter``); the protocol itself is written here once, for
``with`` and for ``async with``.
"""

from __future__ import annotations

from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["AsyncScoped", "Scoped"]


class Scoped:
    """A context manager: the block gives the object (once :meth:`_enter` has run) and
    ends with :meth:`_leave`, also after an exception."""

    def __enter__(self) -> Self:
        """The object itself, once :meth:`_enter` has run (the class says what that does)."""
        self._enter()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """:meth:`_leave`, given the exception that ends the block (None: none)."""
        self._leave(exc)

    def _enter(self) -> None:
        """What entering the block does before it gives the object: nothing."""

    def _leave(self, exc: BaseException | None) -> None:
        """What leaving the block does (``exc``: the exception that ends it, or None)."""
        raise NotImplementedError


class AsyncScoped:
    """An async context manager: the block gives the object and ends with :meth:`_aleave`,
    also after an exception or on cancellation."""

    async def __aenter__(self) -> Self:
        """The object itself."""
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """:meth:`_aleave`, given the exception that ends the block (None: none)."""
        await self._aleave(exc)

    async def _aleave(self, exc: BaseException | None) -> None:
        """What leaving the block does (``exc``: the exception that ends it, or None)."""
        raise NotImplementedError
