//! Line format to wire timing: character time, t1.5 and t3.5 (Modbus over Serial Line V1.02,
//! 2.5.1.1: above 19200 baud fixed values of 750 us and 1.750 ms are used); precise sleeps to
//! a monotonic deadline ([`sleep_until`]); the line's silence before a frame
//! ([`SilenceGuard`]), the per-unit pacing of writes ([`WritePacing`]) and each unit's recent
//! turnaround ([`Turnarounds`]); the absolute deadlines of a polling loop ([`Schedule`]).

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

/// Parity of the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

impl Parity {
    /// The letter used in line formats like "8E1".
    pub fn letter(self) -> char {
        match self {
            Parity::None => 'N',
            Parity::Even => 'E',
            Parity::Odd => 'O',
        }
    }

    /// Parses "N", "E" or "O" (any case).
    pub fn from_letter(s: &str) -> Option<Parity> {
        match s.to_ascii_uppercase().as_str() {
            "N" => Some(Parity::None),
            "E" => Some(Parity::Even),
            "O" => Some(Parity::Odd),
            _ => None,
        }
    }
}

/// Baud rates above this use the fixed t1.5 / t3.5 of the serial line spec.
const FIXED_TIMING_ABOVE: u32 = 19_200;

/// A serial line format: baud rate, data bits, parity and stop bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineFormat {
    /// Bits per second.
    pub baudrate: u32,
    /// Data bits per character (Modbus RTU: 8).
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits, 1 or 2.
    pub stop_bits: u8,
}

impl LineFormat {
    /// A line format with 8 data bits.
    pub fn new(baudrate: u32, parity: Parity, stop_bits: u8) -> LineFormat {
        LineFormat {
            baudrate,
            data_bits: 8,
            parity,
            stop_bits,
        }
    }

    /// The line format of Modbus ASCII (serial line spec 2.5.2): 7 data bits, and with
    /// `parity` 1 stop bit, without it 2 (7N1 is not allowed). The spec's default is 7E1,
    /// `LineFormat::ascii(baudrate, Parity::Even)`.
    pub fn ascii(baudrate: u32, parity: Parity) -> LineFormat {
        LineFormat {
            baudrate,
            data_bits: crate::codec::ascii::DATA_BITS,
            parity,
            stop_bits: if parity == Parity::None { 2 } else { 1 },
        }
    }

    /// Whether this line format may carry Modbus ASCII: 7 or 8 data bits, and 7 bits
    /// without parity need 2 stop bits (serial line spec 2.5.2: 7N1 is not allowed).
    ///
    /// # Errors
    /// What is wrong, in words for the user.
    pub fn check_ascii(&self) -> Result<(), String> {
        match (self.data_bits, self.parity, self.stop_bits) {
            (7, Parity::None, 1) => Err(
                "Modbus ASCII with 7 data bits and no parity needs 2 stop bits (7N2; 7N1 is \
                 not allowed)"
                    .into(),
            ),
            (7 | 8, _, _) => Ok(()),
            (bits, _, _) => Err(format!("Modbus ASCII takes 7 or 8 data bits, not {bits}")),
        }
    }

    /// Bits on the wire per character: start + data + parity + stop.
    pub fn bits_per_char(&self) -> u32 {
        let parity = u32::from(self.parity != Parity::None);
        1 + u32::from(self.data_bits) + parity + u32::from(self.stop_bits)
    }

    /// Time one character takes on the wire.
    pub fn char_time(&self) -> Duration {
        self.chars(1.0)
    }

    /// Time `n` characters take on the wire.
    pub fn frame_time(&self, n: usize) -> Duration {
        self.chars(n as f64)
    }

    /// When the first of `n` characters read together at `read` crossed the wire, at the
    /// latest: each crossed a character time after the one before, so the first was there
    /// `n - 1` character times before the read at least (a master slow to read, or an
    /// adapter that hands bytes over in bursts, still sees when a frame began).
    pub fn first_of(&self, n: usize, read: Instant) -> Instant {
        let behind = self.frame_time(n.saturating_sub(1));
        read.checked_sub(behind).unwrap_or(read)
    }

    /// Longest gap allowed inside a frame.
    pub fn t1_5(&self) -> Duration {
        self.gap(1.5, Duration::from_micros(750))
    }

    /// Silence that separates frames.
    pub fn t3_5(&self) -> Duration {
        self.gap(3.5, Duration::from_micros(1750))
    }

    /// `n` character times, or `fixed` above [`FIXED_TIMING_ABOVE`] baud.
    fn gap(&self, n: f64, fixed: Duration) -> Duration {
        if self.baudrate > FIXED_TIMING_ABOVE {
            fixed
        } else {
            self.chars(n)
        }
    }

    fn chars(&self, n: f64) -> Duration {
        let baud = f64::from(self.baudrate.max(1));
        Duration::from_secs_f64(n * f64::from(self.bits_per_char()) / baud)
    }
}

impl std::fmt::Display for LineFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {}{}{}",
            self.baudrate,
            self.data_bits,
            self.parity.letter(),
            self.stop_bits
        )
    }
}

/// Keeps the line silent for t3.5 before each send, on the monotonic clock.
#[derive(Debug, Clone, Copy)]
pub struct SilenceGuard {
    quiet_since: Instant,
}

