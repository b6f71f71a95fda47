//! Bindings of [`crate::device::instrument`]: the compiled base class of
//! `benchbus.Instrument`, which adds only what belongs to Python (its defaults, the
//! identification record, the repr, the context manager).

use super::{
    int_in, number, opt, public, register_list, seconds, u16_arg, unit_arg, Attached, PyBus,
    PyStation,
};
use crate::codec::pdu::{MAX_READ_COUNT, MAX_WRITE_COUNT};
use crate::device::instrument::{Instrument, WordOrder, MAX_DECIMALS};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyBytes, PyDict, PyFloat, PyInt, PyString, PyTuple};
use std::time::Duration;

/// The Python module of the family's public types.
const PY: &str = "benchbus._instrument";

/// The levels of Read Device Identification by name, with their read codes.
const LEVELS: [(&str, u8); 3] = [("basic", 1), ("regular", 2), ("extended", 3)];

/// The compiled base of `benchbus.Instrument`: the request limits, the value conversions and
/// every call to the instrument.
#[pyclass(extends = PyStation, subclass, frozen, module = "benchbus._core", name = "InstrumentCore")]
pub(super) struct PyInstrumentCore {
    dev: Attached<Instrument>,
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

/// A `word_order` argument; absent or None: "big".
fn order_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<WordOrder> {
    opt(obj, WordOrder::HighFirst, word_order)
}

fn decimals_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<u8> {
    opt(obj, 0, |d| {
        int_in(d, "decimals", 0, MAX_DECIMALS.into()).map(|d| d as u8)
    })
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

/// The values of a write: any iterable of ints but text, bytes and bytearray (refused
/// before the address is looked at).
fn values_kind(values: &Bound<'_, PyAny>) -> PyResult<()> {
    if values.is_instance_of::<PyString>()
        || values.is_instance_of::<PyBytes>()
        || values.is_instance_of::<PyByteArray>()
    {
        return Err(PyTypeError::new_err(
            "values must be a sequence of ints, not str or bytes",
        ));
    }
    if values.try_iter().is_err() {
        return Err(PyTypeError::new_err(format!(
            "values must be a sequence of ints, got {}",
            values.get_type().name()?
        )));
    }
    Ok(())
}

/// The read code of an identification `level`: "basic", "regular" or "extended".
fn level_arg(level: &Bound<'_, PyAny>) -> PyResult<u8> {
    let expected = "level must be 'basic', 'regular' or 'extended'";
    if !level.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "{expected}, got {}",
            level.get_type().name()?
        )));
    }
    let name: String = level.extract()?;
    LEVELS
        .iter()
        .find(|(known, _)| *known == name)
        .map(|&(_, code)| code)
        .ok_or_else(|| match level.repr() {
            Ok(shown) => PyValueError::new_err(format!("{expected}, got {shown}")),
            Err(e) => e,
        })
}

/// "basic", the default identification level (still checked when given).
fn py_basic() -> Py<PyAny> {
    Python::attach(|py| PyString::new(py, "basic").into_any().unbind())
}

#[pymethods]
impl PyInstrumentCore {
    #[new]
    #[pyo3(signature = (*_args, **_kwargs))]
    fn new(
        _args: &Bound<'_, PyTuple>,
        _kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyClassInitializer<Self> {
        Attached::class(|dev| PyInstrumentCore { dev })
    }

    /// Attaches the instrument at `unit` to `bus` with its request limits (what
    /// `Instrument.__init__` does); `timeout` / `retries` replace the Bus's.
    #[pyo3(signature = (bus, unit, max_read, max_write, min_write_interval, timeout=None, retries=None))]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn _attach(
        slf: &Bound<'_, Self>,
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        max_read: &Bound<'_, PyAny>,
        max_write: &Bound<'_, PyAny>,
        min_write_interval: &Bound<'_, PyAny>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let max_read = int_in(max_read, "max_read", 1, MAX_READ_COUNT.into())? as u16;
        let max_write = int_in(max_write, "max_write", 1, MAX_WRITE_COUNT.into())? as u16;
        let interval: Duration = seconds(min_write_interval, "min_write_interval", true)?;
        let station = slf.as_super().get();
        slf.get()
            .dev
            .attach(station, bus, unit, unit_arg, timeout, retries, |b, u| {
                Instrument::new(b, u, max_read, max_write, interval)
            })
    }

    /// Most registers one read asks for.
    #[getter]
    fn max_read(&self) -> PyResult<u16> {
        Ok(self.dev.device()?.max_read())
    }

    /// Most registers one write carries.
    #[getter]
    fn max_write(&self) -> PyResult<u16> {
        Ok(self.dev.device()?.max_write())
    }

    /// Least time between two writes, seconds.
    #[getter]
    fn min_write_interval(&self) -> PyResult<f64> {
        Ok(self.dev.device()?.min_write_interval().as_secs_f64())
    }

