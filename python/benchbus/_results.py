"""The results of the Bus's serial line counters (Modbus application protocol 6.9, 6.10):
named tuples, so that ``status, count = bus.get_comm_event_counter(1)`` reads as a pair."""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["CommEventCounter", "CommEventLog"]


class CommEventCounter(NamedTuple):
    """A Get Comm Event Counter reply (function 0x0B): the status word and the event
    counter."""

    #: 0xFFFF while the device is still processing a program command, else 0x0000.
    status: int
    #: Messages the device has completed without an error since its last restart (the
    #: counter wraps at 0xFFFF); neither exception replies nor this request are counted.
    event_count: int


class CommEventLog(NamedTuple):
    """A Get Comm Event Log reply (function 0x0C): the status word, both counters and the
    events."""

    #: 0xFFFF while the device is still processing a program command, else 0x0000.
    status: int
    #: As :attr:`CommEventCounter.event_count`.
    event_count: int
    #: Messages the device has processed since its last restart.
    message_count: int
    #: The events, one byte each, the newest first, 0 to 64 of them (their bits as the
    #: specification's 6.10 defines them: receive, send, listen only mode, restart).
    events: bytes