impl Default for SilenceGuard {
    fn default() -> Self {
        SilenceGuard::new()
    }
}

impl SilenceGuard {
    /// A guard whose line has been quiet since now.
    pub fn new() -> SilenceGuard {
        SilenceGuard {
            quiet_since: Instant::now(),
        }
    }

    /// Records that the line carries traffic until `until` (the end of a frame).
    pub fn busy_until(&mut self, until: Instant) {
        self.quiet_since = self.quiet_since.max(until);
    }

    /// Records that a complete reply, the last traffic a transaction puts on the line, ended
    /// at `at`. Unlike [`SilenceGuard::busy_until`] this may move the quiet time earlier: the
    /// request's end is reckoned from its length and the baud rate, and on a line without wire
    /// time (a pseudo-terminal) a reply can arrive before that reckoned end. On a real line
    /// the reply always ends after the request, so both agree.
    pub fn reply_ended(&mut self, at: Instant) {
        self.quiet_since = at;
    }

    /// The earliest instant a frame may start after `silence` of quiet line.
    pub fn ready_at(&self, silence: Duration) -> Instant {
        self.quiet_since + silence
    }

    /// Sleeps until the line has been quiet for `silence`; returns at once if it has.
    pub fn wait(&self, silence: Duration) {
        sleep_until(self.ready_at(silence));
    }
}

/// Per-unit write pacing: the least time between two write requests to the same unit that
/// its device asks for (J2: 150 ms), where a broadcast counts as a write to every unit.
///
/// Pure bookkeeping: it is told when writes ended and answers when the next may go; it never
/// reads a clock or sleeps.
#[derive(Debug, Clone, Default)]
pub struct WritePacing {
    /// When each unit's last write ended, and the longest write interval its device asked
    /// for.
    last_write: HashMap<u8, (Instant, Duration)>,
    /// When the last broadcast's turnaround ended: a write to every unit.
    last_broadcast: Option<Instant>,
}

impl WritePacing {
    /// No write yet: every write may go at once.
    pub fn new() -> WritePacing {
        WritePacing::default()
    }

    /// Records that a write to `unit` (whose device wants `interval` between writes) ended
    /// at `at`.
    pub fn wrote(&mut self, unit: u8, interval: Duration, at: Instant) {
        self.last_write
            .entry(unit)
            .and_modify(|(last, widest)| {
                *last = at;
                *widest = (*widest).max(interval);
            })
            .or_insert((at, interval));
    }

    /// Records that a broadcast (a write to every unit) ended at `at`.
    pub fn broadcast(&mut self, at: Instant) {
        self.last_broadcast = Some(at);
    }

    /// When a write to `unit` may go: `interval` after its last write or the last
    /// broadcast; None if there was neither.
    pub fn write_ready(&self, unit: u8, interval: Duration) -> Option<Instant> {
        let last = self.last_write.get(&unit).map(|&(at, _)| at);
        last.max(self.last_broadcast).map(|at| at + interval)
    }

    /// When a broadcast that wants `interval` between writes to every unit (for units it
    /// may not have seen a write to yet) may go: every unit's own write interval has passed
    /// since its last write, and the widest of them and `interval` since the last
    /// broadcast; None if nothing holds it.
    pub fn broadcast_ready(&self, interval: Duration) -> Option<Instant> {
        let widest = self.last_write.values().map(|&(_, i)| i).max();
        let after_broadcast = self
            .last_broadcast
            .map(|at| at + widest.unwrap_or_default().max(interval));
        self.last_write
            .values()
            .map(|&(at, interval)| at + interval)
            .chain(after_broadcast)
            .max()
    }
}

/// How many of a unit's recent replies its least turnaround is taken over.
const TURNAROUND_SAMPLES: usize = 16;

/// How many replies must be known before a frame is judged: the first replies of a device
/// (or of a simulator's code, cold) may be slower than all that follow.
const TURNAROUND_KNOWN: usize = 4;

/// The least slack a reply may come sooner by than the unit's recent least and still be taken
/// (the slack is half the least turnaround, and at least this): scheduling and an adapter's
/// latency make the arrival of a reply later than on the wire, never earlier, but not always
/// equally late. A desktop system's scheduler, loaded, wakes a waiting thread a millisecond
/// or two late now and then; less than this dropped good replies of a fast device (one that
/// answers at t3.5) on a busy machine.
const TURNAROUND_SLACK_FLOOR: Duration = Duration::from_millis(2);

/// How soon each unit has answered lately, to tell its replies from frames that cannot be
/// one: a copy of an earlier reply, or an earlier request's answer come late. Each function
/// of a unit is timed apart (a device may write its flash slowly and read at once).
///
/// A reply is timed from the request it answers twice: from its start, and from its
/// reckoned end on the wire. Over the last 16 vouched replies of a unit to a function the
/// least of each is kept, once 4 have come. A frame that begins sooner than both, by more
/// than the slack (half the least time from the end, at least 2 ms), is too soon to answer
/// the request: a device does not get much faster from one request to the next, and nothing
/// on the way (an adapter, a scheduler) makes a reply arrive earlier than it was sent.
///
/// A unit that has lately answered before its request's reckoned end is not on a line that
/// keeps the wire's time (a pseudo-terminal to a simulator, which answers at once): its
/// times are its host's scheduling, which a load changes from one request to the next, and
/// nothing of it is judged.
///
/// Pure bookkeeping: it is told when things happened and never reads a clock.
#[derive(Debug, Clone, Default)]
pub struct Turnarounds {
    units: HashMap<(u8, u8), Recent>,
}

