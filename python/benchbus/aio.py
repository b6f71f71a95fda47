"""asyncio: the Bus and the devices as awaitables, for notebooks, dashboards and other code
that runs on an event loop.

::

    import benchbus as bb

    async with bb.aio.AsyncBus("/dev/ttyUSB0", timeout=0.1) as bus:
        speed, = await bus.read_holding_registers(1, 0x3006, 1)
        async for t, (speed,) in bus.poll(1, 0x3006, interval=0.05, duration=2):
            print(f"{t:5.2f} s  {speed} rpm")

    async with bb.aio.Drive(bus, unit=1) as drive:      # stops the motor on leaving
        await drive.set("speed_setpoint", 1500)
        await drive.forward()
        print(await drive.telemetry())

There is no second protocol engine here: every call is the synchronous :class:`benchbus.Bus`
or device method of the same name, run in a worker thread while the core waits for the
wire with the GIL released, so the event loop never waits for the line. What this layer
adds is the queue in front of those threads and cancellation:

- Each :class:`AsyncBus` has its own worker threads (``workers``, 8 by default), shared by
  the devices made on it. Several calls may be under way at once, and they reach the line
  in the order they were made: a thread lets its call go only once the call before it
  holds its place in the line's queue (``CancelToken.queued``). The core serves them one
  attempt at a time, in that order, but for a write to a unit whose earlier write is not
  over yet, which waits for it.
- A task cancelled while its call still waits in the queue (no thread has taken it) takes
  the call out of the queue: nothing is sent. A task cancelled while its call is in a thread
  gets ``CancelledError`` at once, and the call's :class:`benchbus.CancelToken` is
  cancelled: a call still waiting for its turn on the line leaves without sending
  anything; an attempt on the wire finishes in the core (which keeps the line in step: the
  next call never reads the cancelled call's reply), no retry or further request follows
  (a device method of several requests stops there), and its result is dropped.
- Nothing here runs an event loop of its own (no ``asyncio.run``): it works in the loop a
  notebook already runs (top-level ``await``) as in ``asyncio.run``.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import contextlib
import functools
import inspect
import os
import threading
import time
import types
from collections.abc import Callable, Coroutine, Iterable
from typing import TYPE_CHECKING, Any, ClassVar, Generic, TypeVar, overload

from benchbus import _aio_members, _core
from benchbus._aio_members import DeviceMembers
from benchbus._core import Bus, CancelToken, _Ticks
from benchbus._device import BusDevice, did_you_mean, forked
from benchbus._profile import Device as _SyncDevice
from benchbus._scope import AsyncScoped
from benchbus.exceptions import PortError

if TYPE_CHECKING:
    from typing_extensions import Concatenate, ParamSpec, Self

    P = ParamSpec("P")

__all__ = ["AsyncBus", "AsyncDevice", "AsyncPoll", "Device"]  # and the families': see the end

R = TypeVar("R")

#: How many worker threads an AsyncBus has unless told.
WORKERS = 8
#: Seconds a worker thread waits for a call before it ends (a bus left idle, or never
#: closed, keeps no thread running).
IDLE_END = 10.0
#: How long before a poll's deadline the loop hands the read to a thread, which then waits
#: out the rest on the monotonic clock (the loop's own timers are only as fine as a
#: millisecond).
_EARLY = 0.002
#: How often a thread looks whether the call before its own holds its place in the line's
#: queue (it usually does within microseconds).
_ADMIT_POLL = 0.0002
_JOIN = 1.0  # s: the most a closing waits for a thread past its last act (microseconds)


# ---- cancellation in the core ---------------------------------------------------------------


def _run_cancellable(token: CancelToken, fn: Callable[[], R]) -> R:
    """``fn()`` in this thread under ``token``: once the token is cancelled the core sends
    nothing more (an attempt already on the wire finishes) and the call raises
    :class:`benchbus.Cancelled`; ``token.queued`` says when the call took its place in the
    line's queue."""
    with token:
        result = fn()
    return result


