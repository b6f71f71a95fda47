//! The line's queue: callers take turns on the line in the order they asked for one (FIFO),
//! and a [`CancelToken`] takes a caller out of the queue while it waits.
//!
//! A turn is one attempt on the wire. A call that must try again takes a new turn at the
//! back of the queue, so nobody waits behind more than one attempt of another call.

use crate::timing::sleep_until;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, Weak};
use std::time::Instant;

/// Turns on one line, served in the order they were asked for.
#[derive(Default)]
pub(crate) struct Queue {
    tickets: Mutex<Tickets>,
    /// Signalled when the front of the queue changes or a token waiting here is cancelled.
    moved: Condvar,
}

#[derive(Default)]
struct Tickets {
    next: u64,
    /// Tickets in the order they were taken; the first holds the line.
    waiting: VecDeque<u64>,
}

/// The line, held until dropped; the next ticket's holder goes on then.
pub(crate) struct Turn<'a> {
    queue: &'a Queue,
    ticket: u64,
}

impl Queue {
    /// Takes a ticket at the back of the queue and waits until it is at the front: the
    /// caller's turn. None if one of `cancel`'s tokens is cancelled first: the ticket is
    /// withdrawn, and the line was not touched.
    pub(crate) fn turn<'a>(self: &'a Arc<Self>, cancel: &Cancel) -> Option<Turn<'a>> {
        let _watch = cancel.watch(self);
        let mut tickets = self.lock();
        let ticket = tickets.next;
        tickets.next += 1;
        tickets.waiting.push_back(ticket);
        cancel.queued();
        loop {
            if cancel.is_cancelled() {
                tickets.waiting.retain(|&t| t != ticket);
                drop(tickets);
                // The front may have been this ticket: the next one goes on.
                self.moved.notify_all();
                return None;
            }
            if tickets.waiting.front() == Some(&ticket) {
                return Some(Turn {
                    queue: self,
                    ticket,
                });
            }
            tickets = self
                .moved
                .wait(tickets)
                .unwrap_or_else(|poisoned| poisoned.into_inner());
        }
    }

    /// Waits, without a turn, until `at`; false if one of `cancel`'s tokens is cancelled
    /// first.
    pub(crate) fn wait_until(self: &Arc<Self>, at: Instant, cancel: &Cancel) -> bool {
        if cancel.0.is_empty() {
            sleep_until(at);
            return true;
        }
        let _watch = cancel.watch(self);
        let mut tickets = self.lock();
        loop {
            if cancel.is_cancelled() {
                return false;
            }
            let now = Instant::now();
            if now >= at {
                return true;
            }
            tickets = self
                .moved
                .wait_timeout(tickets, at - now)
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }

    /// Wakes every waiter, to look at its tokens again.
    fn wake(&self) {
        // Taken and let go: a waiter that saw its token not cancelled is waiting by now.
        drop(self.lock());
        self.moved.notify_all();
    }

    fn lock(&self) -> MutexGuard<'_, Tickets> {
        self.tickets
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        let mut tickets = self.queue.lock();
        tickets.waiting.retain(|&t| t != self.ticket);
        drop(tickets);
        self.queue.moved.notify_all();
    }
}

/// Cancels the calls made under it: [`CancelToken::enter`] puts it in force for the calls
/// the current thread makes until the guard is dropped, and [`CancelToken::cancel`] (from
/// any thread) stops them.
///
/// A call waiting for its turn on the line leaves the queue without touching the line. An
/// attempt in flight finishes as usual (a reply is read, or its timeout runs out, and a late
/// reply is listened for as after any timeout), so the line stays in step; then the call
/// starts nothing more (no retry, no further request of a call made of several) and fails
/// with [`crate::Error::Cancelled`]. An attempt that ends the call (a reply, an exception)
/// stands: its result is returned. A cancelled token stays cancelled: every call made under
/// it fails at once. (A device's sequence waiting for another sequence on the same unit,
/// see [`crate::Bus::exclusive`], is not woken: its first request fails once it runs.)
#[derive(Clone, Default)]
pub struct CancelToken(Arc<TokenState>);

#[derive(Default)]
struct TokenState {
    cancelled: AtomicBool,
    /// Whether a call under this token has taken a ticket in a line's queue.
    queued: AtomicBool,
    /// The queues where calls under this token wait, to wake them when it is cancelled.
    watchers: Mutex<Vec<Weak<Queue>>>,
}

impl CancelToken {
    /// A token not cancelled.
    pub fn new() -> CancelToken {
        CancelToken::default()
    }