/// A unit's recent turnarounds, in nanoseconds, newest last (from the end: may be negative).
#[derive(Debug, Clone, Default)]
struct Recent {
    from_start: VecDeque<i128>,
    from_end: VecDeque<i128>,
}

impl Turnarounds {
    /// Nothing known yet: every frame may be an answer.
    pub fn new() -> Turnarounds {
        Turnarounds::default()
    }

    /// Records that `unit`'s reply to a request of `function` sent from `start` to `end`
    /// (reckoned on the wire) began to arrive at `first`.
    pub fn answered(
        &mut self,
        unit: u8,
        function: u8,
        start: Instant,
        end: Instant,
        first: Instant,
    ) {
        let recent = self.units.entry((unit, function)).or_default();
        for (samples, since) in [(&mut recent.from_start, start), (&mut recent.from_end, end)] {
            if samples.len() == TURNAROUND_SAMPLES {
                samples.pop_front();
            }
            samples.push_back(signed_nanos(since, first));
        }
    }

    /// Whether a frame from `unit` that began to arrive at `first` came too soon to answer a
    /// request of `function` sent from `start` to `end`: sooner than the unit's recent
    /// replies to it by more than the slack, counted from the start and from the end alike.
    /// Never while too little is known.
    pub fn too_soon(
        &self,
        unit: u8,
        function: u8,
        start: Instant,
        end: Instant,
        first: Instant,
    ) -> bool {
        let Some(recent) = self.units.get(&(unit, function)) else {
            return false;
        };
        if recent.from_start.len() < TURNAROUND_KNOWN {
            return false;
        }
        let (Some(&least_start), Some(&least_end)) =
            (recent.from_start.iter().min(), recent.from_end.iter().min())
        else {
            return false;
        };
        if least_end < 0 {
            return false;
        }
        let slack = (least_end / 2).max(TURNAROUND_SLACK_FLOOR.as_nanos() as i128);
        signed_nanos(start, first) < least_start - slack
            && signed_nanos(end, first) < least_end - slack
    }

    /// The least time from the start of a request of `function` to `unit`'s reply lately,
    /// if any is known.
    pub fn least(&self, unit: u8, function: u8) -> Option<Duration> {
        let least = self.units.get(&(unit, function))?.from_start.iter().min()?;
        u64::try_from(*least).ok().map(Duration::from_nanos)
    }

    /// Forgets what is known of `unit`'s replies to `function`: after a frame thought too
    /// soon was followed by no other, the device may have become faster.
    pub fn forget(&mut self, unit: u8, function: u8) {
        self.units.remove(&(unit, function));
    }
}

/// `to - from` in nanoseconds, negative if `to` is earlier.
fn signed_nanos(from: Instant, to: Instant) -> i128 {
    match to.checked_duration_since(from) {
        Some(d) => d.as_nanos() as i128,
        None => -(from.duration_since(to).as_nanos() as i128),
    }
}

/// Sleeps until `deadline` on the monotonic clock; returns at once if it has passed. Never
/// returns before it, and never spins.
///
/// Linux lets a sleeping thread wake up to its timer slack late (50 us by default, see
/// `/proc/self/timerslack_ns`), so a plain sleep of t3.5 (1.75 ms) overshoots by some
/// 50-60 us. For the duration of the sleep the calling thread's slack is lowered to 1 ns, and
/// put back afterwards (also if the sleep unwinds). Elsewhere this is a plain sleep: on
/// Windows, `std::thread::sleep` waits on a high-resolution waitable timer (Windows 10 1803
/// and later), not in the system's 15.6 ms timer ticks.
pub fn sleep_until(deadline: Instant) {
    let now = Instant::now();
    if deadline <= now {
        return;
    }
    #[cfg(target_os = "linux")]
    let _fine = slack::Fine::lower();
    // A long sleep lets the CPU into a deep idle state (on a virtual machine, lets the host
    // deschedule it), and waking from that takes tens of microseconds. So a long wait ends in
    // a short second sleep: the CPU, just woken, idles only lightly and wakes on time.
    if deadline - now > LAST_STAGE * 2 {
        std::thread::sleep(deadline - LAST_STAGE - now);
    }
    let mut now = Instant::now();
    // `thread::sleep` resumes after a signal on its own; the loop only makes "never early"
    // hold whatever the platform's sleep does.
    while now < deadline {
        std::thread::sleep(deadline - now);
        now = Instant::now();
    }
}

/// How long the last stage of a long [`sleep_until`] is.
const LAST_STAGE: Duration = Duration::from_micros(60);

/// The calling thread's timer slack (Linux): how late the kernel may wake a sleeper so that
/// it can batch wake-ups.
#[cfg(target_os = "linux")]
mod slack {
    /// The slack a precise sleep runs with, in nanoseconds (0 would mean "the default").
    const FINE_NS: libc::c_ulong = 1;

