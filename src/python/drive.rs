//! Bindings of [`crate::device::drive`]: the register-level core that `benchbus.Drive`
//! (Python) wraps with enums, dataclasses and the context manager.

use super::{int_in, number, on_wire, own_timing, standard_unit_arg, to_pyerr, PyBus};
use crate::device::drive::{fault_name, Command, Drive, Family, Model, REGISTERS};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt, PyList};
use std::sync::Arc;

/// The register-level core of a BLD2 / BLD3H / ZBLD.C20 drive (see `benchbus.Drive`).
#[pyclass(frozen, module = "benchbus._core", name = "DriveCore")]
pub(super) struct PyDriveCore {
    drive: Arc<Drive>,
    bus: Py<PyBus>,
}

impl PyDriveCore {
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&Drive) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        on_wire(py, &self.drive, f)
    }
}

/// The drive family called `name`, or a ValueError naming the two.
fn family_arg(name: &str) -> PyResult<Family> {
    Family::from_name(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "family must be \"BLD\" (BLD2, BLD3H) or \"C20\", got {name:?}"
        ))
    })
}

/// A number argument (int or float, not bool or str) as f64.
#[pymethods]
impl PyDriveCore {
    #[new]
    #[pyo3(signature = (bus, unit, family, write_ack, timeout=None, retries=None))]
    fn new(
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        family: &str,
        write_ack: bool,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let unit = standard_unit_arg(unit)?;
        let family = family_arg(family)?;
        let (timeout, retries) = own_timing(timeout, retries)?;
        let core = Arc::clone(&bus.get().bus);
        let drive = Drive::new(core, unit, family, write_ack).with_timing(timeout, retries);
        Ok(PyDriveCore {
            drive: Arc::new(drive),
            bus: bus.unbind(),
        })
    }

    /// The Bus the drive talks through.
    #[getter]
    fn bus(&self, py: Python<'_>) -> Py<PyBus> {
        self.bus.clone_ref(py)
    }

    /// The drive's unit address.
    #[getter]
    fn unit(&self) -> u8 {
        self.drive.unit()
    }

