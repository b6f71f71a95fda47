//! Bindings of [`crate::device::pbl`]: the compiled base class of `benchbus.PblDrive`, which
//! adds only what belongs to Python (enums, the status object, reprs, the context manager).

use super::device_methods;
use super::{int_choice, int_in, public, to_pyerr, Attached, PyBus, PyStation};

/// The Python module of the family's public types.
const PY: &str = "benchbus._pbl";
use crate::device::pbl::{alarm_names, by_name, by_number, table, Pbl, SAMPLE};
use crate::device::Access;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFrozenSet, PyInt, PyList, PyString, PyTuple};

/// The compiled base of `benchbus.PblDrive`: the parameter table and every call to the drive.
#[pyclass(extends = PyStation, subclass, frozen, module = "benchbus._core", name = "PblCore")]
pub(super) struct PyPblCore {
    dev: Attached<Pbl>,
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
    let last = table()
        .map_err(|e| to_pyerr(py, e))?
        .len()
        .saturating_sub(1);
    int_in(key, "parameter", 0, last as i64).map(|n| n as u16)
}

device_methods! {
PyPblCore = |dev| PyPblCore { dev };
attach = Pbl::new;
tabled;


    /// Reads one parameter, by number or name.
    fn read_parameter(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<u16> {
        let n = parameter_number(py, key)?;
        self.dev.wire(py, move |p| p.read_parameter(n))
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
        self.dev.wire(py, move |p| p.write_parameter(n, value))
    }

    /// Reads `count` parameters from `start` (in as few requests as allowed).
    fn read_parameters(
        &self,
        py: Python<'_>,
        start: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let start = parameter_number(py, start)?;
        let all = table().map_err(|e| to_pyerr(py, e))?.len();
        let count = int_in(count, "count", 1, all as i64)? as u16;
        self.dev.wire(py, move |p| p.read_parameters(start, count))
    }

    /// The names :meth:`sample` gives: parameters 50..54.
    #[classattr]
    #[allow(non_snake_case)]
    fn SAMPLE_FIELDS<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, SAMPLE)
    }

    /// Speed (rpm), bus voltage (V), analog speed input (mV), current (A) and power (W):
    /// parameters 50..54, in one request.
    fn sample<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.dev.wire(py, |p| p.sample())?;
        let out = PyDict::new(py);
        for (name, value) in all {
            out.set_item(name, f64::from(value))?;
        }
        Ok(out)
    }

    /// Every documented parameter, `{name: value}`, in four requests (61 a reply).
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.dev.wire(py, |p| p.parameters())?;
        let out = PyDict::new(py);
        for (name, value) in all {
            out.set_item(name, value)?;
        }
        Ok(out)
    }

    /// Parameters 0..99 (status and measurements) by name, in two requests: a dict, shown
    /// as a table in notebooks.
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let all = self.dev.wire(py, |p| p.telemetry())?;
        let out = PyDict::new(py);
        for (name, value, _) in all {
            out.set_item(name, value)?;
        }
        public(py, PY, "PblTelemetry", (out,), None)
    }

    /// Start: set bit 0 of the control word, keeping its other bits.
    fn start(&self, py: Python<'_>) -> PyResult<()> {
        self.dev.wire(py, |p| p.start())
    }

    /// Stop: clear bit 0 of the control word, keeping its other bits.
    fn stop(&self, py: Python<'_>) -> PyResult<()> {
        self.dev.wire(py, |p| p.stop())
    }

    /// What leaving a ``with`` block sends: :meth:`stop`; ``urgent`` (leaving on an
    /// exception): a control word of 0 (stop, forward), sent once, at once.
    #[pyo3(signature = (urgent=false))]
    fn _stop_on_exit(&self, py: Python<'_>, urgent: bool) -> PyResult<()> {
        self.dev.stop_on_exit(py, |p| p.stop_on_exit(urgent))
    }

    /// The direction asked for: bit 1 of the control word (see :meth:`status` for the
    /// direction the motor turns). Setting it keeps the control word's other bits.
    #[getter]
    fn direction<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (_, reverse) = self.dev.wire(py, |p| p.control())?;
        public(py, PY, "Direction", (u8::from(reverse),), None)
    }

    #[setter]
    fn set_direction(&self, py: Python<'_>, direction: &Bound<'_, PyAny>) -> PyResult<()> {
        let allowed = "Direction.FORWARD or REVERSE";
        let choices = [(0, false), (1, true)];
        let reverse = int_choice(direction, "direction", "a Direction", allowed, &choices)?;
        self.dev.wire(py, move |p| p.set_reverse(reverse))
    }

    /// The status word: running, and the direction the motor turns.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (running, reverse) = self.dev.wire(py, |p| p.status())?;
        let direction = public(py, PY, "Direction", (u8::from(reverse),), None)?;
        public(py, PY, "PblStatus", (running, direction), None)
    }

    /// Whether the motor is moving (status word bit 0).
    #[getter]
    fn running(&self, py: Python<'_>) -> PyResult<bool> {
        self.dev
            .wire(py, |p| p.status())
            .map(|(running, _)| running)
    }

    /// The 32-bit alarm word (parameter 5 high, 4 low).
    #[getter]
    fn alarm_word(&self, py: Python<'_>) -> PyResult<u32> {
        self.dev.wire(py, |p| p.alarms())
    }

    /// The active alarm bits by name ("alarm bit N": the manual names none).
    #[getter]
    fn alarms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyFrozenSet>> {
        let word = self.dev.wire(py, |p| p.alarms())?;
        PyFrozenSet::new(py, alarm_names(word))
    }

    /// Writes 1511 to parameter 214 (defaults restored at the next power-up).
    fn _restore_defaults(&self, py: Python<'_>) -> PyResult<()> {
        self.dev.wire(py, |p| p.restore_defaults())
    }

    /// The parameter table: a :class:`~benchbus.PblParameter` (number, name, unit, access,
    /// low, high) for each parameter; access "R" or "W/R".
    #[staticmethod]
    fn table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for p in table().map_err(|e| to_pyerr(py, e))? {
            let p = &p.register;
            // A read-only parameter takes no write: its range is (0, 0).
            let ((low, high), access) = match p.access {
                Access::Read => ((0.0, 0.0), "R"),
                _ => (p.range, "W/R"),
            };
            let row = (p.address, &p.name, &p.unit, access, low, high);
            out.append(public(py, PY, "PblParameter", row, None)?)?;
        }
        Ok(out)
    }

    /// The unit of each parameter by name, from :meth:`table` (``""`` for none).
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for p in table().map_err(|e| to_pyerr(py, e))? {
            out.set_item(&p.register.name, &p.register.unit)?;
        }
        Ok(out)
    }
}