async def _unstoppable(future: asyncio.Future[R]) -> R:
    """The outcome of ``future``, awaited to the end even when the awaiting task is
    cancelled meanwhile (a motor's stop must be sent before ``asyncio.run`` ends and takes
    the worker threads with it); the cancellation is raised after."""
    cancelled: asyncio.CancelledError | None = None
    while not future.done():
        try:
            await asyncio.shield(future)
        except asyncio.CancelledError as exc:
            if future.done() and future.cancelled():
                raise
            cancelled = exc
    result = future.result()
    if cancelled is not None:
        raise cancelled
    return result


# ---- the worker threads -----------------------------------------------------------------------


class _Call:
    """One call waiting for, or in, a worker thread."""

    __slots__ = ("cancellable", "finished", "fn", "future", "loop", "taken", "token")

    def __init__(
        self,
        fn: Callable[[], Any],
        future: asyncio.Future[Any],
        loop: asyncio.AbstractEventLoop,
        cancellable: bool,
    ) -> None:
        self.fn = fn
        self.future = future
        self.loop = loop
        #: False for a call that cannot be cancelled (a motor's stop on leaving a block).
        self.cancellable = cancellable
        #: Cancelled when the awaiting task is; also says when the call took its place in
        #: the line's queue.
        self.token = CancelToken()
        #: Whether a thread has taken it.
        self.taken = False
        #: Set once its thread is done with it.
        self.finished = threading.Event()

    def admitted(self) -> bool:
        """Whether the call after it may go to the line: this one holds its place in the
        line's queue, or is over (or never needed the line)."""
        return self.token.queued or self.finished.is_set()


def _settle(future: asyncio.Future[Any], result: Any, error: BaseException | None) -> None:
    """Give the awaiting task its call's outcome, unless it stopped waiting (cancelled)."""
    if future.done():
        return
    if error is None:
        future.set_result(result)
    elif isinstance(error, StopIteration):  # a future cannot carry one
        future.set_exception(RuntimeError(f"the call raised StopIteration: {error}"))
    else:
        future.set_exception(error)


