//! Bindings of [`crate::device::drive`]: the compiled base class of `benchbus.Drive`, which
//! adds only what belongs to Python (enums, the keepalive, reprs, the context manager).

use super::device_methods;
use super::{
    int_in, member, number, public, shown, standard_unit_arg, to_pyerr, Attached, PyBus, PyStation,
};
use crate::device::drive::{
    command_doc, drive_commands, fault_name, table as drive_table, Command, Drive, Family, Model,
    Telemetry,
};
use crate::device::{Access, Device, Tabled};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyList, PyTuple};

/// The Python module of the family's public types.
const PY: &str = "benchbus._drive";

/// The compiled base of `benchbus.Drive`: the register table and every call to the drive.
#[pyclass(extends = PyStation, subclass, frozen, module = "benchbus._core", name = "DriveCore")]
pub(super) struct PyDriveCore {
    dev: Attached<Drive>,
}

/// The drive family called `name`, or a ValueError naming the two.
fn family_arg(name: &str) -> PyResult<Family> {
    Family::from_name(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "family must be \"BLD\" (BLD2, BLD3H) or \"C20\", got {name:?}"
        ))
    })
}

/// The register table of `family` as `DriveRegister` rows.
fn table<'py>(py: Python<'py>, family: Family) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for r in &drive_table(family).map_err(|e| to_pyerr(py, e))?.registers {
        let r = &r.register;
        // A read-only register takes no write: its range is (0, 0).
        let ((low, high), access) = match r.access {
            Access::Read => ((0.0, 0.0), "R"),
            Access::ReadWrite => (r.range, "W/R"),
            Access::WriteWhenStopped => (r.range, "W/R*"),
            Access::Write => (r.range, "W"),
        };
        let row = (&r.name, r.address, r.scale, &r.unit, access, low, high);
        out.append(public(py, PY, "DriveRegister", row, None)?)?;
    }
    Ok(out)
}

/// `#[pymethods] impl PyDriveCore` with the methods given, plus one method per row of the
/// command table (`forward`, `stop`...) that sends its command.
macro_rules! with_command_methods {
    ({ $($methods:tt)* } $($variant:ident = $code:literal, $method:ident, $doc:literal;)*) => {
        device_methods! {
            PyDriveCore = |dev| PyDriveCore { dev };
            tabled;
            $($methods)*

            $(
                #[doc = command_doc!($doc, $code)]
                fn $method(&self, py: Python<'_>) -> PyResult<()> {
                    self.dev.wire(py, |d| d.command(Command::$variant))
                }
            )*
        }
    };
}

