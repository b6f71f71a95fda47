//! The order of writes to one unit: a write goes to the line only once the writes made
//! before it to the same unit are over, and not at all once an urgent write, a write
//! nested in it (a signal handler's) or a broadcast made after it has gone out.
//!
//! A call that must try again takes a new turn at the back of the line's queue (see
//! [`super::queue`]). For a read that costs nothing, but a write whose reply was lost or
//! garbled has usually been carried out: sent again behind a later write to the same unit,
//! it would leave the device with the earlier value while every call succeeded. So a write
//! made later to that unit waits, without a turn, until the earlier one is over: the device
//! takes the writes in the order they were made, the last one last (and a cancelled or
//! interrupted call stops waiting at once, unsent). Reads (functions 0x01
//! to 0x04 and the other reading functions, also as raw requests), other units and urgent
//! writes (a motor's stop) are not held up. An urgent write or a broadcast goes at once
//! instead; a write made before it that has not gone out by then, or would go out again,
//! does not (a drive's run command sent after the stop would start the motor again): it
//! fails, cancelled or with its last attempt's error.
//!
//! A write made on the thread of an earlier one to its unit (a signal handler's, run while
//! that one waits or between its attempts) waits only for what that one waits for: it
//! would wait for itself. Once gone out, it overrules the writes made before it to its
//! unit, whatever their addresses, as an urgent write does: the earlier one, resumed after
//! the handler, would otherwise go out after it, out of the order they were made in.

use crate::codec::pdu::decode::decode;
use crate::codec::Request;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread::{self, ThreadId};
use std::time::Duration;

/// How often a write held behind an earlier one to its unit looks again (waiting without a
/// turn, so the line serves the others meanwhile).
pub(crate) const POLL: Duration = Duration::from_millis(1);

/// How often a write held behind an earlier one asks whether its caller wants it to stop
/// (Ctrl-C: in Python that takes the GIL for a moment, so not at every look).
pub(crate) const ASK: Duration = Duration::from_millis(20);

/// Whether `request` may change the device: a write, whose order among the writes to its
/// unit is kept. A raw request is what the codec decodes it to, so that a read built by hand
/// (as the gateway forwards its clients' requests) is a read.
pub(crate) fn changes_device(request: &Request) -> bool {
    match request {
        Request::Raw { function, data, .. } => {
            decode(*function, data).map_or(true, |decoded| !decoded.is_read())
        }
        other => !other.is_read(),
    }
}

/// The writes of a Bus: those in progress, and the calls that overrule them.
#[derive(Default)]
pub(crate) struct Writes(Mutex<Book>);

#[derive(Default)]
struct Book {
    /// The write calls in progress: their unit, call number and thread.
    writing: Vec<(u8, u64, ThreadId)>,
    /// The last urgent or nested write to each unit that has gone out, by call number.
    urgent: HashMap<u8, u64>,
    /// The last broadcast, by call number.
    broadcast: Option<u64>,
}

/// A write call in progress, recorded until dropped.
pub(crate) struct Writing<'a> {
    writes: &'a Writes,
    unit: u8,
    call: u64,
    /// Made on the thread of an earlier write to its unit still in progress (nested in it).
    nested: bool,
}

impl Writes {
    /// Numbers a write call to `unit` from `calls` and records it, both at once, so that the
    /// numbers of one unit's writes are the order they were made in.
    pub(crate) fn enter(&self, unit: u8, calls: &AtomicU64) -> Writing<'_> {
        let mut book = self.lock();
        let call = calls.fetch_add(1, Ordering::Relaxed);
        let me = thread::current().id();
        let nested = book.writing.iter().any(|&(u, _, t)| u == unit && t == me);
        book.writing.push((unit, call, me));
        Writing {
            writes: self,
            unit,
            call,
            nested,
        }
    }

    /// Numbers a call that overrules the writes made before it (an urgent write or a
    /// broadcast) from `calls`, in the order of the writes' numbers.
    pub(crate) fn number(&self, calls: &AtomicU64) -> u64 {
        let _book = self.lock();
        calls.fetch_add(1, Ordering::Relaxed)
    }

    /// Records that the urgent or nested write `call` to `unit` (None: the broadcast `call`)
    /// has gone out: the writes made before it do not go out from now on.
    pub(crate) fn overrule(&self, unit: Option<u8>, call: u64) {
        let mut book = self.lock();
        match unit {
            Some(unit) => {
                let last = book.urgent.entry(unit).or_insert(call);
                *last = (*last).max(call);
            }
            None => book.broadcast = book.broadcast.max(Some(call)),
        }
    }

    /// Whether a write to `unit` made before `call` on another thread is still in progress
    /// (on the thread of `call`: made before the first write of that thread to `unit` still
    /// in progress, which is what that one waits for).
    pub(crate) fn behind(&self, unit: u8, call: u64) -> bool {
        let me = thread::current().id();
        let book = self.lock();
        let mine = book
            .writing
            .iter()
            .filter(|&&(u, _, t)| u == unit && t == me);
        let limit = mine.map(|&(_, c, _)| c).fold(call, u64::min);
        book.writing
            .iter()
            .any(|&(u, c, t)| u == unit && c < limit && t != me)
    }

    /// Whether an urgent or nested write to the unit of `writing`, or a broadcast, made
    /// after it has gone out.
    pub(crate) fn overruled(&self, writing: &Writing<'_>) -> bool {
        let book = self.lock();
        let urgent = book.urgent.get(&writing.unit).copied();
        [urgent, book.broadcast]
            .into_iter()
            .flatten()
            .any(|later| later > writing.call)
    }

    fn lock(&self) -> MutexGuard<'_, Book> {
        // A panic while holding it leaves a consistent book: go on.
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl Writing<'_> {
    /// The call's number.
    pub(crate) fn call(&self) -> u64 {
        self.call
    }

    /// Whether it was made on the thread of an earlier write to its unit still in progress
    /// (a signal handler's): once gone out, it overrules the writes made before it.
    pub(crate) fn nested(&self) -> bool {
        self.nested
    }
}

