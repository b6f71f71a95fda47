//! The replies a line still owes: a request whose attempt timed out may be answered later
//! all the same (a slow device, or one that queues its master's retries and answers each).
//!
//! A call that sent k requests to a unit and got one reply leaves k - 1 answers owed by that
//! unit. Each is waited for up to its window (three timeouts) after the frame before it: the
//! request, or the owed answer before it. Until the unit has paid them, or the window has
//! passed with nothing, no reply of the unit to another call is trusted (see
//! [`super::Bus::send`]); a frame of the unit that comes while another unit is asked is
//! dropped as one of them (see [`super::Bus::attempt`]).
//!
//! Pure bookkeeping: it is told what happened and when, and never reads a clock.

use crate::codec::{Request, BROADCAST};
use std::time::{Duration, Instant};

/// What a unit still owes the line.
#[derive(Debug, Clone)]
pub(super) struct Owed {
    pub(super) unit: u8,
    /// The last request that was not answered: what an owed frame answers (for its length).
    pub(super) request: Request,
    /// How many answers are still owed.
    pub(super) count: u32,
    /// Until when the next of them may come.
    pub(super) until: Instant,
    /// How long each may take after the frame before it.
    pub(super) window: Duration,
    /// The call that sent the requests: its own attempts do not wait for them (any of
    /// them answers the same request).
    pub(super) call: u64,
}

/// Every unit's owed replies, one entry a unit.
#[derive(Debug, Default)]
pub(super) struct Ledger {
    owed: Vec<Owed>,
}

impl Ledger {
    /// Records that an attempt of `call` to `unit` of `request` got no reply by `now`, so an
    /// answer to it is owed, within `window` of the frame before it.
    pub(super) fn owe(
        &mut self,
        unit: u8,
        request: &Request,
        call: u64,
        window: Duration,
        now: Instant,
    ) {
        match self.owed.iter_mut().find(|o| o.unit == unit) {
            Some(o) => {
                o.count = o.count.saturating_add(1);
                o.request = request.clone();
                o.until = o.until.max(now + window);
                o.window = o.window.max(window);
                o.call = call;
            }
            None => self.owed.push(Owed {
                unit,
                request: request.clone(),
                count: 1,
                until: now + window,
                window,
                call,
            }),
        }
    }

    /// Records that a frame of `unit` ended at `at`: one of its owed answers if `owed` (the
    /// count goes down), else its answer to the call being served; either way the next owed
    /// answer may come within the window after it.
    pub(super) fn frame_from(&mut self, unit: u8, at: Instant, owed: bool) {
        if let Some(o) = self.owed.iter_mut().find(|o| o.unit == unit) {
            if owed {
                o.count = o.count.saturating_sub(1);
            }
            o.until = o.until.max(at + o.window);
        }
        self.owed.retain(|o| o.count > 0);
    }

    /// Until when an answer owed by `target` (a broadcast: by any unit) to another call than
    /// `call` may still come, if one may.
    pub(super) fn until(&self, target: u8, call: u64, now: Instant) -> Option<Instant> {
        self.owed
            .iter()
            .filter(|o| (target == BROADCAST || o.unit == target) && o.call != call)
            .map(|o| o.until)
            .filter(|&until| until > now)
            .max()
    }

    /// Until when any answer owed to another call than `call` may still come (a Modbus TCP
    /// gateway that serves one request at a time answers those first).
    pub(super) fn until_any(&self, call: u64) -> Option<Instant> {
        self.owed
            .iter()
            .filter(|o| o.call != call)
            .map(|o| o.until)
            .max()
    }

    /// What `target` (a broadcast: every unit) owes to other calls than `call`, taken out of
    /// the ledger to be drained before a request goes out, windows passed or not: an answer
    /// that came while nobody listened is waiting in the input.
    pub(super) fn take(&mut self, target: u8, call: u64) -> Vec<Owed> {
        let (taken, kept) = std::mem::take(&mut self.owed)
            .into_iter()
            .partition(|o| (target == BROADCAST || o.unit == target) && o.call != call);
        self.owed = kept;
        taken
    }

    /// The owed answers of another unit than `unit` that a frame from `first` may be.
    pub(super) fn of_other_unit(&self, unit: u8, first: Option<u8>) -> Option<&Owed> {
        let first = first?;
        self.owed.iter().find(|o| o.unit == first && o.unit != unit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read() -> Request {
        Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        }
    }

    #[test]
    fn each_owed_answer_has_its_window_after_the_frame_before_it() {
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut l = Ledger::default();
        // A call (7) that timed out twice, then got its answer at 130 ms.
        l.owe(1, &read(), 7, ms(150), t0 + ms(50));
        l.owe(1, &read(), 7, ms(150), t0 + ms(100));
        l.frame_from(1, t0 + ms(130), false);
        assert_eq!(l.until(1, 8, t0 + ms(131)), Some(t0 + ms(280)));
        // The call's own attempts do not wait; other units do not wait.
        assert_eq!(l.until(1, 7, t0 + ms(131)), None);
        assert_eq!(l.until(2, 8, t0 + ms(131)), None);
        assert_eq!(l.until(BROADCAST, 8, t0 + ms(131)), Some(t0 + ms(280)));
        // The first owed answer comes at 255 ms: the next may come until 405 ms.
        l.frame_from(1, t0 + ms(255), true);
        assert_eq!(l.until(1, 8, t0 + ms(256)), Some(t0 + ms(405)));
        // The last: nothing is owed any more.
        l.frame_from(1, t0 + ms(380), true);
        assert_eq!(l.until(1, 8, t0 + ms(381)), None);
        assert!(l.take(1, 8).is_empty());
    }

    #[test]
    fn taking_a_units_debts_leaves_the_others_and_forgets_the_past() {
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut l = Ledger::default();
        l.owe(1, &read(), 1, ms(300), t0);
        l.owe(2, &read(), 2, ms(300), t0);
        l.owe(3, &read(), 3, ms(10), t0);
        assert_eq!(l.of_other_unit(2, Some(1)).map(|o| o.unit), Some(1));
        assert!(l.of_other_unit(1, Some(1)).is_none());
        assert!(l.of_other_unit(1, None).is_none());
        let taken = l.take(1, 9);
        assert_eq!(taken.iter().map(|o| o.unit).collect::<Vec<_>>(), [1]);
        // Unit 3's window is over, not its debt: an answer may be waiting in the input.
        assert_eq!(l.until(3, 9, t0 + ms(20)), None);
        assert_eq!(l.until_any(9), Some(t0 + ms(300)));
        let all = l.take(BROADCAST, 9);
        assert_eq!(all.iter().map(|o| o.unit).collect::<Vec<_>>(), [2, 3]);
    }
}
