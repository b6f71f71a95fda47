//! A Bus belongs to the process that opened it.
//!
//! A child made by `fork()` (Python's `multiprocessing` with its fork start method, a
//! forking server) gets a copy of every Bus of its parent, and of its port's descriptor: two
//! processes would then write on one line and read each other's replies. Worse, a lock that
//! a thread of the parent held at the fork (a call in progress holds the line's) stays held
//! in the child for ever, as that thread does not exist there, so a call that waited for it
//! would never return.
//!
//! So every entry point that would touch the line or its locks asks [`Bus::owned`] first,
//! before anything else: in another process it fails at once with [`Error::Forked`], and
//! nothing is locked, sent or read. Closing or dropping the Bus there sends nothing and
//! leaves the parent's port as it is: the transport is let go of with
//! [`Transport::abandon`](crate::transport::Transport::abandon), never dropped (a serial
//! port's drop clears the exclusive mode the copies share; only this process's copy of the
//! descriptor is closed).

use super::{Bus, Link, State};
use crate::error::{Error, Result};
use std::sync::{PoisonError, TryLockError};

impl Bus {
    /// Whether this process may use the Bus: the one that opened it.
    ///
    /// # Errors
    /// [`Error::Forked`] in any other process (a child made by `fork()`), saying what to do.
    pub fn owned(&self) -> Result<()> {
        let here = std::process::id();
        if here == self.owner {
            return Ok(());
        }
        Err(Error::Forked {
            port: self.config.port.clone(),
            owner: self.owner,
            here,
        })
    }

    /// In a process other than the owner: lets go of this process's copy of the port, if no
    /// thread of the parent held the line at the fork (else the state is left as it is,
    /// to [`Drop`]). Never waits.
    pub(super) fn let_go(&self) {
        let mut st = match self.state.try_lock() {
            Ok(st) => st,
            Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner(),
            Err(TryLockError::WouldBlock) => return,
        };
        abandon_link(&mut st);
    }
}

/// Takes the port out of `st` and lets go of it, without its drop.
fn abandon_link(st: &mut State) {
    if let Link::Open(framed) = std::mem::replace(&mut st.link, Link::Closed) {
        framed.abandon();
    }
}

impl Drop for Bus {
    /// In the process that opened it, the port closes as its transport drops. In another,
    /// the transport is let go of, as [`Bus::close`] does there, without taking any lock.
    fn drop(&mut self) {
        if self.owned().is_err() {
            let st = self.state.get_mut().unwrap_or_else(PoisonError::into_inner);
            abandon_link(st);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::queue::Cancel;
    use crate::bus::{BusConfig, TxOptions};
    use crate::codec::Request;
    use crate::timing::{LineFormat, Parity};
    use crate::transport::Transport;
    use std::io;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{mpsc, Arc};
    use std::time::Duration;

    /// What happened to a [`Probe`] transport.
    #[derive(Default)]
    struct Seen {
        writes: AtomicUsize,
        reads: AtomicUsize,
        dropped: AtomicUsize,
        abandoned: AtomicUsize,
    }

    /// A transport that answers every read of one register with 0x1234 and counts what is
    /// done to it.
    struct Probe {
        seen: Arc<Seen>,
        reply: Vec<u8>,
    }

    impl Transport for Probe {
        fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
            self.seen.writes.fetch_add(1, Ordering::SeqCst);
            let mut reply = vec![frame[0], 0x03, 2, 0x12, 0x34];
            let crc = crate::codec::rtu::crc16(&reply);
            reply.extend_from_slice(&crc.to_le_bytes());
            self.reply = reply;
            Ok(())
        }

        fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
            self.seen.reads.fetch_add(1, Ordering::SeqCst);
            let n = buf.len().min(self.reply.len());
            buf[..n].copy_from_slice(&self.reply[..n]);
            self.reply.drain(..n);
            Ok(n)
        }

        fn discard_input(&mut self) -> io::Result<Vec<u8>> {
            Ok(Vec::new())
        }

        fn abandon(self: Box<Self>) {
            self.seen.abandoned.fetch_add(1, Ordering::SeqCst);
            std::mem::forget(self);
        }
    }

    impl Drop for Probe {
        fn drop(&mut self) {
            self.seen.dropped.fetch_add(1, Ordering::SeqCst);
        }
    }

    fn probed_bus() -> (Bus, Arc<Seen>) {
        let seen = Arc::new(Seen::default());
        let probe = Probe {
            seen: Arc::clone(&seen),
            reply: Vec::new(),
        };
        let config =
            BusConfig::new("/dev/fake", LineFormat::new(115_200, Parity::None, 1)).unwrap();
        (Bus::with_transport(config, Box::new(probe)), seen)
    }

    /// The Bus as a child made by fork sees it: opened by another process.
    fn forked(mut bus: Bus) -> Bus {
        bus.owner = std::process::id().wrapping_add(1);
        bus
    }

    fn read(bus: &Bus) -> Result<Vec<u16>> {
        bus.read_holding_registers(1, 0, 1, &TxOptions::default())
    }