class _Pool:
    """Worker threads that run calls in the order they were handed over.

    Threads are started as calls need them, up to ``workers``, and end when the pool is
    closed and has nothing left to run, or after :data:`IDLE_END` seconds without a call.
    """

    def __init__(self, workers: int, name: str) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int):
            raise TypeError(f"workers must be an int, got {type(workers).__name__}")
        if not 1 <= workers <= 64:
            raise ValueError(f"workers must be 1..64, got {workers}")
        self._workers = workers
        self._name = name
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue: collections.deque[_Call] = collections.deque()
        self._threads: list[threading.Thread] = []
        self._idle = 0
        self._live = 0
        self._closed = False
        self._then: Callable[[], None] | None = None
        #: The call a thread took last: the next waits until it holds its place in line.
        self._last: _Call | None = None
        #: Done once closing is: a future of no event loop, so that any loop may await it.
        self._ended: concurrent.futures.Future[None] | None = None

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    def threads(self) -> list[threading.Thread]:
        """The threads started so far (ended ones included)."""
        with self._lock:
            return list(self._threads)

    def submit(self, fn: Callable[[], R], *, cancellable: bool = True) -> asyncio.Future[R]:
        """Queue ``fn`` for a thread; the future it gives is the outcome. Cancelling the
        future takes a queued call out of the queue, or cancels a running one's token."""
        loop = asyncio.get_running_loop()
        future: asyncio.Future[R] = loop.create_future()
        call = _Call(fn, future, loop, cancellable)
        with self._lock:
            if self._closed:
                raise PortError(f"{self._name}: closed")
            self._queue.append(call)
            if len(self._queue) > self._idle and self._live < self._workers:
                thread = threading.Thread(
                    target=self._work,
                    name=f"benchbus.aio {self._name} #{len(self._threads)}",
                    daemon=True,
                )
                self._threads.append(thread)
                self._live += 1
                thread.start()
            self._wake.notify()
        if cancellable:
            future.add_done_callback(functools.partial(self._dropped, call))
        return future

    def _dropped(self, call: _Call, future: asyncio.Future[Any]) -> None:
        """On the loop, once ``call``'s future is done: if it was cancelled, take the call
        out of the queue, or tell the core through its token."""
        if not future.cancelled():
            return
        with self._lock:
            if not call.taken:
                with contextlib.suppress(ValueError):
                    self._queue.remove(call)
                return
        call.token.cancel()

    def _work(self) -> None:
        """A worker thread: take calls in order and run them, until closed and drained."""
        while True:
            with self._lock:
                while not self._queue and not self._closed:
                    self._idle += 1
                    woke = self._wake.wait(IDLE_END)
                    self._idle -= 1
                    if not (woke or self._queue or self._closed):
                        self._live -= 1  # idle too long: the next call starts another
                        return
                if not self._queue:
                    self._live -= 1
                    last = self._live == 0
                    break
                call = self._queue.popleft()
                if call.cancellable and call.future.cancelled():
                    # Cancelled on the loop, its callback not yet run: never sent.
                    continue
                call.taken = True
                before, self._last = self._last, call
            result: Any = None
            error: BaseException | None = None
            try:
                # The calls reach the line in the order they were made: this one goes once
                # the one before holds its place in the line's queue (or is over).
                while before is not None and not before.admitted():
                    before.finished.wait(_ADMIT_POLL)
                del before
                result = _run_cancellable(call.token, call.fn)
            except BaseException as exc:  # handed to the awaiting task
                error = exc
            finally:
                call.finished.set()
            with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
                call.loop.call_soon_threadsafe(_settle, call.future, result, error)
            del call, result, error
        if last:
            self._finish()

    def _finish(self) -> None:
        """In the last thread to end: run what closing asked for, and say it is done."""
        then, self._then = self._then, None
        error: BaseException | None = None
        if then is not None:
            try:
                then()
            except BaseException as exc:
                error = exc
        ended = self._ended
        if ended is not None and not ended.done():
            if error is None:
                ended.set_result(None)
            else:
                ended.set_exception(error)

    def close(self, then: Callable[[], None] | None = None) -> asyncio.Future[None]:
        """Refuse new calls; fail the queued ones that can be cancelled with PortError,
        unsent; let the others and those in threads finish; then run ``then`` (in the
        last thread, or here if none runs). The future it gives is done when all that is."""
        loop = asyncio.get_running_loop()
        with self._lock:
            if self._ended is not None:
                return asyncio.ensure_future(
                    self._joined(asyncio.wrap_future(self._ended, loop=loop))
                )
            self._closed = True
            self._ended = concurrent.futures.Future()
            self._then = then
            dropped = [c for c in self._queue if c.cancellable]
            for call in dropped:
                self._queue.remove(call)
            self._wake.notify_all()
            running = self._live > 0
        for call in dropped:
            error = PortError(f"{self._name}: closed before it was sent")
            if call.loop is loop:
                _settle(call.future, None, error)
            else:  # a call made on another event loop
                with contextlib.suppress(RuntimeError):  # that loop is closed: nobody waits
                    call.loop.call_soon_threadsafe(_settle, call.future, None, error)
        if not running:
            self._finish()
        return asyncio.ensure_future(self._joined(asyncio.wrap_future(self._ended, loop=loop)))

    async def _joined(self, ended: asyncio.Future[None]) -> None:
        """``ended``'s outcome, once the threads have also returned: the last one says the
        pool has ended just before it returns, so closing leaves no thread behind. Waited
        for on the loop without blocking it (at most :data:`_JOIN`); cancelling this leaves
        ``ended`` (shared by every loop's wait) alone, and waits for no thread."""
        try:
            await asyncio.shield(ended)
        finally:
            if ended.done() and not ended.cancelled():
                deadline = time.monotonic() + _JOIN
                while any(t.is_alive() for t in self.threads()) and time.monotonic() < deadline:
                    await asyncio.sleep(_ADMIT_POLL)


# ---- the bus ----------------------------------------------------------------------------------


def _awaitable(
    method: Callable[Concatenate[Bus, P], R],
) -> Callable[Concatenate[AsyncBus, P], Coroutine[Any, Any, R]]:
    """The Bus's ``method`` as a coroutine of AsyncBus, run in one of its threads (same
    name, signature and docstring)."""
    name = method.__name__

    async def call(self: AsyncBus, /, *args: P.args, **kwargs: P.kwargs) -> R:
        bound: Callable[..., R] = getattr(self._bus, name)
        return await self._run(bound, *args, **kwargs)

    functools.update_wrapper(call, method)
    return call


T = TypeVar("T")


