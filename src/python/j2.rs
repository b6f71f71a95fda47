//! Bindings of [`crate::device::j2`]: the compiled base class of `benchbus.J2Controller`,
//! which adds only what belongs to Python (enums, the status object, named tuples, reprs).

use super::device_methods;
use super::{
    int_choice, listed, member, named, named_pairs, number, public, row_name, shown, to_pyerr,
    Attached, PyBus, PyStation,
};

/// The Python module of the family's public types.
const PY: &str = "benchbus._j2";
use crate::device::j2::{
    by_name, table, HELD_TO_LIMITS, J2, LIMITS, PID, PID2, RAPNF, SAMPLE, STATUS,
};
use crate::device::{Access, Register, Tabled};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt, PyList, PyString, PyTuple};

/// The compiled base of `benchbus.J2Controller`: the parameter table, the manual's rules and
/// every call to the controller.
#[pyclass(extends = PyStation, subclass, frozen, module = "benchbus._core", name = "J2Core")]
pub(super) struct PyJ2Core {
    dev: Attached<J2>,
}

impl PyJ2Core {
    /// The parameters called `names`, as Python has them, in as few requests as allowed.
    fn read_names<'py, N: std::borrow::Borrow<Bound<'py, PyAny>>>(
        &self,
        py: Python<'py>,
        names: &[N],
    ) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let params = names
            .iter()
            .map(|n| param(py, n.borrow()))
            .collect::<PyResult<Vec<_>>>()?;
        let wanted: Vec<&'static str> = params.iter().map(|p| p.name.as_str()).collect();
        let values = self.dev.wire(py, move |j| j.get_many(&wanted))?;
        Ok(params
            .iter()
            .zip(values)
            .map(|(p, v)| shown(py, p, v))
            .collect())
    }

    /// Writes `value`, a sequence of as many numbers as `group` has names, to the group's
    /// parameters, as `write_many` does.
    fn write_group<const N: usize>(
        &self,
        py: Python<'_>,
        group: &[&'static str; N],
        value: &Bound<'_, PyAny>,
        name: &str,
        what: &str,
    ) -> PyResult<()> {
        let values: [Bound<'_, PyAny>; N] = sized(value, name, what)?;
        let pairs = group
            .iter()
            .zip(&values)
            .map(|(p, v)| Ok((*p, number(v, p)?)))
            .collect::<PyResult<Vec<_>>>()?;
        self.dev.wire(py, move |j| j.set_many(&pairs))
    }

    /// The parameters of `group` (a table of the core), as Python has them.
    fn read_group<'py>(&self, py: Python<'py>, group: &[&str]) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let names: Vec<Bound<'py, PyAny>> = group
            .iter()
            .map(|n| PyString::new(py, n).into_any())
            .collect();
        self.read_names(py, &names)
    }

    /// The parameters of `group`, read in one request, as the `benchbus._j2` type `kind`.
    fn read_as<'py>(
        &self,
        py: Python<'py>,
        group: &[&str],
        kind: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        public(
            py,
            PY,
            kind,
            PyTuple::new(py, self.read_group(py, group)?)?,
            None,
        )
    }
}

/// A parameter name (str), checked against the table.
fn param(py: Python<'_>, name: &Bound<'_, PyAny>) -> PyResult<&'static Register<String>> {
    by_name(&row_name(name)?).map_err(|e| to_pyerr(py, e))
}

/// `obj` as exactly `N` items: TypeError as [`listed`] says, ValueError for another count
/// ("limits are two numbers (low, high), got 3").
fn sized<'py, const N: usize>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<[Bound<'py, PyAny>; N]> {
    let items = listed(obj, name, what)?;
    let count = items.len();
    items.try_into().map_err(|_| {
        let verb = if name.starts_with("a ") { "is" } else { "are" };
        PyValueError::new_err(format!("{name} {verb} {what}, got {count}"))
    })
}

/// `False`, the default of a flag that must be a bool when given.
fn py_false() -> Py<PyAny> {
    Python::attach(|py| PyBool::new(py, false).to_owned().into_any().unbind())
}

