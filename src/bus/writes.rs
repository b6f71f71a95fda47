//! The order of writes to one unit: a write goes to the line only once the writes made
//! before it to the same unit are over, and a write is not sent again once an urgent write
//! or a broadcast made after it has come.
//!
//! A call that must try again takes a new turn at the back of the line's queue (see
//! [`super::queue`]). For a read that costs nothing, but a write whose reply was lost or
//! garbled has usually been carried out: sent again behind a later write to the same unit,
//! it would leave the device with the earlier value while every call succeeded. So a write
//! made later to that unit waits, without a turn, until the earlier one is over: the device
//! takes the writes in the order they were made, the last one last. Reads (functions 0x01
//! to 0x04), other units and urgent writes (a motor's stop) are not held up; an urgent
//! write or a broadcast goes at once instead, and the earlier writes it overtakes are not
//! sent again after it (a drive's run command sent again after the stop would start the
//! motor again): they fail with their last attempt's error.
//!
//! A write made on the thread of an earlier one (a signal handler's, run between that
//! one's attempts) does not wait for it: it would wait for itself.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread::{self, ThreadId};
use std::time::Duration;

/// How often a write held behind an earlier one to its unit looks again (waiting without a
/// turn, so the line serves the others meanwhile).
pub(crate) const POLL: Duration = Duration::from_millis(1);

/// The writes of a Bus: those in progress, and the calls that overrule them.
#[derive(Default)]
pub(crate) struct Writes(Mutex<Book>);

#[derive(Default)]
struct Book {
    /// The write calls in progress: their unit, call number and thread.
    writing: Vec<(u8, u64, ThreadId)>,
    /// The last urgent write to each unit, by call number.
    urgent: HashMap<u8, u64>,
    /// The last broadcast, by call number.
    broadcast: Option<u64>,
}

/// A write call in progress, recorded until dropped.
pub(crate) struct Writing<'a> {
    writes: &'a Writes,
    unit: u8,
    call: u64,
}

impl Writes {
    /// Numbers a write call to `unit` from `calls` and records it, both at once, so that the
    /// numbers of one unit's writes are the order they were made in.
    pub(crate) fn enter<'a>(&'a self, unit: u8, calls: &AtomicU64) -> Writing<'a> {
        let mut book = self.lock();
        let call = calls.fetch_add(1, Ordering::Relaxed);
        book.writing.push((unit, call, thread::current().id()));
        Writing {
            writes: self,
            unit,
            call,
        }
    }

    /// Numbers an urgent write to `unit` (None: a broadcast) from `calls` and records it:
    /// the writes made before it are not sent again from now on.
    pub(crate) fn overrule(&self, unit: Option<u8>, calls: &AtomicU64) -> u64 {
        let mut book = self.lock();
        let call = calls.fetch_add(1, Ordering::Relaxed);
        match unit {
            Some(unit) => {
                book.urgent.insert(unit, call);
            }
            None => book.broadcast = Some(call),
        }
        call
    }

    /// Whether a write to `unit` made before `call`, on another thread, is still in
    /// progress.
    pub(crate) fn behind(&self, unit: u8, call: u64) -> bool {
        let me = thread::current().id();
        self.lock()
            .writing
            .iter()
            .any(|&(u, c, t)| u == unit && c < call && t != me)
    }

    /// Whether an urgent write to the unit of `writing`, or a broadcast, was made after it.
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

    #[test]
    fn a_write_waits_only_for_earlier_writes_to_its_unit_from_other_threads() {
        let (writes, calls) = (Writes::default(), AtomicU64::new(7));
        let first = writes.enter(1, &calls);
        let other_unit = writes.enter(2, &calls);
        // On this thread, a later write does not wait for the earlier one.
        let later = writes.enter(1, &calls);
        assert!(first.call() < later.call());
        assert!(!writes.behind(1, later.call()));
        // On another, it does, until the earlier ones are over.
        let elsewhere = |writes: &Writes, call: u64| {
            thread::scope(|s| s.spawn(|| writes.behind(1, call)).join().unwrap_or(false))
        };
        assert!(elsewhere(&writes, later.call()));
        assert!(!elsewhere(&writes, first.call()));
        drop(first);
        assert!(elsewhere(&writes, later.call() + 1));
        drop(later);
        assert!(!elsewhere(&writes, u64::MAX));
        assert!(!writes.behind(2, other_unit.call()));
        drop(other_unit);
        assert!(writes.lock().writing.is_empty());
    }

    #[test]
    fn an_urgent_write_or_a_broadcast_overrules_only_the_writes_made_before_it() {
        let (writes, calls) = (Writes::default(), AtomicU64::new(0));
        let (one, two) = (writes.enter(1, &calls), writes.enter(2, &calls));
        writes.overrule(Some(1), &calls);
        let after = writes.enter(1, &calls);
        assert!(writes.overruled(&one));
        assert!(!writes.overruled(&two) && !writes.overruled(&after));
        writes.overrule(None, &calls);
        assert!(writes.overruled(&two) && writes.overruled(&after));
    }
}
