//! `diagnose`: a serial port's check-up ([`crate::transport::doctor`]) as tuples.

use super::{line_arg, opt, seconds, u8_in};
use crate::transport::doctor::{self, Checkup};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;

/// One finding: `(name, verdict, message, fix or None)`.
type Row = (&'static str, &'static str, String, Option<String>);

/// The findings for the serial port `port`, each `(name, verdict, message, fix)`: the
/// line format is the one to open it at, `unit` and `timeout` those of the echo test's read;
/// `sysfs_root` and `proc_root` read other trees than `/sys` and `/proc` (Linux). Runs
/// without the GIL.
#[pyfunction]
#[pyo3(
    signature = (port, baudrate=None, parity=None, stopbits=None, unit=None, timeout=None, sysfs_root=None, proc_root=None),
    text_signature = "(port, baudrate=19200, parity='N', stopbits=1, unit=1, timeout=0.1, sysfs_root=None, proc_root=None)"
)]
#[allow(clippy::too_many_arguments)]
pub fn diagnose(
    py: Python<'_>,
    port: &Bound<'_, PyAny>,
    baudrate: Option<&Bound<'_, PyAny>>,
    parity: Option<&Bound<'_, PyAny>>,
    stopbits: Option<&Bound<'_, PyAny>>,
    unit: Option<&Bound<'_, PyAny>>,
    timeout: Option<&Bound<'_, PyAny>>,
    sysfs_root: Option<PathBuf>,
    proc_root: Option<PathBuf>,
) -> PyResult<Vec<Row>> {
    let port: PathBuf = port
        .extract()
        .map_err(|_| PyTypeError::new_err("port must be a str or os.PathLike"))?;
    let port = port.to_string_lossy().into_owned();
    let mut checkup = Checkup::new(line_arg(baudrate, parity, stopbits)?);
    checkup.unit = opt(unit, 1, |u| u8_in(u, "unit", 1, 247))?;
    checkup.timeout = opt(timeout, checkup.timeout, |t| seconds(t, "timeout", false))?;
    if let Some(root) = sysfs_root {
        checkup.sysfs = root;
    }
    if let Some(root) = proc_root {
        checkup.proc_root = root;
    }
    let found = py
        .detach(move || doctor::diagnose(&port, &checkup))
        .map_err(PyValueError::new_err)?;
    Ok(found
        .into_iter()
        .map(|f| (f.name, f.verdict.as_str(), f.message, f.fix))
        .collect())
}