/// 6 (function 0x06), the default of `write`'s `function`.
fn py_six() -> Py<PyAny> {
    Python::attach(|py| PyInt::new(py, 0x06).into_any().unbind())
}

device_methods! {
PyJ2Core = |dev| PyJ2Core { dev };
attach = J2::new;
tabled;


    /// One parameter by its manual name ("SV", "AL1", "INP"; any case): a float for the
    /// signed table, an int for the unsigned one (a member of its enum, as :meth:`get`).
    fn read<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        name: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        Self::get(slf, py, name)
    }

    /// Write one parameter by name, with the manual's rules (see the class).
    ///
    /// ``function`` is 0x06 (write single register) or 0x10 (write multiple registers,
    /// here one); the manual shows both for SV.
    #[pyo3(signature = (name, value, *, function=py_six()), text_signature = "($self, name, value, *, function=6)")]
    fn write(
        &self,
        py: Python<'_>,
        name: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        function: Py<PyAny>,
    ) -> PyResult<()> {
        let choices = [(0x06, false), (0x10, true)];
        let function = function.bind(py);
        let multiple = int_choice(function, "function", "an int", "0x06 or 0x10", &choices)?;
        let p = param(py, name)?;
        let v = number(value, &p.name)?;
        self.dev.wire(py, move |j| j.set_as(&p.name, v, multiple))
    }

    /// Several parameters by name, in as few requests as the 16-register limit allows (each
    /// as :meth:`read` gives it).
    fn read_many<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        names: &Bound<'py, PyAny>,
    ) -> PyResult<Vec<Bound<'py, PyAny>>> {
        if names.is_instance_of::<PyString>() {
            return Err(PyTypeError::new_err(
                "names is a list of names ([\"SV\", \"PV\"]), not one str",
            ));
        }
        let names = listed(names, "names", "a list of names ([\"SV\", \"PV\"])")?;
        let values = slf.get().read_names(py, &names)?;
        names
            .iter()
            .zip(values)
            .map(|(name, value)| named(slf.as_any(), &param(py, name)?.name, value))
            .collect()
    }

    /// Write several parameters in order, each as :meth:`write` does.
    ///
    /// ``values`` is ``{name: value}`` or ``(name, value)`` pairs. Every value is checked
    /// against its fixed range before the first is sent; the checks that need the
    /// controller (SV within its limits, MV in manual mode) are made write by write, so a
    /// refusal there leaves the earlier writes done.
    fn write_many(&self, py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut pairs = Vec::new();
        for (name, value) in named_pairs(py, values)? {
            let p = by_name(&name).map_err(|e| to_pyerr(py, e))?;
            pairs.push((p.name.as_str(), number(&value, &p.name)?));
        }
        self.dev.wire(py, move |j| j.set_many(&pairs))
    }

    /// Every parameter, `{name: value}`, in six requests of at most 16 registers.
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let all = self.dev.wire(py, |j| j.parameters())?;
        let out = PyDict::new(py);
        for (name, v) in all {
            let p = by_name(name).map_err(|e| to_pyerr(py, e))?;
            out.set_item(name, shown(py, p, v))?;
        }
        Ok(out)
    }

    /// Set the output MV to ``percent`` (0..100).
    ///
    /// The manual allows MV only in manual mode: in automatic mode this raises
    /// :class:`~benchbus.StateError`, unless ``switch_to_manual`` (then AM is written 0
    /// first, and the controller stays in manual mode).
    #[pyo3(signature = (percent, switch_to_manual=py_false()), text_signature = "($self, percent, switch_to_manual=False)")]
    fn set_output(
        &self,
        py: Python<'_>,
        percent: &Bound<'_, PyAny>,
        switch_to_manual: Py<PyAny>,
    ) -> PyResult<()> {
        let switch_to_manual = switch_to_manual.bind(py);
        if !switch_to_manual.is_instance_of::<PyBool>() {
            return Err(PyTypeError::new_err(format!(
                "switch_to_manual must be True or False, got {}",
                switch_to_manual.get_type().name()?
            )));
        }
        let switch_to_manual = switch_to_manual.extract::<bool>()?;
        let percent = number(percent, "MV")?;
        self.dev
            .wire(py, move |j| j.set_output(percent, switch_to_manual))
    }

    /// Writes LSP and USP in the order that keeps LSP <= USP.
    fn _set_limits(
        &self,
        py: Python<'_>,
        low: &Bound<'_, PyAny>,
        high: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (low, high) = (number(low, "LSP")?, number(high, "USP")?);
        self.dev.wire(py, move |j| j.set_limits(low, high))
    }

    /// Start the setpoint ramp (RAPNF = 1).
    fn start_ramp(&self, py: Python<'_>) -> PyResult<()> {
        self.dev.wire(py, |j| j.set(RAPNF, 1.0))
    }

    /// End the setpoint ramp (RAPNF = 0).
    fn stop_ramp(&self, py: Python<'_>) -> PyResult<()> {
        self.dev.wire(py, |j| j.set(RAPNF, 0.0))
    }

    /// The names :meth:`sample` gives: ``pv``, ``sv``, ``mv``.
    #[classattr]
    #[allow(non_snake_case)]
    fn SAMPLE_FIELDS<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, SAMPLE.map(str::to_lowercase))
    }

    /// PV, SV and MV (``{"pv": .., "sv": .., "mv": ..}``), in one request.
    fn sample<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let values = self.read_group(py, &SAMPLE)?;
        let out = PyDict::new(py);
        for (name, v) in SAMPLE.iter().zip(values) {
            out.set_item(name.to_lowercase(), v.extract::<f64>()?)?;
        }
        Ok(out)
    }

    /// PV, SV, MV, mode, autotune, ramp and alarm values, in two requests.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut fields = self.read_group(py, &STATUS)?;
        // STATUS is in the status object's field order: mode, then the two flags.
        fields[3] = member(py, PY, "J2Mode", fields[3].extract()?)?;
        for flag in &mut fields[4..6] {
            *flag = PyBool::new(py, flag.is_truthy()?).to_owned().into_any();
        }
        public(py, PY, "J2Status", PyTuple::new(py, fields)?, None)
    }

    /// The first PID set (P, I, D), read in one request; set it with a 3-tuple.
    #[getter]
    fn pid<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.read_as(py, &PID, "Pid")
    }

    #[setter]
    fn set_pid(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.write_group(py, &PID, value, "a PID set", "three numbers (P, I, D)")
    }

    /// The second PID set (P1, I1, D1), read in one request; set it with a 3-tuple.
    #[getter]
    fn pid2<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.read_as(py, &PID2, "Pid")
    }

    #[setter]
    fn set_pid2(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.write_group(py, &PID2, value, "a PID set", "three numbers (P, I, D)")
    }

    /// The setpoint limits (LSP, USP), read in one request. Set them with a ``(low, high)``
    /// pair: they are written in the order that keeps LSP <= USP.
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.read_as(py, &LIMITS, "Limits")
    }

    #[setter]
    fn set_limits(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let [low, high] = sized(value, "limits", "two numbers (low, high)")?;
        let (low, high) = (number(&low, "LSP")?, number(&high, "USP")?);
        self.dev.wire(py, move |j| j.set_limits(low, high))
    }

    /// The parameter table: a :class:`~benchbus.J2Parameter` (name, address, signed,
    /// writable, low, high, within_limits) for each parameter.
    #[staticmethod]
    fn table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for p in table().map_err(|e| to_pyerr(py, e))? {
            let p = &p.register;
            let row = (
                &p.name,
                p.address,
                p.signed,
                p.access != Access::Read,
                p.range.0,
                p.range.1,
                p.name == HELD_TO_LIMITS,
            );
            out.append(public(py, PY, "J2Parameter", row, None)?)?;
        }
        Ok(out)
    }

    /// The unit of each parameter by its manual name (``"PV"``), from the family's table
    /// (``""`` for none; a linear input, INP = LN, reads in its own scale, not °C).
    #[staticmethod]
    fn units<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for p in table().map_err(|e| to_pyerr(py, e))? {
            out.set_item(&p.register.name, &p.register.unit)?;
        }
        Ok(out)
    }
}
