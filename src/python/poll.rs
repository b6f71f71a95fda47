//! `Bus.poll`: an iterator of holding-register reads on absolute deadlines. The deadline
//! bookkeeping is [`crate::timing::Schedule`]; this file sleeps (GIL released, in slices that
//! let Ctrl-C through: [`sleep_near`], which `_Ticks` shares), reads and maps errors.

use super::{
    int_in, on_wire, opt, seconds, seconds_value, to_pyerr, u16_arg, unit_arg, within_map,
};
use crate::bus::{self, TxOptions};
use crate::codec::pdu::MAX_READ_COUNT;
use crate::timing::{sleep_until, Schedule};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// The longest sleep between two checks for Ctrl-C (and other signals).
const SLICE: Duration = Duration::from_millis(100);

/// Reads of holding registers at `start + n * interval`, as `(t, values)`.
#[pyclass(frozen, module = "benchbus._core", name = "Poll")]
pub(super) struct PyPoll {
    bus: Arc<bus::Bus>,
    unit: u8,
    address: u16,
    count: u16,
    /// The interval as the caller gave it: `t` is `n * interval` in floats, as in Python.
    interval: f64,
    /// The interval on the clock.
    period: Duration,
    duration: Option<(f64, Duration)>,
    /// None until the first `__next__` starts the poll. Locked only with the GIL held and
    /// never across a release of it (no Python code runs under it), so it is never waited
    /// for.
    schedule: Mutex<Option<Schedule>>,
    missed: AtomicU64,
    started: OnceLock<f64>,
}

impl PyPoll {
    /// Checks the arguments of `Bus.poll` (before anything is sent) and makes the iterator.
    pub(super) fn new(
        py: Python<'_>,
        bus: &Arc<bus::Bus>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: Option<&Bound<'_, PyAny>>,
        interval: &Bound<'_, PyAny>,
        duration: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyPoll> {
        let unit = unit_arg(unit)?;
        let address = u16_arg(address, "address")?;
        let count = opt(count, 1, |c| int_in(c, "count", 1, MAX_READ_COUNT.into()))? as u16;
        within_map(address, count.into())?;
        let period = seconds(interval, "interval", false)?;
        let interval = seconds_value(interval, "interval")?;
        let duration = opt(duration, None, |d| duration_arg(d).map(Some))?;
        let shared = Arc::clone(bus);
        if py.detach(move || shared.is_closed()) {
            return Err(to_pyerr(py, bus.closed()));
        }
        Ok(PyPoll {
            bus: Arc::clone(bus),
            unit,
            address,
            count,
            interval,
            period,
            duration,
            schedule: Mutex::new(None),
            missed: AtomicU64::new(0),
            started: OnceLock::new(),
        })
    }

    /// The next deadline (starting the poll on the first call); None once it is over.
    fn next_deadline(&self, py: Python<'_>) -> PyResult<Option<(u64, Instant)>> {
        // The clock is read before the lock is taken: reading Python's (off Linux) may let
        // other threads run, and one waiting for the lock would then hold the GIL.
        let fresh = match self.started.get() {
            Some(_) => None,
            None => Some(monotonic_start(py)?),
        };
        let mut schedule = self
            .schedule
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let schedule = match (&mut *schedule, fresh) {
            (Some(s), _) => s,
            (empty, Some((start, seconds))) => {
                let _ = self.started.set(seconds);
                let duration = self.duration.map(|(_, d)| d);
                empty.insert(Schedule::new(start, self.period, duration))
            }
            // Cannot be: `started` is set together with the schedule.
            (None, None) => return Ok(None),
        };
        let next = schedule.next(Instant::now());
        self.missed.store(schedule.missed(), Ordering::Relaxed);
        Ok(next)
    }
}

#[pymethods]
impl PyPoll {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// Sleeps until the next deadline, reads, and returns `(t, values)`.
    fn __next__(&self, py: Python<'_>) -> PyResult<Option<(f64, Vec<u16>)>> {
        let bus = Arc::clone(&self.bus);
        if py.detach(move || bus.is_closed()) {
            return Err(to_pyerr(py, self.bus.closed()));
        }
        let Some((n, deadline)) = self.next_deadline(py)? else {
            return Ok(None);
        };
        // The last slice and the request share one release, so the request is not held up
        // waiting for the GIL after the sleep.
        sleep_near(py, deadline)?;
        let (unit, address, count) = (self.unit, self.address, self.count);
        let values = on_wire(py, &self.bus, move |b| {
            sleep_until(deadline);
            b.read_holding_registers(unit, address, count, &TxOptions::default())
        })?;
        Ok(Some((n as f64 * self.interval, values)))
    }

    /// Deadlines skipped because they had passed when the next sample was asked for.
    #[getter]
    fn missed(&self) -> u64 {
        self.missed.load(Ordering::Relaxed)
    }

    /// `time.monotonic()` at the poll's start (the first `__next__`); None before it.
    #[getter]
    fn started(&self) -> Option<f64> {
        self.started.get().copied()
    }

    fn __repr__(&self) -> String {
        let duration = match self.duration {
            Some((d, _)) => format!("{d:?}"),
            None => "None".to_string(),
        };
        format!(
            "Poll(unit={}, address={:#06x}, count={}, interval={:?}, duration={}, missed={})",
            self.unit,
            self.address,
            self.count,
            self.interval,
            duration,
            self.missed()
        )
    }
}

/// Sleeps until `deadline` is at most one [`SLICE`] away: in slices, with the GIL released,
/// so Ctrl-C (and other signals) get through between them.
///
/// # Errors
/// What a signal handler raised (KeyboardInterrupt).
pub(super) fn sleep_near(py: Python<'_>, deadline: Instant) -> PyResult<()> {
    loop {
        let now = Instant::now();
        if deadline.saturating_duration_since(now) <= SLICE {
            return Ok(());
        }
        py.detach(move || sleep_until(now + SLICE));
        py.check_signals()?;
    }
}

/// A duration argument: a finite number of seconds >= 0, as given and on the clock.
fn duration_arg(obj: &Bound<'_, PyAny>) -> PyResult<(f64, Duration)> {
    let value = seconds_value(obj, "duration")?;
    let clock = Duration::try_from_secs_f64(value)
        .ok()
        .filter(|_| value.is_finite())
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "duration must be a finite number of seconds >= 0 (or None), got {value}"
            ))
        })?;
    Ok((value, clock))
}

/// The monotonic clock now, as an `Instant` and as `time.monotonic()` seconds taken at the
/// same moment. On Linux both are `CLOCK_MONOTONIC`, read back to back; elsewhere (or should
/// that read fail) Python's own clock is read right after the `Instant`.
pub(super) fn monotonic_start(py: Python<'_>) -> PyResult<(Instant, f64)> {
    #[cfg(target_os = "linux")]
    if let Some(pair) = crate::timing::monotonic_now() {
        return Ok(pair);
    }
    let instant = Instant::now();
    let seconds: f64 = py.import("time")?.call_method0("monotonic")?.extract()?;
    Ok((instant, seconds))
}