    /// The calling thread's timer slack in nanoseconds, None if it cannot be read.
    pub(super) fn get() -> Option<libc::c_ulong> {
        // SAFETY: PR_GET_TIMERSLACK takes no pointers and only reads the calling thread's
        // slack, which it returns (the further arguments are ignored).
        let ns = unsafe { libc::prctl(libc::PR_GET_TIMERSLACK, 0, 0, 0, 0) };
        libc::c_ulong::try_from(ns).ok().filter(|&ns| ns > 0)
    }

    /// Sets the calling thread's timer slack; whether the kernel took it.
    pub(super) fn set(ns: libc::c_ulong) -> bool {
        // SAFETY: PR_SET_TIMERSLACK takes no pointers and only changes the calling thread's
        // slack (ignored for real-time threads, which have none).
        unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, ns, 0, 0, 0) == 0 }
    }

    /// Holds the calling thread's slack at [`FINE_NS`] until dropped, then puts back what it
    /// was. Not `Send`: it must be dropped on the thread that made it.
    pub(super) struct Fine {
        previous: libc::c_ulong,
        _same_thread: std::marker::PhantomData<*const ()>,
    }

    impl Fine {
        /// Lowers the slack; None (nothing to put back) if it is already fine or cannot be
        /// read or changed.
        pub(super) fn lower() -> Option<Fine> {
            let previous = get()?;
            if previous <= FINE_NS || !set(FINE_NS) {
                return None;
            }
            Some(Fine {
                previous,
                _same_thread: std::marker::PhantomData,
            })
        }
    }

    impl Drop for Fine {
        fn drop(&mut self) {
            set(self.previous);
        }
    }
}

/// The absolute deadlines of a polling loop: deadline `n` is `start + n * interval`, so time
/// spent between samples never accumulates as drift. A sample taken late (by the caller or a
/// slow reply) skips the deadlines already past rather than firing them in a burst, and
/// counts them in [`Schedule::missed`]. With a duration the deadlines end before the first
/// one at or after `start + duration`, counted in ticks (in floats, as a Python loop would
/// count them; `benchbus._core._Ticks` gives the deadlines to Python): tick `n` is the end
/// if `n * interval >= duration - epsilon`, with `epsilon` 1 ns per second of duration (at
/// least 1 ns), so 0.9 s at 0.3 s is 3 ticks, not 4.
///
/// Pure bookkeeping: it is given `now` and never reads a clock or sleeps.
#[derive(Debug, Clone)]
pub struct Schedule {
    start: Instant,
    interval: Duration,
    /// The first tick at or after the duration; None: no end.
    end: Option<u64>,
    /// The next tick not yet given out or skipped.
    next: u64,
    missed: u64,
}

impl Schedule {
    /// Deadlines every `interval` from `start` (the first one is `start` itself), for
    /// `duration` or (None) for ever. An interval under 1 ns is taken as 1 ns.
    pub fn new(start: Instant, interval: Duration, duration: Option<Duration>) -> Schedule {
        let interval = interval.max(Duration::from_nanos(1));
        Schedule {
            start,
            interval,
            end: duration.and_then(|d| end_tick(interval, d)),
            next: 0,
            missed: 0,
        }
    }

    /// The next deadline as `(n, start + n * interval)`, given that it is now `now`; None
    /// once the duration is over.
    ///
    /// If `now` is past deadline `n` and also past deadline `n + 1`, the deadlines up to the
    /// latest one not after `now` are skipped and counted as missed: that one is returned (a
    /// little late), never a burst of old ones. A deadline still ahead is returned as is:
    /// the caller sleeps until it.
    pub fn next(&mut self, now: Instant) -> Option<(u64, Instant)> {
        let mut n = self.next;
        if self.end.is_some_and(|end| n >= end) {
            return None;
        }
        let mut deadline = self.deadline(n)?;
        if now > deadline {
            let late = (now - deadline).as_nanos() / self.interval.as_nanos();
            let behind = u64::try_from(late).unwrap_or(u64::MAX);
            let to = n.saturating_add(behind);
            if let Some(end) = self.end.filter(|&end| to >= end) {
                self.missed = self.missed.saturating_add(end - n);
                self.next = end;
                return None;
            }
            deadline = self.deadline(to)?;
            self.missed = self.missed.saturating_add(behind);
            n = to;
        }
        self.next = n.saturating_add(1);
        Some((n, deadline))
    }

    /// How many deadlines were skipped because they had passed.
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// The first deadline.
    pub fn start(&self) -> Instant {
        self.start
    }

    /// The time between deadlines.
    pub fn interval(&self) -> Duration {
        self.interval
    }

    /// `start + n * interval`; None past what an Instant can hold (as good as never).
    fn deadline(&self, n: u64) -> Option<Instant> {
        let nanos = self.interval.as_nanos().checked_mul(u128::from(n))?;
        let secs = u64::try_from(nanos / 1_000_000_000).ok()?;
        let offset = Duration::new(secs, (nanos % 1_000_000_000) as u32);
        self.start.checked_add(offset)
    }
}

/// The first tick `n` with `n * interval >= duration - epsilon` (see [`Schedule`]); None if
/// there are too many ticks to count exactly (more than 2^53: no end in practice).
fn end_tick(interval: Duration, duration: Duration) -> Option<u64> {
    let (i, d) = (interval.as_secs_f64(), duration.as_secs_f64());
    let past = |n: u64| n as f64 * i >= d - 1e-9 * d.max(1.0);
    let guess = (d / i).ceil();
    if !(0.0..9.0e15).contains(&guess) {
        return None;
    }
    // The float guess is within a tick or two of the answer: walk to it.
    let mut n = guess as u64;
    while n > 0 && past(n - 1) {
        n -= 1;
    }
    while !past(n) {
        n += 1;
    }
    Some(n)
}