    /// "BLD" or "C20".
    #[getter]
    fn family(&self) -> &'static str {
        self.drive.family().name()
    }

    /// Whether writes are answered (False for a drive set to F08.06 = 1).
    #[getter]
    fn write_ack(&self) -> bool {
        self.drive.write_ack()
    }

    /// Reply timeout of the drive's requests, in seconds (its own, or the Bus's).
    #[getter]
    fn timeout(&self) -> f64 {
        self.drive.timeout().as_secs_f64()
    }

    /// Retries of the drive's requests (its own, or the Bus's).
    #[getter]
    fn retries(&self) -> u32 {
        self.drive.retries()
    }

    /// Whether the drive answers multi-register reads; None until one was tried.
    #[getter]
    fn block_reads(&self) -> Option<bool> {
        self.drive.block_reads()
    }

    /// Reads the register called `name`: an int, or a float for a scaled register.
    fn get<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let register = self.drive.register(name).map_err(|e| to_pyerr(py, e))?;
        let name = name.to_string();
        let value = self.wire(py, move |d| d.get(&name))?;
        if register.is_integer() {
            Ok(PyInt::new(py, value as i64).into_any())
        } else {
            Ok(PyFloat::new(py, value).into_any())
        }
    }

    /// Writes `value` (engineering units) to the register called `name`.
    fn set(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let value = number(value, name)?;
        let name = name.to_string();
        self.wire(py, move |d| d.set(&name, value))
    }

    /// Sends the command called `name` ("forward", see `commands()`) to 0x2000.
    fn command(&self, py: Python<'_>, name: &str) -> PyResult<()> {
        let command = Command::from_name(name).ok_or_else(|| {
            let names: Vec<_> = Command::ALL.iter().map(|c| c.name()).collect();
            PyValueError::new_err(format!(
                "no drive command {name:?}; the commands are {}",
                names.join(", ")
            ))
        })?;
        self.wire(py, move |d| d.command(command))
    }

    /// The command table: `(name, code)` of every value the command register 0x2000 takes,
    /// in code order, the brake stop (BLD only) included.
    #[staticmethod]
    fn commands() -> Vec<(&'static str, u16)> {
        Command::ALL.iter().map(|c| (c.name(), c.code())).collect()
    }

    /// 0x2100..0x2102 decoded: a dict of state, bus_voltage_ready, overloaded,
    /// control_source, keypad_connected, fault_code and fault_name.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.wire(py, |d| d.status())?;
        let out = PyDict::new(py);
        out.set_item("state", s.state)?;
        out.set_item("bus_voltage_ready", s.bus_voltage_ready)?;
        out.set_item("overloaded", s.overloaded)?;
        out.set_item("control_source", s.control_source)?;
        out.set_item("keypad_connected", s.keypad_connected)?;
        out.set_item("fault_code", s.fault_code)?;
        out.set_item("fault_name", fault_name(s.fault_code))?;
        Ok(out)
    }

    /// The model an identification code (0x2103) names on a drive of `family`: "BLD2",
    /// "BLD3H" or "C20", or None for a code the manuals do not list.
    #[staticmethod]
    fn model_from_id(family: &str, id: &Bound<'_, PyAny>) -> PyResult<Option<&'static str>> {
        let family = family_arg(family)?;
        let id = int_in(id, "id", 0, 0xFFFF)? as u16;
        Ok(Model::from_id(family, id).map(Model::name))
    }

    /// The model table: `(name, identification code, family)` of each model the manuals
    /// name.
    #[staticmethod]
    fn models() -> Vec<(&'static str, u16, &'static str)> {
        Model::ALL
            .iter()
            .map(|m| (m.name(), m.id(), m.family().name()))
            .collect()
    }

    /// The model name from 0x2103 ("BLD2", "BLD3H", "C20"), or the raw code if unknown.
    fn model<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(match self.wire(py, |d| d.model())? {
            Ok(model) => model.name().into_pyobject(py)?.into_any(),
            Err(id) => id.into_pyobject(py)?.into_any(),
        })
    }

    /// One snapshot of 0x3000..: `{name: value}` in engineering units, plus `hall_count`
    /// (None on the C20).
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.wire(py, |d| d.telemetry())?;
        let out = PyDict::new(py);
        let units = PyDict::new(py);
        for (name, value, _) in &t.values {
            let integer = REGISTERS
                .iter()
                .any(|r| r.register.name == *name && r.register.is_integer());
            if integer {
                out.set_item(*name, *value as i64)?;
            } else {
                out.set_item(*name, *value)?;
            }
        }
        for (name, _, unit) in &t.values {
            units.set_item(*name, *unit)?;
        }
        out.set_item("hall_count", t.hall_count)?;
        out.set_item("units", units)?;
        Ok(out)
    }

    /// The line speed stored in 0x2009, in bits per second (None for an unlisted code).
    fn baud_rate(&self, py: Python<'_>) -> PyResult<Option<u32>> {
        self.wire(py, |d| d.baud_rate())
    }

    /// Stores a new line speed in 0x2009, in bits per second.
    fn set_baud_rate(&self, py: Python<'_>, bps: &Bound<'_, PyAny>) -> PyResult<()> {
        let bps = int_in(bps, "baud rate", 0, i64::from(u32::MAX))? as u32;
        self.wire(py, move |d| d.set_baud_rate(bps))
    }

    /// The raw value of function-code parameter `code` ("F00.10").
    fn read_parameter(&self, py: Python<'_>, code: &str) -> PyResult<u16> {
        let code = code.to_string();
        self.wire(py, move |d| d.read_parameter(&code))
    }

    /// Writes the raw `value` to function-code parameter `code`, enabling 0x200E around it.
    fn write_parameter(
        &self,
        py: Python<'_>,
        code: &str,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let value = int_in(value, "value", 0, 0xFFFF)? as u16;
        crate::device::drive::parameter_address(code).map_err(|e| to_pyerr(py, e))?;
        let code = code.to_string();
        self.wire(py, move |d| d.write_parameter(&code, value))
    }

    /// Reads the setting called `name` (a function-code parameter in engineering units,
    /// "comm_loss_timeout" for F08.04).
    fn read_setting(&self, py: Python<'_>, name: &str) -> PyResult<f64> {
        self.drive.setting(name).map_err(|e| to_pyerr(py, e))?;
        let name = name.to_string();
        self.wire(py, move |d| d.read_setting(&name))
    }

    /// Writes `value` (engineering units) to the setting called `name`, enabling 0x200E
    /// around it; the value and the family are checked before anything is sent.
    fn write_setting(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let value = number(value, name)?;
        let name = name.to_string();
        self.wire(py, move |d| d.write_setting(&name, value))
    }

    /// The register table: `(name, address, scale, unit, access, low, high)` for each
    /// register of this family; access is "R", "W/R" or "W/R*".
    fn registers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for entry in REGISTERS {
            let Ok(r) = self.drive.register(entry.register.name) else {
                continue;
            };
            let access = match r.access {
                crate::device::Access::Read => "R",
                crate::device::Access::ReadWrite => "W/R",
                crate::device::Access::WriteWhenStopped => "W/R*",
            };
            out.append((
                r.name, r.address, r.scale, r.unit, access, r.range.0, r.range.1,
            ))?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "DriveCore(unit={}, family='{}', write_ack={})",
            self.drive.unit(),
            self.drive.family().name(),
            if self.drive.write_ack() {
                "True"
            } else {
                "False"
            }
        )
    }
}
