//! Bindings of [`crate::device::pbl`]: the parameter-level core that `benchbus.PblDrive`
//! (Python) wraps with enums and properties.

use super::{int_in, number, to_pyerr, Attached, PyBus};
use crate::device::pbl::{alarm_names, by_name, by_number, Pbl, PARAMETERS};
use crate::device::Access;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt, PyList, PyString};

/// The parameter-level core of a PBL-series drive (see `benchbus.PblDrive`).
#[pyclass(frozen, module = "benchbus._core", name = "PblCore")]
pub(super) struct PyPblCore {
    dev: Attached<Pbl>,
}

impl PyPblCore {
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&Pbl) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        self.dev.wire(py, f)
    }
}

/// A parameter given by number (0..=222) or by name, as its number.
fn parameter_number(py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<u16> {
    if key.is_instance_of::<PyString>() {
        let name: String = key.extract()?;
        return by_name(&name)
            .map(|p| p.address)
            .map_err(|e| to_pyerr(py, e));
    }
    if key.is_instance_of::<PyBool>() || !key.is_instance_of::<PyInt>() {
        return Err(PyTypeError::new_err(format!(
            "a parameter is a number 0 to 222 or a name, got {}",
            key.get_type().name()?
        )));
    }
    int_in(key, "parameter", 0, (PARAMETERS.len() - 1) as i64).map(|n| n as u16)
}

#[pymethods]
impl PyPblCore {
    #[new]
    #[pyo3(signature = (bus, unit, timeout=None, retries=None))]
    fn new(
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let dev = Attached::new(bus, unit, timeout, retries, |b, u| Ok(Pbl::new(b, u)))?;
        Ok(PyPblCore { dev })
    }

    /// The Bus the drive talks through.
    #[getter]
    fn bus(&self, py: Python<'_>) -> Py<PyBus> {
        self.dev.bus(py)
    }

    /// The drive's unit address.
    #[getter]
    fn unit(&self) -> u8 {
        self.dev.unit()
    }

    /// Reads the parameter called `name` (an int).
    fn get(&self, py: Python<'_>, name: &str) -> PyResult<i64> {
        by_name(name).map_err(|e| to_pyerr(py, e))?;
        let name = name.to_string();
        self.wire(py, move |p| p.get(&name)).map(|v| v as i64)
    }

    /// Writes `value` to the parameter called `name`.
    fn set(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let value = number(value, name)?;
        let name = name.to_string();
        self.wire(py, move |p| p.set(&name, value))
    }

    /// Reads one parameter, by number or name.
    fn read_parameter(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<u16> {
        let n = parameter_number(py, key)?;
        self.wire(py, move |p| p.read_parameter(n))
    }

    /// Writes one parameter, by number or name, checked against the table first.
    fn write_parameter(
        &self,
        py: Python<'_>,
        key: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let n = parameter_number(py, key)?;
        let value = int_in(value, "value", 0, 0xFFFF)? as u16;
        by_number(n)
            .and_then(|p| p.encode(f64::from(value)))
            .map_err(|e| to_pyerr(py, e))?;
        self.wire(py, move |p| p.write_parameter(n, value))
    }

    /// Reads `count` parameters from `start` (in as few requests as allowed).
    fn read_parameters(
        &self,
        py: Python<'_>,
        start: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let start = parameter_number(py, start)?;
        let count = int_in(count, "count", 1, PARAMETERS.len() as i64)? as u16;
        self.wire(py, move |p| p.read_parameters(start, count))
    }

    /// Every documented parameter, `{name: value}`, in four requests (61 a reply).
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.wire(py, |p| p.parameters())?;
        let out = PyDict::new(py);
        for (name, value) in all {
            out.set_item(name, value)?;
        }
        Ok(out)
    }

    /// Parameters 0..=99 but the reserved ones, `{name: value}`, in two requests.
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.wire(py, |p| p.telemetry())?;
        let out = PyDict::new(py);
        for (name, value, _) in all {
            out.set_item(name, value)?;
        }
        Ok(out)
    }

    /// Sets the start bit of the control word, keeping the others.
    fn start(&self, py: Python<'_>) -> PyResult<()> {
        self.wire(py, |p| p.start())
    }

    /// Clears the start bit of the control word, keeping the others.
    fn stop(&self, py: Python<'_>) -> PyResult<()> {
        self.wire(py, |p| p.stop())
    }

    /// Sets the direction bit of the control word (True = reverse), keeping the others.
    fn set_reverse(&self, py: Python<'_>, reverse: bool) -> PyResult<()> {
        self.wire(py, move |p| p.set_reverse(reverse))
    }

    /// The control word as `(started, reverse)`.
    fn control(&self, py: Python<'_>) -> PyResult<(bool, bool)> {
        self.wire(py, |p| p.control())
    }

    /// The status word as `(running, reverse)`.
    fn status(&self, py: Python<'_>) -> PyResult<(bool, bool)> {
        self.wire(py, |p| p.status())
    }

    /// The 32-bit alarm word and the names of its set bits.
    fn alarms(&self, py: Python<'_>) -> PyResult<(u32, Vec<String>)> {
        let word = self.wire(py, |p| p.alarms())?;
        Ok((word, alarm_names(word)))
    }

    /// Writes 1511 to parameter 214 (defaults restored at the next power-up).
    fn restore_defaults(&self, py: Python<'_>) -> PyResult<()> {
        self.wire(py, |p| p.restore_defaults())
    }

    /// The parameter table: `(number, name, unit, access, low, high)`; access "R" or "W/R".
    #[staticmethod]
    fn table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for p in &PARAMETERS {
            let access = if p.access == Access::Read { "R" } else { "W/R" };
            out.append((p.address, p.name, p.unit, access, p.range.0, p.range.1))?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!("PblCore(unit={})", self.dev.unit())
    }
}