/// The monotonic clock now, read twice at the same moment: as an [`Instant`] and as
/// `CLOCK_MONOTONIC` seconds, the clock Python's `time.monotonic()` reads on Linux (Rust's
/// `Instant` reads it too). None if the clock cannot be read.
#[cfg(target_os = "linux")]
pub fn monotonic_now() -> Option<(Instant, f64)> {
    let mut ts = std::mem::MaybeUninit::<libc::timespec>::uninit();
    let instant = Instant::now();
    // SAFETY: the pointer is to a writable timespec that outlives the call; it is read only
    // after clock_gettime succeeded, which then has written all of it.
    let ts = unsafe {
        if libc::clock_gettime(libc::CLOCK_MONOTONIC, ts.as_mut_ptr()) != 0 {
            return None;
        }
        ts.assume_init()
    };
    Some((instant, ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_read_together_began_a_character_time_apart_before_the_read() {
        // 9600 8N1: 10 bits a character, 1.0417 ms.
        let line = LineFormat::new(9600, Parity::None, 1);
        let read = Instant::now() + ms(100);
        assert_eq!(line.first_of(1, read), read);
        assert_eq!(line.first_of(0, read), read);
        let seven = read - line.first_of(7, read);
        assert!(
            (seven.as_secs_f64() - 6.0 * 10.0 / 9600.0).abs() < 1e-6,
            "{seven:?}"
        );
        // However far back (a count no read gives), no panic: at most the read itself.
        let now = Instant::now();
        assert!(line.first_of(usize::MAX, now) <= now);
    }

    #[test]
    fn a_frame_sooner_than_the_units_recent_replies_is_too_soon() {
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut t = Turnarounds::new();
        // Nothing known: anything may answer; nor with three replies known.
        assert!(!t.too_soon(1, 3, t0, t0 + ms(8), t0));
        for i in 0..3u64 {
            let start = t0 + ms(100 * i);
            t.answered(1, 3, start, start + ms(8), start + ms(13));
        }
        assert!(!t.too_soon(1, 3, t0 + ms(1000), t0 + ms(1008), t0 + ms(1001)));
        // A real line at 9600: 8.3 ms of request, 5 ms of turnaround.
        for i in 0..20u64 {
            let start = t0 + ms(100 * i);
            t.answered(1, 3, start, start + ms(8), start + ms(13 + i % 3));
        }
        assert_eq!(t.least(1, 3), Some(ms(13)));
        let start = t0 + ms(10_000);
        let end = start + ms(8);
        // Before the request has even ended: a copy, or the last request's answer.
        assert!(t.too_soon(1, 3, start, end, start + ms(2)));
        assert!(t.too_soon(1, 3, start, end, end - ms(2)));
        // Sooner than half its usual turnaround: a copy sent right after the request.
        assert!(t.too_soon(1, 3, start, end, end + ms(2)));
        // As soon as usual, a little sooner, or later: an answer.
        assert!(!t.too_soon(1, 3, start, end, end + ms(5)));
        assert!(!t.too_soon(1, 3, start, end, end + ms(3)));
        assert!(!t.too_soon(1, 3, start, end, end + ms(50)));
        // A long request (a write of many registers) is answered later from its start, never
        // sooner from its end: still an answer.
        assert!(!t.too_soon(1, 3, start, start + ms(60), start + ms(65)));
        // Another unit, or another function, is judged by its own replies only.
        assert!(!t.too_soon(2, 3, start, end, start + ms(2)));
        assert!(!t.too_soon(1, 6, start, end, start + ms(2)));
        t.forget(1, 3);
        assert!(!t.too_soon(1, 3, start, end, start + ms(2)));
        assert_eq!(t.least(1, 3), None);
    }

    #[test]
    fn a_unit_that_answers_before_the_reckoned_end_is_not_judged() {
        // A simulator on a pseudo-terminal, a long request (50 ms reckoned): its replies
        // come 5 ms after the start, before the end; one that comes sooner (the simulator's
        // host less loaded) is no copy.
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut t = Turnarounds::new();
        for i in 0..16u64 {
            let start = t0 + ms(100 * i);
            t.answered(1, 16, start, start + ms(50), start + ms(5));
        }
        let start = t0 + ms(10_000);
        assert!(!t.too_soon(1, 16, start, start + ms(50), start + ms(2)));
    }

    #[test]
    fn a_fast_device_woken_for_late_is_judged_by_the_end_of_the_request() {
        // A device that answers at t3.5 (1.75 ms), each reply seen a scheduler's 1.5 ms late:
        // the one seen on time is an answer.
        let us = Duration::from_micros;
        let t0 = Instant::now();
        let mut t = Turnarounds::new();
        for i in 0..16u64 {
            let start = t0 + us(10_000 * i);
            t.answered(1, 3, start, start + us(700), start + us(700 + 1750 + 1500));
        }
        let start = t0 + us(1_000_000);
        let end = start + us(700);
        assert!(!t.too_soon(1, 3, start, end, end + us(1750)));
        assert!(!t.too_soon(1, 3, start, end, end + us(1500)));
        // Two milliseconds sooner than any seen: sooner than the device answers.
        assert!(t.too_soon(1, 3, start, end, end + us(1000)));
        assert!(t.too_soon(1, 3, start, end, end - us(300)));
    }

    #[test]
    fn on_a_line_without_wire_time_nothing_is_too_soon() {
        // A pseudo-terminal: the reply comes 0.3 ms after the request starts, before its
        // reckoned end, whatever its length: its times are not the wire's, none is judged.
        let ms = Duration::from_millis;
        let us = Duration::from_micros;
        let t0 = Instant::now();
        let mut t = Turnarounds::new();
        for i in 0..16u64 {
            let start = t0 + ms(10 * i);
            t.answered(1, 3, start, start + ms(8), start + us(300));
        }
        let start = t0 + ms(1000);
        for end in [start + ms(8), start + ms(200)] {
            assert!(!t.too_soon(1, 3, start, end, start + us(10)));
            assert!(!t.too_soon(1, 3, start, end, start + us(300)));
        }
    }

    #[test]
    fn the_least_turnaround_is_the_recent_one() {
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut t = Turnarounds::new();
        t.answered(1, 3, t0, t0, t0 + ms(1));
        for i in 1..=TURNAROUND_SAMPLES as u64 {
            let start = t0 + ms(100 * i);
            t.answered(1, 3, start, start, start + ms(20));
        }
        // The 1 ms answer has aged out.
        assert_eq!(t.least(1, 3), Some(ms(20)));
    }

    fn us(d: Duration) -> f64 {
        d.as_secs_f64() * 1e6
    }

    #[test]
    fn char_time_counts_start_parity_and_stop_bits() {
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert_eq!(n81.bits_per_char(), 10);
        assert!((us(n81.char_time()) - 520.833).abs() < 0.01);
        let e81 = LineFormat::new(115_200, Parity::Even, 1);
        assert_eq!(e81.bits_per_char(), 11);
        assert!((us(e81.char_time()) - 95.486).abs() < 0.01);
        let n82 = LineFormat::new(9600, Parity::None, 2);
        assert_eq!(n82.bits_per_char(), 11);
    }

    #[test]
    fn ascii_line_is_7e1_by_default_and_7n2_without_parity() {
        let e71 = LineFormat::ascii(9600, Parity::Even);
        assert_eq!((e71.data_bits, e71.stop_bits), (7, 1));
        assert_eq!(e71.to_string(), "9600 7E1");
        assert_eq!(e71.bits_per_char(), 10);
        assert!((us(e71.char_time()) - 1041.667).abs() < 0.01);
        let n72 = LineFormat::ascii(9600, Parity::None);
        assert_eq!(n72.to_string(), "9600 7N2");
        assert_eq!(n72.bits_per_char(), 10);
        assert_eq!(e71.check_ascii(), Ok(()));
        assert_eq!(n72.check_ascii(), Ok(()));
        assert_eq!(LineFormat::new(9600, Parity::None, 1).check_ascii(), Ok(()));
        let n71 = LineFormat {
            stop_bits: 1,
            ..n72
        };
        assert!(n71.check_ascii().is_err_and(|e| e.contains("7N2")));
        let six = LineFormat {
            data_bits: 6,
            ..e71
        };
        assert!(six.check_ascii().is_err_and(|e| e.contains("not 6")));
    }

    #[test]
    fn t35_is_three_and_a_half_chars_up_to_19200_then_fixed() {
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert!((us(n81.t3_5()) - 1822.9).abs() < 0.1);
        assert!((us(n81.t1_5()) - 781.25).abs() < 0.01);
        let slow = LineFormat::new(9600, Parity::None, 1);
        assert!((us(slow.t3_5()) - 3645.8).abs() < 0.1);
        let fast = LineFormat::new(38_400, Parity::None, 1);
        assert_eq!(fast.t3_5(), Duration::from_micros(1750));
        assert_eq!(fast.t1_5(), Duration::from_micros(750));
    }

    #[test]
    fn wire_limit_of_single_register_reads() {
        // 8 request + 7 reply characters and one t3.5 per transaction.
        let per_tx = |f: LineFormat| f.frame_time(15) + f.t3_5();
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert!((1.0 / per_tx(n81).as_secs_f64() - 103.8).abs() < 0.05);
        let e81 = LineFormat::new(115_200, Parity::Even, 1);
        assert!((1.0 / per_tx(e81).as_secs_f64() - 314.2).abs() < 0.05);
    }

    #[test]
    fn guard_waits_out_the_silence() {
        let mut g = SilenceGuard::new();
        let end = Instant::now() + Duration::from_millis(5);
        g.busy_until(end);
        g.busy_until(Instant::now()); // an earlier instant never shortens the wait
        g.wait(Duration::from_millis(2));
        assert!(Instant::now() >= end + Duration::from_millis(2));
    }

    #[test]
    fn sleep_until_is_never_early() {
        for us in [0, 50, 300, 1750, 3000] {
            let deadline = Instant::now() + Duration::from_micros(us);
            sleep_until(deadline);
            assert!(Instant::now() >= deadline, "woke early for {us} us");
        }
        let past = Instant::now();
        sleep_until(past); // already due: returns at once
        assert!(Instant::now() >= past);
    }

    /// The CPU time the calling thread has used.
    #[cfg(unix)]
    fn thread_cpu_time() -> Duration {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: a valid out-pointer to a timespec on this stack frame.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        assert_eq!(rc, 0);
        Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
    }

    /// The CPU time the calling thread has used.
    #[cfg(windows)]
    fn thread_cpu_time() -> Duration {
        use windows_sys::Win32::Foundation::FILETIME;
        use windows_sys::Win32::System::Threading::{GetCurrentThread, GetThreadTimes};
        let zero = || FILETIME {
            dwLowDateTime: 0,
            dwHighDateTime: 0,
        };
        let (mut created, mut exited, mut kernel, mut user) = (zero(), zero(), zero(), zero());
        // SAFETY: the current thread's pseudo-handle and four valid out-pointers.
        let ok = unsafe {
            GetThreadTimes(
                GetCurrentThread(),
                &mut created,
                &mut exited,
                &mut kernel,
                &mut user,
            )
        };
        assert_ne!(ok, 0);
        let ticks = |t: FILETIME| (u64::from(t.dwHighDateTime) << 32) | u64::from(t.dwLowDateTime);
        Duration::from_nanos((ticks(kernel) + ticks(user)) * 100)
    }

    #[test]
    fn a_t35_wait_is_not_rounded_up_to_timer_ticks_nor_spun() {
        // Windows's default timer tick is 15.6 ms: a sleep that waited in ticks would turn
        // the 1.75 ms t3.5 of a fast line into some 15 ms, a wait that spun would burn a core.
        let t35 = LineFormat::new(38_400, Parity::None, 1).t3_5();
        let rounds = 40;
        let cpu = thread_cpu_time();
        let start = Instant::now();
        for _ in 0..rounds {
            sleep_until(Instant::now() + t35);
        }
        let (took, cpu) = (start.elapsed(), thread_cpu_time() - cpu);
        let mean = took / rounds;
        assert!(
            mean >= t35 && mean < Duration::from_millis(6),
            "a 1.75 ms wait took {mean:?} on average"
        );
        assert!(cpu < took / 4, "{cpu:?} of CPU in {took:?} of waits");
    }

    #[cfg(target_os = "linux")]
    fn thread_slack() -> libc::c_int {
        // SAFETY: PR_GET_TIMERSLACK takes no pointers and only reads this thread's slack.
        unsafe { libc::prctl(libc::PR_GET_TIMERSLACK, 0, 0, 0, 0) }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn sleep_until_puts_the_thread_slack_back() {
        let before = thread_slack();
        assert!(before > 0);
        sleep_until(Instant::now() + Duration::from_millis(1));
        assert_eq!(thread_slack(), before);
        // A slack of the thread's own (not the default) is put back too.
        assert!(slack::set(123_457));
        sleep_until(Instant::now() + Duration::from_millis(1));
        assert_eq!(thread_slack(), 123_457);
        // While a sleep runs the slack is fine; dropping the guard restores it.
        {
            let _fine = slack::Fine::lower();
            assert_eq!(thread_slack(), 1);
        }
        assert_eq!(thread_slack(), 123_457);
        assert!(slack::set(before as libc::c_ulong));
        assert_eq!(thread_slack(), before);
    }

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn schedule_on_time_gives_every_deadline() {
        let start = Instant::now();
        let mut s = Schedule::new(start, ms(50), None);
        assert_eq!(s.next(start), Some((0, start)));
        // The caller asks a little after each sample: the next deadline is still ahead.
        for n in 1..=1000u64 {
            let now = start + ms(50) * (n as u32 - 1) + ms(3);
            assert_eq!(s.next(now), Some((n, start + ms(50) * n as u32)));
        }
        assert_eq!(s.missed(), 0);
        assert_eq!((s.start(), s.interval()), (start, ms(50)));
    }

    #[test]
    fn schedule_skips_past_deadlines_without_a_burst() {
        let start = Instant::now();
        let mut s = Schedule::new(start, ms(100), None);
        assert_eq!(s.next(start), Some((0, start)));
        // The body took 2.5 intervals: deadlines 1 and 2 have passed; 1 is skipped, 2 is
        // taken late, and the next one is 3 on the original grid.
        assert_eq!(s.next(start + ms(250)), Some((2, start + ms(200))));
        assert_eq!(s.missed(), 1);
        assert_eq!(s.next(start + ms(260)), Some((3, start + ms(300))));
        // Exactly at a deadline is on time.
        assert_eq!(s.next(start + ms(400)), Some((4, start + ms(400))));
        // Late by less than one interval: taken late, nothing missed.
        assert_eq!(s.next(start + ms(590)), Some((5, start + ms(500))));
        assert_eq!(s.missed(), 1);
        // A long stall: 1 h at 100 ms skips 35 994 deadlines at once.
        let hour = Duration::from_secs(3600);
        assert_eq!(s.next(start + hour + ms(1)), Some((36_000, start + hour)));
        assert_eq!(s.missed(), 1 + 35_994);
    }

    #[test]
    fn schedule_counts_ticks_of_a_duration() {
        let count = |interval: f64, duration: f64| {
            let start = Instant::now();
            let mut s = Schedule::new(
                start,
                Duration::from_secs_f64(interval),
                Some(Duration::from_secs_f64(duration)),
            );
            let mut ticks = Vec::new();
            while let Some((n, at)) = s.next(start) {
                assert_eq!(at, start + s.interval() * n as u32);
                ticks.push(n);
            }
            assert_eq!(s.next(start + Duration::from_secs(10)), None); // stays over
            assert_eq!(s.missed(), 0);
            assert_eq!(ticks, (0..ticks.len() as u64).collect::<Vec<_>>());
            ticks.len()
        };
        assert_eq!(count(0.05, 0.3), 6);
        assert_eq!(count(0.3, 0.9), 3); // 0.9 / 0.3 is 3.0000000000000004 in floats
        assert_eq!(count(0.1, 1.0), 10);
        assert_eq!(count(0.1, 0.7), 7);
        assert_eq!(count(1.0 / 3.0, 1.0), 3);
        assert_eq!(count(0.05, 0.31), 7);
        assert_eq!(count(0.05, 0.0), 0);
        assert_eq!(count(0.05, 0.001), 1);
        assert_eq!(count(3600.0, 0.5), 1);
    }

    #[test]
    fn schedule_overrun_past_the_end_counts_what_was_missed() {
        let start = Instant::now();
        let mut s = Schedule::new(start, ms(50), Some(ms(300)));
        assert_eq!(s.next(start), Some((0, start)));
        assert_eq!(s.next(start + ms(120)), Some((2, start + ms(100))));
        assert_eq!(s.missed(), 1);
        // Deadlines 3, 4 and 5 pass while the caller is away; 6 is the end.
        assert_eq!(s.next(start + Duration::from_secs(5)), None);
        assert_eq!(s.missed(), 4);
        assert_eq!(s.next(start + Duration::from_secs(6)), None);
        assert_eq!(s.missed(), 4);
    }

    #[test]
    fn schedule_edge_intervals() {
        let start = Instant::now();
        // A zero interval is taken as 1 ns rather than dividing by zero.
        let mut s = Schedule::new(start, Duration::ZERO, None);
        assert_eq!(s.next(start), Some((0, start)));
        assert_eq!(
            s.next(start + Duration::from_nanos(10)),
            Some((10, start + Duration::from_nanos(10)))
        );
        assert_eq!(s.missed(), 9);
        // A duration of more ticks than a float counts exactly has no end in practice.
        let s = Schedule::new(
            start,
            Duration::from_nanos(1),
            Some(Duration::from_secs(1 << 40)),
        );
        assert_eq!(s.end, None);
        // A deadline past what an Instant holds ends the schedule instead of overflowing.
        // Deadline 2 is past any platform's Instant (Linux's i64 seconds, Windows's u64).
        let mut s = Schedule::new(start, Duration::from_secs(u64::MAX / 2), None);
        assert_eq!(s.next(start), Some((0, start)));
        let _ = s.next(start); // deadline 1 may or may not fit in an Instant
        assert_eq!(s.next(start), None);
        assert_eq!(s.next(start), None);
    }

    #[test]
    fn write_pacing_per_unit_and_across_broadcasts() {
        let t0 = Instant::now();
        let mut p = WritePacing::new();
        assert_eq!(p.write_ready(1, ms(150)), None);
        assert_eq!(p.broadcast_ready(ms(0)), None);
        p.wrote(1, ms(150), t0);
        assert_eq!(p.write_ready(1, ms(150)), Some(t0 + ms(150)));
        // Another unit is not held up by unit 1's writes.
        assert_eq!(p.write_ready(2, ms(150)), None);
        // A broadcast waits out unit 1's interval...
        assert_eq!(p.broadcast_ready(ms(0)), Some(t0 + ms(150)));
        p.wrote(2, ms(0), t0 + ms(10));
        assert_eq!(p.broadcast_ready(ms(0)), Some(t0 + ms(150)));
        // ...and every unit's next write waits its interval after the broadcast.
        p.broadcast(t0 + ms(200));
        assert_eq!(p.write_ready(1, ms(150)), Some(t0 + ms(350)));
        assert_eq!(p.write_ready(2, ms(20)), Some(t0 + ms(220)));
        // The next broadcast waits the widest interval any unit asked for.
        assert_eq!(p.broadcast_ready(ms(0)), Some(t0 + ms(350)));
        // A unit's widest interval is kept even when a later write asks for less.
        p.wrote(1, ms(50), t0 + ms(400));
        assert_eq!(p.broadcast_ready(ms(0)), Some(t0 + ms(550)));
        p.broadcast(t0 + ms(500));
        assert_eq!(p.broadcast_ready(ms(0)), Some(t0 + ms(650)));
        // A broadcast's own interval holds after the last broadcast too, for units no write
        // has told the pacing of yet.
        assert_eq!(p.broadcast_ready(ms(300)), Some(t0 + ms(800)));
        let mut fresh = WritePacing::new();
        fresh.broadcast(t0);
        assert_eq!(fresh.broadcast_ready(ms(0)), Some(t0));
        assert_eq!(fresh.broadcast_ready(ms(150)), Some(t0 + ms(150)));
    }

    #[test]
    fn display_is_the_usual_notation() {
        assert_eq!(
            LineFormat::new(115_200, Parity::Even, 1).to_string(),
            "115200 8E1"
        );
    }
}
