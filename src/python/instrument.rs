//! Bindings of [`crate::device::instrument`]: the core that `benchbus.Instrument` (Python)
//! wraps.

use super::{int_in, number, opt, register_list, seconds, to_pyerr, u16_arg, Attached, PyBus};
use crate::device::instrument::{Instrument, WordOrder};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyFloat, PyInt, PyString};
use std::collections::BTreeMap;
use std::time::Duration;

/// The core of a generic instrument (see `benchbus.Instrument`).
#[pyclass(frozen, module = "benchbus._core", name = "InstrumentCore")]
pub(super) struct PyInstrumentCore {
    dev: Attached<Instrument>,
}

impl PyInstrumentCore {
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&Instrument) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        self.dev.wire(py, f)
    }
}

fn word_order(obj: &Bound<'_, PyAny>) -> PyResult<WordOrder> {
    if !obj.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "word_order must be \"big\" or \"little\", got {}",
            obj.get_type().name()?
        )));
    }
    match obj.extract::<String>()?.as_str() {
        "big" => Ok(WordOrder::HighFirst),
        "little" => Ok(WordOrder::LowFirst),
        other => Err(PyValueError::new_err(format!(
            "word_order must be \"big\" (high word first) or \"little\" (low word first), \
             got {other:?}"
        ))),
    }
}

fn decimals_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<u8> {
    opt(obj, 0, |d| int_in(d, "decimals", 0, 9).map(|d| d as u8))
}

/// A count of registers from `address`: 1 up to what fits below 0x10000.
fn count_arg(obj: &Bound<'_, PyAny>, address: u16) -> PyResult<usize> {
    let most = 0x1_0000 - i64::from(address);
    int_in(obj, "count", 1, most).map(|n| n as usize)
}

/// The first register of a 32-bit value: 0..=0xFFFE, so that the second one exists too.
fn pair_address(obj: &Bound<'_, PyAny>) -> PyResult<u16> {
    int_in(obj, "address", 0, 0xFFFE).map(|a| a as u16)
}

/// The function a single-register write uses: 0x06, or 0x10 (true).
fn function_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<bool> {
    opt(obj, false, |f| match int_in(f, "function", 0, 255)? {
        0x06 => Ok(false),
        0x10 => Ok(true),
        other => Err(PyValueError::new_err(format!(
            "function must be 6 (0x06) or 16 (0x10), got {other}"
        ))),
    })
}

#[pymethods]
impl PyInstrumentCore {
    #[new]
    #[pyo3(signature = (bus, unit, max_read, max_write, min_write_interval, timeout=None, retries=None))]
    fn new(
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        max_read: &Bound<'_, PyAny>,
        max_write: &Bound<'_, PyAny>,
        min_write_interval: &Bound<'_, PyAny>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let max_read = int_in(max_read, "max_read", 1, 125)? as u16;
        let max_write = int_in(max_write, "max_write", 1, 123)? as u16;
        let interval: Duration = seconds(min_write_interval, "min_write_interval", true)?;
        let dev = Attached::new(bus, unit, timeout, retries, |b, u| {
            Instrument::new(b, u, max_read, max_write, interval)
        })?;
        Ok(PyInstrumentCore { dev })
    }

    /// The Bus the instrument talks through.
    #[getter]
    fn bus(&self, py: Python<'_>) -> Py<PyBus> {
        self.dev.bus(py)
    }

    /// The instrument's unit address.
    #[getter]
    fn unit(&self) -> u8 {
        self.dev.unit()
    }

    /// Most registers one read asks for.
    #[getter]
    fn max_read(&self) -> u16 {
        self.dev.device().max_read()
    }

    /// Most registers one write carries.
    #[getter]
    fn max_write(&self) -> u16 {
        self.dev.device().max_write()
    }

    /// Least time between two writes, seconds.
    #[getter]
    fn min_write_interval(&self) -> f64 {
        self.dev.device().min_write_interval().as_secs_f64()
    }