class _BusProperty(Generic[T]):
    """A property of the Bus underneath, read as it is (nothing is sent), with its
    docstring."""

    def __init__(self, prop: Callable[[Bus], T]) -> None:
        """Read through ``prop`` (``Bus.port``)."""
        self._prop = prop
        self.__doc__ = prop.__doc__

    @overload
    def __get__(self, bus: None, owner: type[AsyncBus] | None = None) -> Self: ...
    @overload
    def __get__(self, bus: AsyncBus, owner: type[AsyncBus] | None = None) -> T: ...
    def __get__(self, bus: AsyncBus | None, owner: type[AsyncBus] | None = None) -> T | Self:
        """The property's value on ``bus``'s Bus (the descriptor itself on the class)."""
        if bus is None:
            return self
        getter: Any = self._prop
        value: T = getter.__get__(bus.bus)
        return value


class _SettableBusProperty(_BusProperty[T]):
    """A property of the Bus underneath that may also be set (``abus.timeout = 5``): set on
    the Bus at once, nothing sent, checked as the Bus checks it."""

    def __set__(self, bus: AsyncBus, value: T) -> None:
        """Set the property on ``bus``'s Bus (a bad value raises as there)."""
        setter: Any = self._prop
        setter.__set__(bus.bus, value)


class AsyncBus(AsyncScoped):
    """A :class:`benchbus.Bus` for asyncio: the same constructor, methods and properties,
    each method a coroutine run in the bus's worker threads.

    ::

        async with bb.aio.AsyncBus("/dev/ttyUSB0", baudrate=19200) as bus:
            speed, = await bus.read_holding_registers(1, 0x3006, 1)
            await bus.write_register(1, 0x2001, 1500)

    The port is opened by the constructor, as a Bus opens it (a serial port at once; a
    ``tcp://`` connection may wait up to its 3 s connect timeout), and exclusively: a Bus
    and an AsyncBus cannot hold the same port at once (PortError). ``workers`` (1..64, 8 by
    default) is how many calls may be in threads at once; more wait in the bus's queue, in
    the order they were made, and a cancelled one leaves the queue unsent. The threads
    start as calls need them and end after :data:`IDLE_END` seconds without one. Devices
    made on the AsyncBus (``bb.aio.Drive(bus, 1)``) share its threads.

    :meth:`aclose` (or leaving ``async with``) refuses new calls (PortError), fails the
    calls still queued with PortError without sending them, lets those already in a
    thread finish, then closes the port and ends the threads. Cancelling a call in a
    thread returns ``CancelledError`` to its task at once and cancels the call's
    :class:`benchbus.CancelToken`: its attempt on the wire, if any, finishes in the core,
    nothing more is sent for it, and its result is dropped.

    Like a Bus, an AsyncBus belongs to the process that opened it: in a child made by fork
    (whose worker threads are the parent's, and do not exist there) every call and
    :meth:`poll` raise the Bus's PortError at once, naming fork and what to do, and
    :meth:`aclose` sends nothing, raises nothing and leaves the parent's port and threads
    as they were.
    """

    def __init__(
        self,
        port: str | os.PathLike[str],
        *args: Any,
        workers: int = WORKERS,
        **kwargs: Any,
    ) -> None:
        """Open ``port`` as :class:`benchbus.Bus` does, with the same arguments (``baudrate``,
        ``parity``, ``stopbits``, ``timeout``, ``retries``, then its keyword-only ones:
        ``turnaround``, ``reconnect``, ``echo``, ``rs485``, ``rts_delay``, ``silence``,
        ``framing``, ``bytesize``), given to it as they are; ``workers`` (1..64) is how many
        calls may run at once."""
        pool = _Pool(workers, str(port))
        self._adopt(Bus(port, *args, **kwargs), pool)

    def _adopt(self, bus: Bus, pool: _Pool) -> None:
        """Serve ``bus`` with ``pool``'s threads."""
        self._bus = bus
        self._pool = pool

    @classmethod
    def _around(cls, bus: Bus) -> AsyncBus:
        """An AsyncBus, with its own threads, for a Bus opened elsewhere (a device's)."""
        made = cls.__new__(cls)
        made._adopt(bus, _Pool(WORKERS, bus.port))
        return made

    async def _run(self, fn: Callable[..., R], *args: Any, **kwargs: Any) -> R:
        """``fn(*args, **kwargs)`` in a worker thread (in a child made by fork, the Bus's
        PortError at once: the threads and their locks are the parent's)."""
        self._bus._owned()
        if self._pool.closed:
            raise PortError(f"{self._bus.port}: the AsyncBus is closed")
        return await self._pool.submit(functools.partial(fn, *args, **kwargs))

    @property
    def bus(self) -> Bus:
        """The synchronous :class:`benchbus.Bus` underneath (for code that needs one; its
        calls block the thread that makes them)."""
        return self._bus

    read_holding_registers = _awaitable(Bus.read_holding_registers)
    read_coils = _awaitable(Bus.read_coils)
    read_discrete_inputs = _awaitable(Bus.read_discrete_inputs)
    read_input_registers = _awaitable(Bus.read_input_registers)
    write_coil = _awaitable(Bus.write_coil)
    write_coils = _awaitable(Bus.write_coils)
    mask_write_register = _awaitable(Bus.mask_write_register)
    read_write_registers = _awaitable(Bus.read_write_registers)
    read_exception_status = _awaitable(Bus.read_exception_status)
    diagnostics = _awaitable(Bus.diagnostics)
    report_server_id = _awaitable(Bus.report_server_id)
    get_comm_event_counter = _awaitable(Bus.get_comm_event_counter)
    get_comm_event_log = _awaitable(Bus.get_comm_event_log)
    read_file_record = _awaitable(Bus.read_file_record)
    write_file_record = _awaitable(Bus.write_file_record)
    read_fifo_queue = _awaitable(Bus.read_fifo_queue)
    request = _awaitable(Bus.request)
    write_register = _awaitable(Bus.write_register)
    write_registers = _awaitable(Bus.write_registers)
    read_device_identification = _awaitable(Bus.read_device_identification)
    broadcast_write_register = _awaitable(Bus.broadcast_write_register)
    broadcast_write_coil = _awaitable(Bus.broadcast_write_coil)
    broadcast_write_coils = _awaitable(Bus.broadcast_write_coils)
    broadcast_write_registers = _awaitable(Bus.broadcast_write_registers)
    scan = _awaitable(Bus.scan)
    reopen = _awaitable(Bus.reopen)

    stats = _BusProperty(Bus.stats)
    port = _BusProperty(Bus.port)
    baudrate = _BusProperty(Bus.baudrate)
    parity = _BusProperty(Bus.parity)
    stopbits = _BusProperty(Bus.stopbits)
    bytesize = _BusProperty(Bus.bytesize)
    framing = _BusProperty(Bus.framing)
    timeout = _SettableBusProperty(Bus.timeout)
    retries = _SettableBusProperty(Bus.retries)
    turnaround = _BusProperty(Bus.turnaround)
    silence = _BusProperty(Bus.silence)
    char_time = _BusProperty(Bus.char_time)
    t3_5 = _BusProperty(Bus.t3_5)
    reconnect = _BusProperty(Bus.reconnect)
    echo = _BusProperty(Bus.echo)
    rs485 = _BusProperty(Bus.rs485)

    @property
    def closed(self) -> bool:
        """True once :meth:`aclose` was called, or the port is closed."""
        return self._pool.closed or self._bus.closed

    def poll(
        self,
        unit: int,
        address: int,
        count: int = 1,
        *,
        interval: float,
        duration: float | None = None,
    ) -> AsyncPoll:
        """:meth:`benchbus.Bus.poll` as an async iterator::

            async for t, (speed,) in bus.poll(1, 0x3006, interval=0.05, duration=10):
                print(f"{t:6.2f} s  {speed} rpm")

        The same deadlines (absolute: ``start + n * interval``, a deadline already past
        skipped and counted in :attr:`AsyncPoll.missed`), the same ``(t, values)`` and the
        same checks of the arguments, here, before anything is sent. The loop waits for
        each deadline (other tasks run meanwhile); the read goes through the bus's queue
        like any call. A failed read raises from ``__anext__``; iterating again resumes at
        the following deadline.
        """
        self._bus._owned()
        if self._pool.closed:
            raise PortError(f"{self._bus.port}: the AsyncBus is closed")
        # The sync poll checks the arguments (and a closed port) as Bus.poll does.
        self._bus.poll(unit, address, count, interval=interval, duration=duration)
        return AsyncPoll(self, unit, address, count, interval, duration)

    async def aclose(self) -> None:
        """Refuse new calls, fail the queued ones with PortError (unsent), wait for those
        in threads to finish, close the port and end the threads. Closing twice is
        harmless; cancelling the wait leaves the closing to go on. In a child made by fork,
        only the Bus's close (which sends nothing there)."""
        if forked(self._bus):
            self._bus.close()
            return
        await asyncio.shield(self._pool.close(then=self._bus.close))

    async def close(self) -> None:
        """:meth:`aclose`, under the Bus's name."""
        await self.aclose()

    async def _aleave(self, exc: BaseException | None) -> None:
        """Leaving an ``async with`` block: :meth:`aclose`."""
        await self.aclose()

    def __repr__(self) -> str:
        """The Bus's, marked async."""
        return f"<AsyncBus {self._bus!r}>"