    /// One register as a value: ``raw / 10**decimals`` (an int when ``decimals`` is 0),
    /// two's complement if ``signed``.
    #[pyo3(signature = (address, decimals=None, signed=false), text_signature = "(self, address, decimals=0, signed=False)")]
    fn read_register<'py>(
        &self,
        py: Python<'py>,
        address: &Bound<'py, PyAny>,
        decimals: Option<&Bound<'py, PyAny>>,
        signed: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let address = u16_arg(address, "address")?;
        let decimals = decimals_arg(decimals)?;
        let v = self
            .dev
            .wire(py, move |i| i.read_value(address, decimals, signed))?;
        Ok(if decimals == 0 {
            PyInt::new(py, v as i64).into_any()
        } else {
            PyFloat::new(py, v).into_any()
        })
    }

    /// Write ``value * 10**decimals`` to one register with 0x06 (or 0x10 if ``function``
    /// is 16). A value that does not fit or has more decimals raises ValueError before
    /// anything is sent.
    #[pyo3(
        signature = (address, value, decimals=None, signed=false, *, function=None),
        text_signature = "(self, address, value, decimals=0, signed=False, *, function=6)"
    )]
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
        self.dev.wire(py, move |i| {
            i.write_value(address, value, decimals, signed, multiple)
        })
    }

    /// ``count`` raw registers from ``address``, in requests of at most ``max_read``.
    fn read_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        self.dev.wire(py, move |i| i.read_registers(address, count))
    }

    /// Write raw ``values`` from ``address`` with 0x10, in requests of at most
    /// ``max_write``.
    fn write_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        values_kind(values)?;
        let address = u16_arg(address, "address")?;
        let values = register_list(values, 0x1_0000 - usize::from(address))?;
        self.dev
            .wire(py, move |i| i.write_registers(address, &values))
    }

    /// A 32-bit integer over the registers ``address`` and ``address + 1``.
    #[pyo3(signature = (address, signed=false, word_order=None), text_signature = "(self, address, signed=False, word_order='big')")]
    fn read_long(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        signed: bool,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<i64> {
        let address = pair_address(address)?;
        let order = order_arg(word_order)?;
        let v = self.dev.wire(py, move |i| i.read_u32(address, order))?;
        Ok(if signed {
            i64::from(v as i32)
        } else {
            i64::from(v)
        })
    }

    /// Write a 32-bit integer over two registers, in one request (two if ``max_write`` is
    /// 1).
    #[pyo3(signature = (address, value, signed=false, word_order=None), text_signature = "(self, address, value, signed=False, word_order='big')")]
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
        let order = order_arg(word_order)?;
        self.dev
            .wire(py, move |i| i.write_u32(address, value, order))
    }

    /// An IEEE 754 single-precision float over two registers.
    #[pyo3(signature = (address, word_order=None), text_signature = "(self, address, word_order='big')")]
    fn read_float(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        word_order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<f64> {
        let address = pair_address(address)?;
        let order = order_arg(word_order)?;
        self.dev
            .wire(py, move |i| i.read_f32(address, order))
            .map(f64::from)
    }

    /// Write an IEEE 754 single over two registers (NaN and infinities are refused).
    #[pyo3(signature = (address, value, word_order=None), text_signature = "(self, address, value, word_order='big')")]
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
        // A finite number beyond a single's range: the core sees only the infinity.
        if value.is_finite() && !single.is_finite() {
            return Err(PyValueError::new_err(format!(
                "value must be a finite number within a 32-bit float's range, got {value}"
            )));
        }
        let order = order_arg(word_order)?;
        self.dev
            .wire(py, move |i| i.write_f32(address, single, order))
    }

    /// ``count`` registers as text, two Latin-1 characters a register (high byte first),
    /// without the NULs that pad it.
    fn read_string(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<String> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        self.dev.wire(py, move |i| i.read_string(address, count))
    }

    /// Write ``text`` into ``count`` registers, two characters a register, padded with
    /// NULs (longer text or characters outside Latin-1 raise ValueError).
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
        self.dev
            .wire(py, move |i| i.write_string(address, &text, count))
    }

    /// Read Device Identification (0x2B / MEI 0x0E) from object 0, following "more
    /// follows" until the device has sent them all.
    ///
    /// A device without the function raises :class:`~benchbus.ModbusException` with code 1
    /// (its ``meaning`` says so).
    #[pyo3(signature = (level=py_basic()), text_signature = "(self, level='basic')")]
    fn identify<'py>(&self, py: Python<'py>, level: Py<PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let read_code = level_arg(level.bind(py))?;
        let id = self.dev.wire(py, move |i| i.identify(read_code))?;
        let objects = id.texts();
        let fields = PyDict::new(py);
        fields.set_item("vendor", objects.get(&0))?;
        fields.set_item("product_code", objects.get(&1))?;
        fields.set_item("revision", objects.get(&2))?;
        fields.set_item("objects", &objects)?;
        fields.set_item("conformity", id.conformity)?;
        public(py, PY, "Identification", (), Some(&fields))
    }
}