    /// `count` registers from `address`, in requests of at most `max_read`.
    fn read_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        self.wire(py, move |i| i.read_registers(address, count))
    }

    /// Writes `values` from `address`, in requests of at most `max_write`.
    fn write_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let address = u16_arg(address, "address")?;
        let values = register_list(values, 0x1_0000 - usize::from(address))?;
        self.wire(py, move |i| i.write_registers(address, &values))
    }

    /// One register as a value: an int without decimals, a float with.
    #[pyo3(signature = (address, decimals=None, signed=false))]
    fn read_register<'py>(
        &self,
        py: Python<'py>,
        address: &Bound<'py, PyAny>,
        decimals: Option<&Bound<'py, PyAny>>,
        signed: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let address = u16_arg(address, "address")?;
        let decimals = decimals_arg(decimals)?;
        let v = self.wire(py, move |i| i.read_value(address, decimals, signed))?;
        Ok(if decimals == 0 {
            PyInt::new(py, v as i64).into_any()
        } else {
            PyFloat::new(py, v).into_any()
        })
    }

    /// Writes one register's value (with 0x06, or 0x10 if `function` is 16).
    #[pyo3(signature = (address, value, decimals=None, signed=false, function=None))]
    fn write_register(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        decimals: Option<&Bound<'_, PyAny>>,
        signed: bool,
        function: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let address = u16_arg(address, "address")?;
        let value = number(value, "value")?;
        let decimals = decimals_arg(decimals)?;
        let multiple = function_arg(function)?;
        // The core's message says what does not fit; the argument it is about is `value`.
        let raw =
            crate::device::instrument::to_raw(value, decimals, signed).map_err(|e| match e {
                crate::Error::InvalidArgument(m) => PyValueError::new_err(format!("value {m}")),
                e => to_pyerr(py, e),
            })?;
        self.wire(py, move |i| i.write_word(address, raw, multiple))
    }

    /// A 32-bit integer over two registers.
    #[pyo3(signature = (address, signed=false, word_order=None))]
    fn read_long(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        signed: bool,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<i64> {
        let address = pair_address(address)?;
        let order = opt(word_order, WordOrder::HighFirst, self::word_order)?;
        let v = self.wire(py, move |i| i.read_u32(address, order))?;
        Ok(if signed {
            i64::from(v as i32)
        } else {
            i64::from(v)
        })
    }

    /// Writes a 32-bit integer over two registers.
    #[pyo3(signature = (address, value, signed=false, word_order=None))]
    fn write_long(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        signed: bool,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let address = pair_address(address)?;
        let value = if signed {
            int_in(value, "value", i64::from(i32::MIN), i64::from(i32::MAX))? as i32 as u32
        } else {
            int_in(value, "value", 0, i64::from(u32::MAX))? as u32
        };
        let order = opt(word_order, WordOrder::HighFirst, self::word_order)?;
        self.wire(py, move |i| i.write_u32(address, value, order))
    }

    /// An IEEE 754 single over two registers.
    #[pyo3(signature = (address, word_order=None))]
    fn read_float(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<f64> {
        let address = pair_address(address)?;
        let order = opt(word_order, WordOrder::HighFirst, self::word_order)?;
        self.wire(py, move |i| i.read_f32(address, order))
            .map(f64::from)
    }

    /// Writes an IEEE 754 single over two registers (finite values only).
    #[pyo3(signature = (address, value, word_order=None))]
    fn write_float(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let address = pair_address(address)?;
        let value = number(value, "value")?;
        let single = value as f32;
        if !value.is_finite() || !single.is_finite() {
            return Err(PyValueError::new_err(format!(
                "value must be a finite number within a 32-bit float's range, got {value}"
            )));
        }
        let order = opt(word_order, WordOrder::HighFirst, self::word_order)?;
        self.wire(py, move |i| i.write_f32(address, single, order))
    }

    /// `count` registers as Latin-1 text, trailing NULs dropped.
    fn read_string(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<String> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        self.wire(py, move |i| i.read_string(address, count))
    }

    /// Writes `text` into `count` registers, padded with NULs.
    fn write_string(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        text: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let address = u16_arg(address, "address")?;
        if !text.is_instance_of::<PyString>() {
            return Err(PyTypeError::new_err(format!(
                "text must be a str, got {}",
                text.get_type().name()?
            )));
        }
        let text: String = text.extract()?;
        let count = count_arg(count, address)?;
        // Checked here so a bad text sends nothing.
        if text.chars().any(|c| u32::from(c) > 0xFF) || text.chars().count() > 2 * count {
            return Err(PyValueError::new_err(format!(
                "text must be Latin-1 and at most {} characters for {count} registers, got {text:?}",
                2 * count
            )));
        }
        self.wire(py, move |i| i.write_string(address, &text, count))
    }

    /// Read Device Identification: `(conformity level, {object id: text})` (Latin-1).
    #[pyo3(signature = (read_code=None))]
    fn identify(
        &self,
        py: Python<'_>,
        read_code: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(u8, BTreeMap<u8, String>)> {
        let read_code = opt(read_code, 1, |r| {
            int_in(r, "read_code", 1, 3).map(|r| r as u8)
        })?;
        let id = self.wire(py, move |i| i.identify(read_code))?;
        Ok((id.conformity, id.texts()))
    }

    fn __repr__(&self) -> String {
        format!("InstrumentCore(unit={})", self.dev.unit())
    }
}