class AsyncPoll:
    """Reads of holding registers on absolute deadlines, as an async iterator; made by
    :meth:`AsyncBus.poll`. Yields ``(t, values)`` as :class:`benchbus.Poll` does."""

    def __init__(
        self,
        bus: AsyncBus,
        unit: int,
        address: int,
        count: int,
        interval: float,
        duration: float | None,
    ) -> None:
        """The poll ``bus.poll(...)`` describes; it starts at the first ``__anext__``."""
        self._bus = bus
        self._read = (unit, address, count)
        self._interval = interval
        # The deadlines are the core's Schedule (what Bus.poll and record use); it gives
        # each at once (the loop, not the schedule, waits for it).
        self._ticks = _Ticks(interval, duration, sleep=lambda _seconds: None)
        self._missed = 0
        self._started: float | None = None

    def __aiter__(self) -> Self:
        """The poll itself."""
        return self

    async def __anext__(self) -> tuple[float, list[int]]:
        """Wait until the next deadline not yet past, read, and return ``(t, values)``;
        StopAsyncIteration once the duration is over."""
        try:
            n, deadline, missed = next(self._ticks)
        except StopIteration:
            raise StopAsyncIteration from None
        self._missed += missed
        if self._started is None:
            self._started = deadline
        await asyncio.sleep(max(0.0, deadline - _EARLY - time.monotonic()))
        sync = self._bus.bus
        unit, address, count = self._read

        def read() -> list[int]:
            left = deadline - time.monotonic()
            if left > 0:
                time.sleep(left)
            return sync.read_holding_registers(unit, address, count)

        values = await self._bus._run(read)
        return n * self._interval, values

    @property
    def missed(self) -> int:
        """Deadlines skipped because they had passed when the next sample was asked for."""
        return self._missed

    @property
    def started(self) -> float | None:
        """``time.monotonic()`` at the poll's start (the first ``__anext__``); None before."""
        return self._started