    /// Cancels the calls made under this token, now and later. Any thread may call it.
    pub fn cancel(&self) {
        self.0.cancelled.store(true, Ordering::SeqCst);
        let watchers = self.watchers().clone();
        for queue in watchers.iter().filter_map(Weak::upgrade) {
            queue.wake();
        }
    }

    /// Whether [`CancelToken::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.cancelled.load(Ordering::SeqCst)
    }

    /// Whether a call made under this token has taken its place in a line's queue (its
    /// first turn asked for, or, for a write waiting for the earlier writes to its unit,
    /// its place among them): a caller that hands calls to several threads can let the
    /// next one go only then, so that they reach the line in the order they were made.
    pub fn has_queued(&self) -> bool {
        self.0.queued.load(Ordering::SeqCst)
    }

    /// Puts the token in force for the calls this thread makes until the guard is dropped
    /// (guards nest: a call stops if any token in force is cancelled).
    pub fn enter(&self) -> Entered {
        SCOPE.with(|scope| scope.borrow_mut().push(self.clone()));
        Entered {
            token: self.clone(),
            _this_thread: PhantomData,
        }
    }

    fn watchers(&self) -> MutexGuard<'_, Vec<Weak<Queue>>> {
        self.0
            .watchers
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl PartialEq for CancelToken {
    /// The same token (clones of one token are equal).
    fn eq(&self, other: &CancelToken) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for CancelToken {}

impl std::fmt::Debug for CancelToken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CancelToken")
            .field("cancelled", &self.is_cancelled())
            .finish()
    }
}

thread_local! {
    /// The tokens in force for the calls this thread makes (see [`CancelToken::enter`]).
    static SCOPE: RefCell<Vec<CancelToken>> = const { RefCell::new(Vec::new()) };
}

/// A token in force in this thread until dropped (see [`CancelToken::enter`]).
#[must_use = "the token is in force only until this guard is dropped"]
pub struct Entered {
    token: CancelToken,
    /// The guard belongs to the thread whose scope it changed.
    _this_thread: PhantomData<*const ()>,
}

impl Entered {
    /// The token this guard put in force.
    pub fn token(&self) -> &CancelToken {
        &self.token
    }
}

impl Drop for Entered {
    fn drop(&mut self) {
        SCOPE.with(|scope| {
            let mut scope = scope.borrow_mut();
            if let Some(at) = scope.iter().rposition(|t| *t == self.token) {
                scope.remove(at);
            }
        });
    }
}

/// The tokens in force in this thread when a call started: what the call honours.
#[derive(Default)]
pub(crate) struct Cancel(Vec<CancelToken>);

impl Cancel {
    /// This thread's tokens in force.
    pub(crate) fn current() -> Cancel {
        Cancel(SCOPE.with(|scope| scope.borrow().clone()))
    }

    /// Marks the tokens: a call under them has taken a ticket, or its place among the
    /// writes to its unit (see [`super::writes`]), which it waits for without a ticket.
    pub(super) fn queued(&self) {
        for token in &self.0 {
            token.0.queued.store(true, Ordering::SeqCst);
        }
    }

    /// Whether any of the tokens was cancelled.
    pub(crate) fn is_cancelled(&self) -> bool {
        self.0.iter().any(CancelToken::is_cancelled)
    }

    /// Asks the tokens to wake `queue`'s waiters when cancelled, until the guard is dropped.
    fn watch(&self, queue: &Arc<Queue>) -> Watch<'_> {
        for token in &self.0 {
            token.watchers().push(Arc::downgrade(queue));
        }
        Watch {
            cancel: self,
            queue: Arc::downgrade(queue),
        }
    }
}

/// The queue a call's tokens wake while it waits there.
struct Watch<'a> {
    cancel: &'a Cancel,
    queue: Weak<Queue>,
}

