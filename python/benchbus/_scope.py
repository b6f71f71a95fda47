"""The ``with`` (and ``async with``) block, written once: a class says only what leaving the
block does (``_leave``: a device closes the Bus it opened, a keepalive stops its thread)."""

from __future__ import annotations

from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["AsyncScoped", "Scoped"]


class Scoped:
    """A context manager: the block gives the object and ends with :meth:`_leave`."""

    def __enter__(self) -> Self:
        """The object itself."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """:meth:`_leave`, given the exception that ends the block (None: none)."""
        self._leave(exc)

    def _leave(self, exc: BaseException | None) -> None:
        """What leaving the block does (``exc``: the exception that ends it, or None)."""
        raise NotImplementedError


class AsyncScoped:
    """An async context manager: the block gives the object and ends with :meth:`_aleave`."""

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
