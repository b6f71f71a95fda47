//! `_Ticks`: the deadlines of [`crate::timing::Schedule`] as a Python iterator, for the
//! periodic loops written in Python (`record`, the keepalive, the CLI's and the demo's
//! loops). `Bus.poll` uses the same Schedule in Rust.
//!
//! Each `__next__` waits for the next deadline and gives `(n, deadline, missed)`: the tick
//! number, its deadline in `time.monotonic()` seconds (`start + n * interval`, in floats)
//! and how many deadlines were skipped just before it. On the real clock the wait happens
//! with the GIL released, in slices that let Ctrl-C through. A `clock` (seconds, as
//! `time.monotonic`) and a `sleep` can be given instead, for tests with a fake clock or for
//! a wait that a stop request cuts short (`threading.Event.wait`); the Schedule then runs on
//! the given clock's readings.

use super::poll::{monotonic_start, sleep_near};
use crate::timing::{sleep_until, Schedule};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt};
use std::time::{Duration, Instant};

/// Deadlines every `interval` seconds from the first `__next__`, for `duration` seconds or
/// (None) for ever.
#[pyclass(module = "benchbus._core", name = "_Ticks")]
pub(super) struct PyTicks {
    /// The interval as given: deadlines are `start + n * interval` in floats, as in Python.
    interval: f64,
    period: Duration,
    duration: Option<Duration>,
    clock: Option<Py<PyAny>>,
    sleep: Option<Py<PyAny>>,
    /// None until the first `__next__`.
    running: Option<Running>,
}

/// A started schedule, and where its clock started.
struct Running {
    schedule: Schedule,
    /// The start on the Instant clock, and in the seconds of the clock given (or of
    /// `time.monotonic()`).
    start: Instant,
    start_seconds: f64,
    /// The deadlines skipped before the last tick given out.
    missed: u64,
}

#[pymethods]
impl PyTicks {
    #[new]
    #[pyo3(signature = (interval, duration = None, *, clock = None, sleep = None))]
    fn new(
        interval: &Bound<'_, PyAny>,
        duration: Option<&Bound<'_, PyAny>>,
        clock: Option<Py<PyAny>>,
        sleep: Option<Py<PyAny>>,
    ) -> PyResult<PyTicks> {
        let (interval, period) = seconds_arg(interval, false).ok_or_else(|| {
            PyValueError::new_err(format!(
                "interval must be a positive number of seconds, got {}",
                interval
                    .repr()
                    .map_or_else(|_| "?".into(), |r| r.to_string())
            ))
        })?;
        let duration = match duration {
            None => None,
            Some(d) => Some(seconds_arg(d, true).map(|(_, d)| d).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "duration must be >= 0 seconds, got {}",
                    d.repr().map_or_else(|_| "?".into(), |r| r.to_string())
                ))
            })?),
        };
        Ok(PyTicks {
            interval,
            period,
            duration,
            clock,
            sleep,
            running: None,
        })
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// Waits for the next deadline and returns `(n, deadline, missed)`; StopIteration once
    /// the duration is over.
    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<(u64, f64, u64)>> {
        let running = match self.running.take() {
            Some(running) => running,
            None => {
                let (start, start_seconds) = match &self.clock {
                    Some(clock) => (Instant::now(), clock.bind(py).call0()?.extract::<f64>()?),
                    None => monotonic_start(py)?,
                };
                Running {
                    schedule: Schedule::new(start, self.period, self.duration),
                    start,
                    start_seconds,
                    missed: 0,
                }
            }
        };
        let running = self.running.insert(running);
        // Now, on the Instant clock and (for a clock given) in its seconds.
        let (now, now_seconds) = match &self.clock {
            Some(clock) => {
                let seconds: f64 = clock.bind(py).call0()?.extract()?;
                let since = Duration::try_from_secs_f64(seconds - running.start_seconds)
                    .unwrap_or(Duration::ZERO);
                (running.start + since, Some(seconds))
            }
            None => (Instant::now(), None),
        };
        let Some((n, deadline)) = running.schedule.next(now) else {
            return Ok(None);
        };
        let missed = running.schedule.missed() - running.missed;
        running.missed = running.schedule.missed();
        let deadline_seconds = running.start_seconds + n as f64 * self.interval;
        let wait = match now_seconds {
            Some(now) => deadline_seconds - now,
            None => deadline.saturating_duration_since(now).as_secs_f64(),
        };
        match &self.sleep {
            Some(sleep) if wait > 0.0 => {
                sleep.call1(py, (wait,))?;
            }
            Some(_) => {}
            None => {
                // On a clock given, its wait on the real clock.
                let until = match now_seconds {
                    Some(_) => {
                        Instant::now() + Duration::try_from_secs_f64(wait).unwrap_or_default()
                    }
                    None => deadline,
                };
                sleep_near(py, until)?;
                py.detach(move || sleep_until(until));
            }
        }
        Ok(Some((n, deadline_seconds, missed)))
    }
}

/// A number of seconds (int or float, not bool), finite and > 0 (or >= 0 if `zero`), as
/// given and on the clock; None if it is not one.
fn seconds_arg(obj: &Bound<'_, PyAny>, zero: bool) -> Option<(f64, Duration)> {
    let number = (obj.is_instance_of::<PyInt>() && (zero || !obj.is_instance_of::<PyBool>()))
        || obj.is_instance_of::<PyFloat>();
    if !number {
        return None;
    }
    let value: f64 = obj.extract().ok()?;
    if !(value > 0.0 || (zero && value == 0.0)) {
        return None;
    }
    Some((value, Duration::try_from_secs_f64(value).ok()?))
}