# ---- the devices ------------------------------------------------------------------------------

#: Attributes read on the loop as they are: what a device knows without asking it.
_LOCAL = frozenset(
    {
        "unit",
        "family",
        "write_ack",
        "timeout",
        "retries",
        "block_reads",
        "profile",
        "enums",
        "max_read",
        "max_write",
        "max_read_bits",
        "max_write_bits",
        "min_write_interval",
        "SAMPLE_FIELDS",
        "LINE_DEFAULTS",
        "IDENTITY",
        "units",
        "sample_units",
        "registers",
        "keepalive",
    }
)

D = TypeVar("D", bound=BusDevice)


def _unwrap(value: Any) -> Any:
    """The sync Bus of an AsyncBus; anything else as it is."""
    return value.bus if isinstance(value, AsyncBus) else value


class AsyncDevice(AsyncScoped, Generic[D]):
    """A benchbus device for asyncio: the synchronous device class's methods as coroutines,
    run in the threads of the AsyncBus it is made on (or of its own, on a port).

    ``await drive.get("speed")``, ``await drive.set("speed_setpoint", 1500)``, ``await
    drive.forward()``, ``await drive.telemetry()``: every public method of the sync class,
    same arguments, same result. Its readable properties are awaitables (``await
    drive.speed``, ``await dev.temperature``); write them with ``await dev.set(name,
    value)``. What the device knows without asking it (``unit``, ``family``, ``profile``,
    ``units()``, ``registers()``, the static tables) is plain. ``bus`` is the AsyncBus.

    ``async with`` closes what the device opened and, for a motor, first stops it, as the
    sync ``with`` does: also after an exception and when the task is being cancelled (the
    stop cannot be cancelled, and is sent even then).

    Type checkers see each member of a subclass with the type it has here (``await
    drive.speed`` an int, ``await drive.telemetry()`` a DriveTelemetry), declared in
    ``_aio_members.pyi``, which is generated from the sync class; a profile's registers
    are ``Any``.
    """

    #: The synchronous class (a subclass sets it).
    SYNC: ClassVar[type[BusDevice]]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        """The sync class's constructor, with an :class:`AsyncBus` where it takes a Bus (or
        a port, which the device opens, with threads of its own)."""
        given = next((a for a in (*args, *kwargs.values()) if isinstance(a, AsyncBus)), None)
        sync = self.SYNC(*map(_unwrap, args), **{k: _unwrap(v) for k, v in kwargs.items()})
        object.__setattr__(self, "_sync", sync)
        object.__setattr__(self, "_owns_pool", given is None)
        object.__setattr__(self, "_abus", AsyncBus._around(sync.bus) if given is None else given)

    _sync: D
    _owns_pool: bool
    _abus: AsyncBus

    @property
    def sync(self) -> D:
        """The synchronous device underneath (its calls block the thread that makes them)."""
        return self._sync

    @property
    def bus(self) -> AsyncBus:
        """The AsyncBus the device talks through."""
        return self._abus

    def _call(self, fn: Callable[..., R]) -> Callable[..., Coroutine[Any, Any, R]]:
        """``fn`` as a coroutine function run in the bus's threads."""

        @functools.wraps(fn)
        async def call(*args: Any, **kwargs: Any) -> R:
            return await self._abus._run(fn, *args, **kwargs)

        return call

    if not TYPE_CHECKING:  # type checkers see each member (benchbus._aio_members)

        def __getattr__(self, name: str) -> Any:
            """A public method as a coroutine function; a property's value as an awaitable."""
            return self._served(name)

    def _served(self, name: str) -> Any:
        """What ``__getattr__`` gives for ``name``: the rules ``_aio_members.pyi`` is
        generated by."""
        sync = self._sync
        if name.startswith("_"):
            raise AttributeError(name)
        found = inspect.getattr_static(sync, name, None)
        if name in _LOCAL or isinstance(found, (staticmethod, classmethod)):
            return getattr(sync, name)
        if found is None:
            registers = getattr(sync, "_register_named", None)
            if registers is None or not registers(name):
                raise self._no_attribute(name)
            # A profile's register, which the sync device reads as an attribute.
            return self._call(lambda: getattr(sync, name))()
        if inspect.isroutine(found):
            return self._call(getattr(sync, name))
        return self._call(lambda: getattr(sync, name))()

    def _no_attribute(self, name: str) -> AttributeError:
        """An AttributeError for ``name``, naming the closest public names (nothing is
        read to find them)."""
        hint = did_you_mean(name, (n for n in dir(self) if n[:1] != "_"))
        return AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}{hint}")

    def __setattr__(self, name: str, value: Any) -> None:
        """Refused: writing a register is ``await device.set(name, value)``, and any other
        setting ``await device.assign(name, value)``."""
        raise AttributeError(
            f"{type(self).__name__}.{name} cannot be set here: use "
            f"`await device.set({name!r}, value)` for a register or "
            f"`await device.assign({name!r}, value)`"
        )

    async def assign(self, name: str, value: Any) -> None:
        """Set the sync device's attribute ``name`` (a setting such as a drive's
        ``comm_loss_timeout``, or a register's property) to ``value``, in the bus's threads:
        ``device.name = value`` for asyncio."""
        if name.startswith("_") or not inspect.isdatadescriptor(
            inspect.getattr_static(type(self._sync), name, None)
        ):
            raise self._no_attribute(name)
        sync = self._sync
        await self._abus._run(setattr, sync, name, value)

    def __dir__(self) -> Iterable[str]:
        """The sync device's public names, and this object's."""
        return sorted({*object.__dir__(self), *(n for n in dir(self._sync) if n[:1] != "_")})

    async def aclose(self) -> None:
        """Close what the device opened (its Bus, its keepalive), after the calls queued
        before; cannot be cancelled half-way."""
        await self._run_then_end(lambda: self._sync.close())

    async def _run_then_end(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in the bus's threads (after what is queued, and whatever happens to
        the awaiting task), then end the threads if they are the device's. In a child made
        by fork, ``fn`` here and now (its calls raise at once there; closing sends
        nothing), leaving the parent's threads alone."""
        if forked(self._abus.bus):
            fn()
            return
        if self._abus._pool.closed:  # the bus is closing: a thread of its own, off the loop
            await _unstoppable(asyncio.ensure_future(asyncio.to_thread(fn)))
            return
        done = self._abus._pool.submit(fn, cancellable=False)
        ended = self._abus._pool.close() if self._owns_pool else None
        await _unstoppable(done)
        if ended is not None:
            await _unstoppable(ended)

    async def _aleave(self, exc: BaseException | None) -> None:
        """Leaving an ``async with`` block: the sync device's ``__exit__`` in a thread: for
        a motor, stop it (also after an exception or on cancellation: the stop is shielded),
        then close what it opened."""
        info = (None, None, None) if exc is None else (type(exc), exc, exc.__traceback__)
        await self._run_then_end(lambda: self._sync.__exit__(*info))

    def __repr__(self) -> str:
        """The sync device's, marked async."""
        return f"<async {self._sync!r}>"