drive_commands!(with_command_methods! {
    /// Attaches the drive at `unit` (1..247) of `family` ("BLD" or "C20") to `bus` (what
    /// `Drive.__init__` does); `timeout` / `retries` replace the Bus's.
    #[pyo3(signature = (bus, unit, family, write_ack, timeout=None, retries=None))]
    fn _attach(
        slf: &Bound<'_, Self>,
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        family: &str,
        write_ack: bool,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let family = family_arg(family)?;
        let station = slf.as_super().get();
        slf.get().dev.attach(
            station,
            bus,
            unit,
            standard_unit_arg,
            timeout,
            retries,
            |b, u| Ok(Drive::new(b, u, family, write_ack)),
        )
    }

    /// "BLD" (BLD2, BLD3H) or "C20".
    #[getter]
    fn family(&self) -> PyResult<&'static str> {
        Ok(self.dev.device()?.family().name())
    }

    /// Whether writes are answered (False for a drive set to F08.06 = 1).
    #[getter]
    fn write_ack(&self) -> PyResult<bool> {
        Ok(self.dev.device()?.write_ack())
    }

    /// Reply timeout of the drive's requests, in seconds (its own, or the Bus's).
    #[getter]
    fn timeout(&self) -> PyResult<f64> {
        Ok(self.dev.device()?.station().timeout().as_secs_f64())
    }

    /// Retries of the drive's requests (its own, or the Bus's).
    #[getter]
    fn retries(&self) -> PyResult<u32> {
        Ok(self.dev.device()?.station().retries())
    }

    /// Whether the drive answers multi-register reads; None until one was tried.
    #[getter]
    fn block_reads(&self) -> PyResult<Option<bool>> {
        Ok(self.dev.device()?.block_reads())
    }

    /// What leaving a ``with`` block sends: a jog stop if this object started a jog, then
    /// the stop; ``urgent`` (leaving on an exception): each sent once, at once.
    #[pyo3(signature = (urgent=false))]
    fn _stop_on_exit(&self, py: Python<'_>, urgent: bool) -> PyResult<()> {
        self.dev.stop_on_exit(py, |d| d.stop_on_exit(urgent))
    }

    /// The command table: ``(name, code)`` of every value the command register 0x2000
    /// takes, in code order, the brake stop (BLD only) included; each is a method.
    #[staticmethod]
    fn commands() -> Vec<(&'static str, u16)> {
        Command::ALL.iter().map(|c| (c.name(), c.code())).collect()
    }

    /// Status words 1 and 2 and the fault code, read in one request where allowed.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let s = self.dev.wire(py, |d| d.status())?;
        let fault = if s.fault_code == 0 {
            py.None().into_bound(py)
        } else {
            public(py, PY, "Fault", (s.fault_code, fault_name(s.fault_code)), None)?
        };
        let args = (
            member(py, PY, "DriveState", s.state.into())?,
            s.bus_voltage_ready,
            s.overloaded,
            member(py, PY, "CommandSource", s.control_source.into())?,
            s.keypad_connected,
            fault,
        );
        public(py, PY, "DriveStatus", args, None)
    }

    /// The model an identification code (0x2103) names on a drive of ``family``: "BLD2",
    /// "BLD3H" or "C20", or None for a code the manuals do not list.
    #[staticmethod]
    fn model_from_id(family: &str, id: &Bound<'_, PyAny>) -> PyResult<Option<&'static str>> {
        let family = family_arg(family)?;
        let id = int_in(id, "id", 0, 0xFFFF)? as u16;
        Ok(Model::from_id(family, id).map(Model::name))
    }

    /// The model table: ``(name, identification code, family)`` of each model the manuals
    /// name.
    #[staticmethod]
    fn models() -> Vec<(&'static str, u16, &'static str)> {
        Model::ALL
            .iter()
            .map(|m| (m.name(), m.id(), m.family().name()))
            .collect()
    }

    /// The model from 0x2103 (a ``Model``), or the raw code if unknown.
    fn _model<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match self.dev.wire(py, |d| d.model())? {
            Ok(model) => public(py, PY, "Model", (model.name(),), None),
            Err(id) => Ok(PyInt::new(py, id).into_any()),
        }
    }

    /// The names :meth:`sample` gives: the fields of :meth:`telemetry`.
    #[classattr]
    #[allow(non_snake_case)]
    fn SAMPLE_FIELDS<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, Telemetry::fields().map_err(|e| to_pyerr(py, e))?)
    }

    /// All measurement registers in one snapshot (one request where the drive allows).
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = self.dev.wire(py, |d| d.telemetry())?;
        let rows = &drive_table(Family::Bld).map_err(|e| to_pyerr(py, e))?.registers;
        let fields = PyDict::new(py);
        let units = PyDict::new(py);
        for (name, raw, unit) in &t.values {
            match rows.iter().find(|r| r.register.name == *name) {
                Some(r) => fields.set_item(*name, shown(py, &r.register, *raw))?,
                None => fields.set_item(*name, *raw)?,
            }
            units.set_item(*name, *unit)?;
        }
        fields.set_item("hall_count", t.hall_count)?;
        fields.set_item("units", units)?;
        public(py, PY, "DriveTelemetry", (), Some(&fields))
    }

    /// The numeric fields of :meth:`telemetry` as floats (one request where the drive
    /// allows); ``hall_count`` only where the drive has it.
    fn sample<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.dev.wire(py, |d| d.telemetry())?;
        let out = PyDict::new(py);
        for (name, raw, _) in &t.values {
            out.set_item(*name, *raw)?;
        }
        if let Some(count) = t.hall_count {
            out.set_item("hall_count", f64::from(count))?;
        }
        Ok(out)
    }

    /// The line speed the drive has stored (0x2009), in bits per second (the raw code if
    /// the manuals do not list it).
    #[getter]
    fn baud_rate(&self, py: Python<'_>) -> PyResult<u32> {
        self.dev.wire(py, |d| match d.baud_rate()? {
            Some(bps) => Ok(bps),
            None => Ok(d.get("baud_code")? as u32),
        })
    }

    /// Store a new line speed (0x2009; stopped only): 1200..115200 (C20 up to 57600).
    ///
    /// The drive talks at the new speed from then on: open a new Bus at it.
    fn set_baud_rate(&self, py: Python<'_>, bps: &Bound<'_, PyAny>) -> PyResult<()> {
        let bps = int_in(bps, "baud rate", 0, i64::from(u32::MAX))? as u32;
        self.dev.wire(py, move |d| d.set_baud_rate(bps))
    }

    /// The raw value of function-code parameter ``code``, e.g. ``"F00.10"``.
    ///
    /// Fgg.nn lives at ``gg << 8 | nn``; a parameter the drive lacks raises
    /// :class:`benchbus.ModbusException` (code 2).
    fn read_parameter(&self, py: Python<'_>, code: &str) -> PyResult<u16> {
        let code = code.to_string();
        self.dev.wire(py, move |d| d.read_parameter(&code))
    }

    /// Write the raw ``value`` (0..0xFFFF) to function-code parameter ``code``.
    ///
    /// Sets the write enable 0x200E to 1 first when it is not, and puts it back afterwards,
    /// also when the write fails; a refusal raises :class:`benchbus.ModbusException` naming
    /// the parameter (0x03 out of range, 0x08 not while running...).
    fn write_parameter(
        &self,
        py: Python<'_>,
        code: &str,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let value = int_in(value, "value", 0, 0xFFFF)? as u16;
        let code = code.to_string();
        self.dev.wire(py, move |d| d.write_parameter(&code, value))
    }

    /// Reads the setting called ``name`` (a function-code parameter in engineering units,
    /// "comm_loss_timeout" for F08.04).
    fn read_setting(&self, py: Python<'_>, name: &str) -> PyResult<f64> {
        let name = name.to_string();
        self.dev.wire(py, move |d| d.read_setting(&name))
    }

    /// Writes ``value`` (engineering units) to the setting called ``name``, enabling 0x200E
    /// around it; the value and the family are checked before anything is sent.
    fn write_setting(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let value = number(value, name)?;
        let name = name.to_string();
        self.dev.wire(py, move |d| d.write_setting(&name, value))
    }

    /// The register table of this drive's family: a ``DriveRegister`` ``(name, address,
    /// scale, unit, access, low, high)`` for each register; access is "R", "W/R" or "W/R*".
    fn registers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        table(py, self.dev.device()?.family())
    }

    /// The register table of ``family`` ("BLD" or "C20"), as :meth:`registers` gives it,
    /// without a drive (for the command line's argument ranges).
    #[staticmethod]
    fn _table<'py>(py: Python<'py>, family: &str) -> PyResult<Bound<'py, PyList>> {
        table(py, family_arg(family)?)
    }

    /// The unit of each register by name, from :meth:`registers` (``""`` for none).
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        let family = self.dev.device()?.family();
        for r in &drive_table(family).map_err(|e| to_pyerr(py, e))?.registers {
            out.set_item(&r.register.name, &r.register.unit)?;
        }
        Ok(out)
    }
});