    #[test]
    fn the_process_that_opened_the_bus_uses_it_and_its_drop_closes_the_port() {
        let (bus, seen) = probed_bus();
        assert!(bus.owned().is_ok());
        assert_eq!(read(&bus).ok(), Some(vec![0x1234]));
        drop(bus);
        assert_eq!(seen.dropped.load(Ordering::SeqCst), 1);
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 0);
    }

    #[test]
    fn every_entry_point_fails_at_once_in_another_process_and_sends_nothing() {
        let (bus, seen) = probed_bus();
        let bus = forked(bus);
        let here = std::process::id();
        let message = match bus.owned() {
            Err(e @ Error::Forked { .. }) => e.to_string(),
            other => panic!("expected Error::Forked, got {other:?}"),
        };
        assert!(message.contains("fork()"), "{message}");
        assert!(
            message.contains(&format!("process {here} got it")),
            "{message}"
        );
        assert!(message.contains("open a new Bus"), "{message}");
        assert!(message.contains("'spawn' or 'forkserver'"), "{message}");
        assert!(message.contains("gateway"), "{message}");
        assert!(matches!(read(&bus), Err(Error::Forked { .. })));
        assert!(matches!(
            bus.broadcast(&Request::WriteSingleRegister {
                address: 0,
                value: 1
            }),
            Err(Error::Forked { .. })
        ));
        assert!(matches!(
            bus.probe(1, 0, Duration::from_millis(10)),
            Err(Error::Forked { .. })
        ));
        assert!(matches!(bus.reopen(), Err(Error::Forked { .. })));
        let request = Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        };
        assert!(matches!(
            bus.transact(1, &request, &TxOptions::default()),
            Err(Error::Forked { .. })
        ));
        // A device's sequence runs, and its requests fail.
        assert!(matches!(
            bus.exclusive(1, || read(&bus)),
            Err(Error::Forked { .. })
        ));
        // A closed bus's error is the fork's too.
        assert!(matches!(bus.closed(), Error::Forked { .. }));
        assert!(bus.is_closed());
        assert!(!bus.is_lost());
        assert_eq!(bus.stats(), crate::bus::Stats::default());
        assert_eq!(seen.writes.load(Ordering::SeqCst), 0);
        assert_eq!(seen.reads.load(Ordering::SeqCst), 0);
    }

    #[test]
    fn close_and_drop_in_another_process_let_go_of_the_port_without_its_drop() {
        let (bus, seen) = probed_bus();
        assert_eq!(read(&bus).ok(), Some(vec![0x1234]));
        let writes = seen.writes.load(Ordering::SeqCst);
        let bus = forked(bus);
        bus.close();
        bus.close();
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 1);
        drop(bus);
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 1);
        assert_eq!(seen.dropped.load(Ordering::SeqCst), 0);
        assert_eq!(seen.writes.load(Ordering::SeqCst), writes);

        let (bus, seen) = probed_bus();
        drop(forked(bus));
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 1);
        assert_eq!(seen.dropped.load(Ordering::SeqCst), 0);
    }

    /// Runs `f` in a thread of its own and gives its result, or None if it has not
    /// returned within two seconds (it waits for a lock, and would for ever).
    fn within_bound<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> Option<T> {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || tx.send(f()).ok());
        rx.recv_timeout(Duration::from_secs(2)).ok()
    }

    /// A thread of the parent held the line (its state, its turn) and a unit's sequence lock
    /// at the fork, and is gone: in the child nothing waits for them, and the port is still
    /// let go of when the Bus is dropped.
    #[test]
    fn nothing_waits_for_a_lock_held_at_the_fork() {
        let (bus, seen) = probed_bus();
        let bus = Arc::new(forked(bus));
        let holder = Arc::clone(&bus);
        std::thread::spawn(move || {
            let sequence = Arc::clone(holder.sequences.lock().unwrap().entry(1).or_default());
            std::mem::forget(sequence.lock.lock());
            std::mem::forget(holder.queue.turn(&Cancel::default()));
            std::mem::forget(holder.lock());
        })
        .join()
        .unwrap();
        assert!(bus.state.try_lock().is_err(), "the state is held");

        let b = Arc::clone(&bus);
        let outcome = within_bound(move || {
            [
                read(&b).err(),
                b.broadcast(&Request::WriteSingleRegister {
                    address: 0,
                    value: 1,
                })
                .err(),
                b.probe(1, 0, Duration::from_millis(10)).err(),
                b.reopen().err(),
                b.exclusive(1, || read(&b)).err(),
            ]
        });
        let errors = outcome.expect("a call waited for a lock held at the fork");
        for error in errors {
            assert!(matches!(error, Some(Error::Forked { .. })), "{error:?}");
        }
        let b = Arc::clone(&bus);
        let looks = within_bound(move || {
            b.close();
            (b.is_closed(), b.is_lost(), b.stats())
        });
        assert_eq!(looks, Some((true, false, crate::bus::Stats::default())));
        // close() could not take the state: the port is let go of when the Bus is dropped.
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 0);
        drop(bus);
        assert_eq!(seen.abandoned.load(Ordering::SeqCst), 1);
        assert_eq!(seen.dropped.load(Ordering::SeqCst), 0);
        assert_eq!(seen.writes.load(Ordering::SeqCst), 0);
    }
}