impl Drop for Writing<'_> {
    fn drop(&mut self) {
        let (unit, call) = (self.unit, self.call);
        self.writes
            .lock()
            .writing
            .retain(|&(u, c, _)| (u, c) != (unit, call));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Writes::behind`] asked on another thread.
    fn elsewhere(writes: &Writes, unit: u8, call: u64) -> bool {
        thread::scope(|s| s.spawn(|| writes.behind(unit, call)).join().unwrap())
    }

    #[test]
    fn a_write_waits_only_for_earlier_writes_to_its_unit_from_other_threads() {
        let (writes, calls) = (Writes::default(), AtomicU64::new(7));
        let first = writes.enter(1, &calls);
        let other_unit = writes.enter(2, &calls);
        // On this thread, a later write does not wait for the earlier one.
        let later = writes.enter(1, &calls);
        assert!(first.call() < later.call());
        // Made while the first is in progress on its thread: nested (once gone out, the Bus
        // records it as overruling the writes before it).
        assert!(later.nested() && !first.nested() && !other_unit.nested());
        assert!(!writes.behind(1, later.call()));
        // On another, it does, until the earlier ones are over.
        assert!(elsewhere(&writes, 1, later.call()));
        assert!(!elsewhere(&writes, 1, first.call()));
        drop(first);
        assert!(elsewhere(&writes, 1, later.call() + 1));
        drop(later);
        assert!(!elsewhere(&writes, 1, u64::MAX));
        assert!(!writes.behind(2, other_unit.call()));
        drop(other_unit);
        assert!(writes.lock().writing.is_empty());
    }

    #[test]
    fn a_write_nested_in_an_earlier_one_waits_only_for_what_that_one_waits_for() {
        // Thread A's write, then thread B's, then A's again (a signal handler's, run while
        // A's first is between attempts): A's second must not wait for B's, which waits for
        // A's first, which waits for the handler.
        let (writes, calls) = (Writes::default(), AtomicU64::new(0));
        let early = thread::scope(|s| {
            s.spawn(|| {
                let b = writes.enter(1, &calls);
                let call = b.call();
                std::mem::forget(b); // B's stays in progress
                call
            })
            .join()
            .unwrap()
        });
        let a = writes.enter(1, &calls);
        let b_late = thread::scope(|s| {
            s.spawn(|| {
                let b = writes.enter(1, &calls);
                let call = b.call();
                std::mem::forget(b);
                call
            })
            .join()
            .unwrap()
        });
        let nested = writes.enter(1, &calls);
        assert!(early < a.call() && a.call() < b_late && b_late < nested.call());
        // Both of A's wait for B's earlier write, neither for B's later one.
        assert!(writes.behind(1, a.call()));
        assert!(writes.behind(1, nested.call()));
        writes.lock().writing.retain(|&(_, c, _)| c != early);
        assert!(!writes.behind(1, nested.call()));
        assert!(elsewhere(&writes, 1, b_late));
    }

    #[test]
    fn a_raw_request_changes_the_device_as_what_it_decodes_to() {
        let raw = |function: u8, data: &[u8]| Request::Raw {
            function,
            data: data.to_vec(),
            reply_length: None,
        };
        assert!(!changes_device(&raw(0x03, &[0, 5, 0, 1])));
        assert!(!changes_device(&raw(0x04, &[0, 5, 0, 2])));
        assert!(changes_device(&raw(0x06, &[0, 5, 0, 1])));
        // Not a read the codec knows (a wrong length, a function of a device's own): held.
        assert!(changes_device(&raw(0x03, &[0, 5])));
        assert!(changes_device(&raw(0x41, &[1, 2])));
        let read = Request::ReadHoldingRegisters {
            address: 5,
            count: 1,
        };
        let write = Request::WriteSingleRegister {
            address: 5,
            value: 1,
        };
        assert!(!changes_device(&read) && changes_device(&write));
    }

    #[test]
    fn an_urgent_write_or_a_broadcast_gone_out_overrules_only_the_writes_made_before_it() {
        let (writes, calls) = (Writes::default(), AtomicU64::new(0));
        let (one, two) = (writes.enter(1, &calls), writes.enter(2, &calls));
        let urgent = writes.number(&calls);
        let after = writes.enter(1, &calls);
        assert!(!writes.overruled(&one), "numbered, not gone out yet");
        writes.overrule(Some(1), urgent);
        assert!(writes.overruled(&one));
        assert!(!writes.overruled(&two) && !writes.overruled(&after));
        let broadcast = writes.number(&calls);
        writes.overrule(None, broadcast);
        assert!(writes.overruled(&two) && writes.overruled(&after));
    }
}