class Device(AsyncDevice[_SyncDevice], DeviceMembers):
    """:class:`benchbus.Device` (a device described by a profile) for asyncio (see
    :class:`AsyncDevice`)::

        dev = bb.aio.Device.from_profile("meter.toml", bus, unit=1)
        print(await dev.read("temperature"), await dev.humidity)
    """

    #: The synchronous class this one wraps.
    SYNC = _SyncDevice

    if TYPE_CHECKING:  # the profile's registers, which no class declares

        def __getattr__(self, name: str) -> Any:
            """A register of the profile: an awaitable of its value."""

    @classmethod
    def from_profile(
        cls,
        profile: _core.Profile | str | os.PathLike[str],
        port_or_bus: str | os.PathLike[str] | AsyncBus,
        unit: int = 1,
        *,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> Device:
        """The device ``profile`` (a Profile, a file, or a profile's name: ``"sdm630"``)
        describes at ``unit``, on an AsyncBus or a port (as
        :meth:`benchbus.Device.from_profile`)."""
        return cls(profile, port_or_bus, unit, timeout=timeout, retries=retries)


# ---- the families' async classes, from the registry -------------------------------------------


def _family_class(sync: type[BusDevice]) -> type[AsyncDevice[Any]]:
    """The async class of a family's sync class ``sync``: of the same name, extending
    :class:`AsyncDevice` and the family's members class (``benchbus._aio_members``)."""
    name = sync.__name__
    namespace = {
        "__doc__": f":class:`benchbus.{name}` for asyncio (see :class:`AsyncDevice`).",
        "__module__": __name__,
        "__qualname__": name,
        "SYNC": sync,
    }
    bases = (AsyncDevice[sync], getattr(_aio_members, f"{name}Members"))  # type: ignore[valid-type]
    return types.new_class(name, bases, {}, lambda ns: ns.update(namespace))


#: ``Drive``, ``PblDrive``... one a family of the registry (``_aio_members.SYNC_CLASSES``).
#: ``_aio_members.pyi`` declares them, with their members' types, for type checkers.
_FAMILY_CLASSES = {c.__name__: _family_class(c) for c in _aio_members.SYNC_CLASSES}
if len(_FAMILY_CLASSES) < len(_aio_members.SYNC_CLASSES) or {*_FAMILY_CLASSES} & {*__all__}:
    raise RuntimeError(f"a family's class name is taken in benchbus.aio: {[*_FAMILY_CLASSES]}")
globals().update(_FAMILY_CLASSES)
vars(_aio_members).update(_FAMILY_CLASSES)  # where the stub declares them
if TYPE_CHECKING:
    from benchbus._aio_members import *  # noqa: F403
__all__ += _aio_members.__all__