impl Drop for Watch<'_> {
    fn drop(&mut self) {
        for token in &self.cancel.0 {
            let mut watchers = token.watchers();
            if let Some(at) = watchers.iter().position(|q| q.ptr_eq(&self.queue)) {
                watchers.swap_remove(at);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::thread;
    use std::time::Duration;

    /// Starts a thread that waits for a turn under `cancel`'s tokens, holds it for `hold`
    /// and reports `id` when served (or `None`-like 0 when cancelled).
    fn waiter(
        queue: &Arc<Queue>,
        id: u32,
        tokens: Vec<CancelToken>,
        hold: Duration,
        served: &mpsc::Sender<Option<u32>>,
    ) -> thread::JoinHandle<()> {
        let queue = Arc::clone(queue);
        let served = served.clone();
        thread::spawn(move || {
            let _in: Vec<Entered> = tokens.iter().map(CancelToken::enter).collect();
            let turn = queue.turn(&Cancel::current());
            served.send(turn.as_ref().map(|_| id)).unwrap();
            thread::sleep(hold);
            drop(turn);
        })
    }

    /// Waits until `n` tickets are in the queue.
    fn queued(queue: &Queue, n: usize) {
        let until = Instant::now() + Duration::from_secs(5);
        while queue.lock().waiting.len() < n {
            assert!(Instant::now() < until, "the queue never reached {n}");
            thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn turns_are_served_in_the_order_they_were_asked_for() {
        let queue = Arc::new(Queue::default());
        let (tx, rx) = mpsc::channel();
        let first = queue.turn(&Cancel::default()).unwrap();
        let mut threads = Vec::new();
        for id in 1..=5 {
            threads.push(waiter(&queue, id, vec![], Duration::ZERO, &tx));
            // Each has its ticket before the next asks.
            queued(&queue, id as usize + 1);
        }
        drop(first);
        let order: Vec<_> = (0..5).map(|_| rx.recv().unwrap()).collect();
        assert_eq!(order, (1..=5).map(Some).collect::<Vec<_>>());
        for t in threads {
            t.join().unwrap();
        }
        assert!(queue.lock().waiting.is_empty());
    }

    #[test]
    fn a_cancelled_waiter_leaves_the_queue_at_once_and_the_rest_keep_their_order() {
        let queue = Arc::new(Queue::default());
        let (tx, rx) = mpsc::channel();
        let first = queue.turn(&Cancel::default()).unwrap();
        let token = CancelToken::new();
        let a = waiter(&queue, 1, vec![], Duration::ZERO, &tx);
        queued(&queue, 2);
        let b = waiter(&queue, 2, vec![token.clone()], Duration::ZERO, &tx);
        queued(&queue, 3);
        let c = waiter(&queue, 3, vec![], Duration::ZERO, &tx);
        queued(&queue, 4);
        token.cancel();
        // Out while the line is still held by the first turn.
        assert_eq!(rx.recv_timeout(Duration::from_secs(5)).unwrap(), None);
        assert_eq!(queue.lock().waiting.len(), 3);
        assert!(token.0.watchers.lock().unwrap().is_empty());
        drop(first);
        assert_eq!(rx.recv().unwrap(), Some(1));
        assert_eq!(rx.recv().unwrap(), Some(3));
        for t in [a, b, c] {
            t.join().unwrap();
        }
        assert!(queue.lock().waiting.is_empty());
    }

    #[test]
    fn a_cancelled_token_gets_no_turn_even_on_a_free_line() {
        let queue = Arc::new(Queue::default());
        let token = CancelToken::new();
        token.cancel();
        let _in = token.enter();
        assert!(queue.turn(&Cancel::current()).is_none());
        assert!(queue.lock().waiting.is_empty());
        assert!(!queue.wait_until(Instant::now() + Duration::from_secs(5), &Cancel::current()));
    }

    #[test]
    fn a_cancel_ends_a_wait_without_a_turn() {
        let queue = Arc::new(Queue::default());
        let token = CancelToken::new();
        let waiting = {
            let (queue, token) = (Arc::clone(&queue), token.clone());
            thread::spawn(move || {
                let _in = token.enter();
                let start = Instant::now();
                let done = queue.wait_until(start + Duration::from_secs(10), &Cancel::current());
                (done, start.elapsed())
            })
        };
        thread::sleep(Duration::from_millis(20));
        token.cancel();
        let (done, took) = waiting.join().unwrap();
        assert!(!done);
        assert!(took < Duration::from_secs(5), "{took:?}");
        // Without a token it waits the time out.
        let start = Instant::now();
        assert!(queue.wait_until(start + Duration::from_millis(20), &Cancel::default()));
        assert!(start.elapsed() >= Duration::from_millis(20));
    }

    #[test]
    fn tokens_are_in_force_in_their_thread_until_their_guard_goes() {
        let (outer, inner) = (CancelToken::new(), CancelToken::new());
        assert!(Cancel::current().0.is_empty());
        {
            let _o = outer.enter();
            {
                let _i = inner.enter();
                assert_eq!(Cancel::current().0, vec![outer.clone(), inner.clone()]);
                inner.cancel();
                assert!(Cancel::current().is_cancelled());
                // Another thread has no token in force.
                assert!(thread::spawn(|| Cancel::current().0.is_empty())
                    .join()
                    .unwrap());
            }
            assert_eq!(Cancel::current().0, vec![outer.clone()]);
            assert!(!Cancel::current().is_cancelled());
        }
        assert!(Cancel::current().0.is_empty());
        assert!(inner.is_cancelled() && !outer.is_cancelled());
        assert_eq!(inner.clone(), inner);
        assert_ne!(inner, outer);
    }
}
