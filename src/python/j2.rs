//! Bindings of [`crate::device::j2`]: the parameter-level core that `benchbus.J2Controller`
//! (Python) wraps with enums and properties.

use super::{number, to_pyerr, Attached, PyBus};
use crate::device::j2::{by_name, Param, J2, PARAMETERS};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt, PyList, PyString};

/// The parameter-level core of a J2 controller (see `benchbus.J2Controller`).
#[pyclass(frozen, module = "benchbus._core", name = "J2Core")]
pub(super) struct PyJ2Core {
    dev: Attached<J2>,
}

impl PyJ2Core {
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&J2) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        self.dev.wire(py, f)
    }
}

/// A parameter name (str), checked against the table.
fn param(py: Python<'_>, name: &Bound<'_, PyAny>) -> PyResult<&'static Param> {
    if !name.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "a J2 parameter is named by a str (\"SV\"), got {}",
            name.get_type().name()?
        )));
    }
    by_name(&name.extract::<String>()?).map_err(|e| to_pyerr(py, e))
}

/// A value as Python has it: an int for the unsigned table, a float for the signed one.
fn value<'py>(py: Python<'py>, p: &Param, v: f64) -> Bound<'py, PyAny> {
    if p.signed {
        PyFloat::new(py, v).into_any()
    } else {
        PyInt::new(py, v as i64).into_any()
    }
}

#[pymethods]
impl PyJ2Core {
    #[new]
    #[pyo3(signature = (bus, unit, timeout=None, retries=None))]
    fn new(
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let dev = Attached::new(bus, unit, timeout, retries, |b, u| Ok(J2::new(b, u)))?;
        Ok(PyJ2Core { dev })
    }

    /// The Bus the controller talks through.
    #[getter]
    fn bus(&self, py: Python<'_>) -> Py<PyBus> {
        self.dev.bus(py)
    }

    /// The controller's unit address.
    #[getter]
    fn unit(&self) -> u8 {
        self.dev.unit()
    }

    /// Reads the parameter called `name`.
    fn get<'py>(&self, py: Python<'py>, name: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let p = param(py, name)?;
        let v = self.wire(py, move |j| j.read(p.name))?;
        Ok(value(py, p, v))
    }

    /// Writes `value` to the parameter called `name` with function 0x06, or 0x10 if
    /// `multiple`, with the manual's rules.
    #[pyo3(signature = (name, value, multiple=false))]
    fn write(
        &self,
        py: Python<'_>,
        name: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        multiple: bool,
    ) -> PyResult<()> {
        let p = param(py, name)?;
        let v = number(value, p.name)?;
        self.wire(py, move |j| j.write_as(p.name, v, multiple))
    }

    /// Writes `value` to the parameter called `name`, with the manual's rules.
    fn set(
        &self,
        py: Python<'_>,
        name: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let p = param(py, name)?;
        let v = number(value, p.name)?;
        self.wire(py, move |j| j.write(p.name, v))
    }

    /// Reads the parameters called `names`, in as few requests as allowed.
    fn read_many<'py>(
        &self,
        py: Python<'py>,
        names: Vec<Bound<'py, PyAny>>,
    ) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let params = names
            .iter()
            .map(|n| param(py, n))
            .collect::<PyResult<Vec<_>>>()?;
        let wanted: Vec<&'static str> = params.iter().map(|p| p.name).collect();
        let values = self.wire(py, move |j| j.read_many(&wanted))?;
        Ok(params
            .iter()
            .zip(values)
            .map(|(p, v)| value(py, p, v))
            .collect())
    }

    /// Writes `(name, value)` pairs in order; fixed ranges are checked before the first is
    /// sent, the checks that need the controller write by write.
    fn write_many(
        &self,
        py: Python<'_>,
        pairs: Vec<(Bound<'_, PyAny>, Bound<'_, PyAny>)>,
    ) -> PyResult<()> {
        let values = pairs
            .iter()
            .map(|(n, v)| {
                let p = param(py, n)?;
                Ok((p.name, number(v, p.name)?))
            })
            .collect::<PyResult<Vec<_>>>()?;
        self.wire(py, move |j| j.write_many(&values))
    }

    /// Every parameter, `{name: value}`, in six requests of at most 16 registers.
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.wire(py, |j| j.parameters())?;
        let out = PyDict::new(py);
        for (name, v) in all {
            let p = by_name(name).map_err(|e| to_pyerr(py, e))?;
            out.set_item(name, value(py, p, v))?;
        }
        Ok(out)
    }

    /// Writes MV; in automatic mode refused, or AM written 0 first if `switch_to_manual`.
    fn set_output(
        &self,
        py: Python<'_>,
        percent: &Bound<'_, PyAny>,
        switch_to_manual: bool,
    ) -> PyResult<()> {
        let percent = number(percent, "MV")?;
        self.wire(py, move |j| j.set_output(percent, switch_to_manual))
    }

    /// Writes LSP and USP in the order that keeps LSP <= USP.
    fn set_limits(
        &self,
        py: Python<'_>,
        low: &Bound<'_, PyAny>,
        high: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (low, high) = (number(low, "LSP")?, number(high, "USP")?);
        self.wire(py, move |j| j.set_limits(low, high))
    }

    /// The parameter table: `(name, address, signed, writable, low, high, within_limits)`.
    #[staticmethod]
    fn table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for p in &PARAMETERS {
            let (lo, hi) = p.register().range;
            out.append((
                p.name,
                p.address,
                p.signed,
                p.writable,
                lo,
                hi,
                p.within_limits,
            ))?;
        }
        Ok(out)
    }

    /// The unit of each parameter by name ("" for none): `{"MV": "%", "PV": "°C", ...}`.
    #[staticmethod]
    fn units<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for p in &PARAMETERS {
            out.set_item(p.name, p.unit)?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!("J2Core(unit={})", self.dev.unit())
    }
}
