//! Bindings of [`crate::device::instrument`]: the compiled base class of
//! `benchbus.Instrument`, which adds only what belongs to Python (its defaults, the
//! identification record, the repr, the context manager).

use super::device_methods;
use super::{
    bool_sequence, comm_event_log, int_in, number, opt, public, read_file_groups, register_list,
    seconds, u16_arg, unit_arg, write_file_groups, Attached, PyBus, PyStation, RESULTS,
};
use crate::codec::pdu::{MAX_READ_BITS, MAX_READ_COUNT, MAX_WRITE_BITS, MAX_WRITE_COUNT};
use crate::device::instrument::{Instrument, MAX_DECIMALS};
use crate::device::value::Layout;
use crate::device::Table;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyDict, PyFloat, PyInt, PyString, PyTuple};
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

/// A `word_order` or `byte_order` argument ("big": most significant first, or "little");
/// absent or None: "big".
fn big_arg(obj: Option<&Bound<'_, PyAny>>, name: &str, what: &str) -> PyResult<bool> {
    opt(obj, true, |o| {
        if !o.is_instance_of::<PyString>() {
            return Err(PyTypeError::new_err(format!(
                "{name} must be \"big\" or \"little\", got {}",
                o.get_type().name()?
            )));
        }
        match o.extract::<String>()?.as_str() {
            "big" => Ok(true),
            "little" => Ok(false),
            other => Err(PyValueError::new_err(format!(
                "{name} must be \"big\" (high {what} first) or \"little\" (low {what} first), \
                 got {other:?}"
            ))),
        }
    })
}

/// The layout of a multi-register value: its `order` ("ABCD", "CDAB", "BADC", "DCBA", as
/// profiles and `from_registers` name it), or the same said by the aliases `word_order`
/// and `byte_order` (each "big" or "little"), not both ways at once.
fn layout_arg(
    order: Option<&Bound<'_, PyAny>>,
    word_order: Option<&Bound<'_, PyAny>>,
    byte_order: Option<&Bound<'_, PyAny>>,
) -> PyResult<Layout> {
    let given = |o: Option<&Bound<'_, PyAny>>| o.is_some_and(|o| !o.is_none());
    if given(order) {
        if given(word_order) || given(byte_order) {
            return Err(PyTypeError::new_err(
                "give order (\"ABCD\", \"CDAB\", \"BADC\" or \"DCBA\") or its aliases \
                 word_order / byte_order, not both",
            ));
        }
        return super::values::layout_arg(order);
    }
    let words = big_arg(word_order, "word_order", "word")?;
    let bytes = big_arg(byte_order, "byte_order", "byte")?;
    Ok(Layout::new(words, bytes))
}

/// A `bits` argument: 32 (absent or None) or 64.
fn bits_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<u32> {
    opt(obj, 32, |b| match int_in(b, "bits", 0, 128)? {
        bits @ (32 | 64) => Ok(bits as u32),
        other => Err(PyValueError::new_err(format!(
            "bits must be 32 or 64, got {other}"
        ))),
    })
}

/// The first register address of a value of `bits` (the last one must be 0xFFFF at most).
fn value_address(obj: &Bound<'_, PyAny>, bits: u32) -> PyResult<u16> {
    let last = 0x1_0000 - i64::from(bits / 16);
    int_in(obj, "address", 0, last).map(|a| a as u16)
}

/// An int `value` that fits `bits`, signed or not, as its two's complement bits.
fn int_bits(value: &Bound<'_, PyAny>, bits: u32, signed: bool) -> PyResult<u64> {
    if value.is_instance_of::<PyBool>() || !value.is_instance_of::<PyInt>() {
        return Err(PyTypeError::new_err(format!(
            "value must be an int, got {}",
            value.get_type().name()?
        )));
    }
    let (lo, hi): (i128, i128) = match (signed, bits) {
        (true, 32) => (i32::MIN.into(), i32::MAX.into()),
        (true, _) => (i64::MIN.into(), i64::MAX.into()),
        (false, 32) => (0, u32::MAX.into()),
        (false, _) => (0, u64::MAX.into()),
    };
    let got = value
        .extract::<i64>()
        .map(i128::from)
        .or_else(|_| value.extract::<u64>().map(i128::from));
    match got {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v as u64 & mask(bits)),
        _ => Err(PyValueError::new_err(format!(
            "value must be {lo} to {hi}, got {value}"
        ))),
    }
}

/// The low `bits` bits set.
fn mask(bits: u32) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1 << bits) - 1
    }
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

/// The table a register read asks: 3 (holding registers, absent or None) or 4 (input
/// registers).
fn read_function_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Table> {
    opt(obj, Table::Holding, |f| {
        match int_in(f, "function", 0, 255)? {
            0x03 => Ok(Table::Holding),
            0x04 => Ok(Table::Input),
            other => Err(PyValueError::new_err(format!(
                "function must be 3 (holding registers) or 4 (input registers), got {other}"
            ))),
        }
    })
}

/// A coil's value: True or False (nothing truthy in its place).
fn coil_arg(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    obj.cast::<PyBool>().map(|b| b.is_true()).map_err(|_| {
        PyTypeError::new_err(format!(
            "a coil is True or False, got {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })
}

/// A count of bits from `address`: 1 up to what fits below 0x10000.
fn bit_count_arg(obj: &Bound<'_, PyAny>, address: u16) -> PyResult<usize> {
    let most = 0x1_0000 - i64::from(address);
    int_in(obj, "count", 1, most).map(|n| n as usize)
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

impl PyInstrumentCore {
    /// One bit of `table` at `address`.
    fn read_bit(&self, py: Python<'_>, table: Table, address: &Bound<'_, PyAny>) -> PyResult<bool> {
        let address = u16_arg(address, "address")?;
        let bits = self.dev.wire(py, move |i| i.read_bits(table, address, 1))?;
        Ok(bits.first().copied().unwrap_or_default())
    }

    /// `count` bits of `table` from `address`.
    fn read_many_bits(
        &self,
        py: Python<'_>,
        table: Table,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<bool>> {
        let address = u16_arg(address, "address")?;
        let count = bit_count_arg(count, address)?;
        self.dev
            .wire(py, move |i| i.read_bits(table, address, count))
    }
}

device_methods! {
PyInstrumentCore = |dev| PyInstrumentCore { dev };

    /// Attaches the instrument at `unit` to `bus` with its request limits (what
    /// `Instrument.__init__` does); `timeout` / `retries` replace the Bus's.
    #[pyo3(signature = (bus, unit, max_read, max_write, min_write_interval, max_read_bits, max_write_bits, timeout=None, retries=None))]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn _attach(
        slf: &Bound<'_, Self>,
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        max_read: &Bound<'_, PyAny>,
        max_write: &Bound<'_, PyAny>,
        min_write_interval: &Bound<'_, PyAny>,
        max_read_bits: &Bound<'_, PyAny>,
        max_write_bits: &Bound<'_, PyAny>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let max_read = int_in(max_read, "max_read", 1, MAX_READ_COUNT.into())? as u16;
        let max_write = int_in(max_write, "max_write", 1, MAX_WRITE_COUNT.into())? as u16;
        let interval: Duration = seconds(min_write_interval, "min_write_interval", true)?;
        let max_read_bits = int_in(max_read_bits, "max_read_bits", 1, MAX_READ_BITS.into())? as u16;
        let max_write_bits =
            int_in(max_write_bits, "max_write_bits", 1, MAX_WRITE_BITS.into())? as u16;
        let station = slf.as_super().get();
        slf.get()
            .dev
            .attach(station, bus, unit, unit_arg, timeout, retries, |b, u| {
                Instrument::new(b, u, max_read, max_write, interval)?
                    .with_bit_limits(max_read_bits, max_write_bits)
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

    /// Most coils or discrete inputs one read asks for.
    #[getter]
    fn max_read_bits(&self) -> PyResult<u16> {
        Ok(self.dev.device()?.max_read_bits())
    }

    /// Most coils one write carries.
    #[getter]
    fn max_write_bits(&self) -> PyResult<u16> {
        Ok(self.dev.device()?.max_write_bits())
    }

    /// Least time between two writes, seconds.
    #[getter]
    fn min_write_interval(&self) -> PyResult<f64> {
        Ok(self.dev.device()?.min_write_interval().as_secs_f64())
    }

    /// One register as a value: ``raw / 10**decimals`` (an int when ``decimals`` is 0),
    /// two's complement if ``signed``; ``function=4`` reads an input register instead of a
    /// holding register (3).
    #[pyo3(
        signature = (address, decimals=None, signed=false, *, function=None),
        text_signature = "($self, address, decimals=0, signed=False, *, function=3)"
    )]
    fn read_register<'py>(
        &self,
        py: Python<'py>,
        address: &Bound<'py, PyAny>,
        decimals: Option<&Bound<'py, PyAny>>,
        signed: bool,
        function: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let address = u16_arg(address, "address")?;
        let decimals = decimals_arg(decimals)?;
        let table = read_function_arg(function)?;
        let v = self
            .dev
            .wire(py, move |i| i.read_value(table, address, decimals, signed))?;
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
        text_signature = "($self, address, value, decimals=0, signed=False, *, function=6)"
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

    /// ``count`` raw registers from ``address``, in requests of at most ``max_read``
    /// (``function=4``: input registers).
    #[pyo3(signature = (address, count, *, function=None), text_signature = "($self, address, count, *, function=3)")]
    fn read_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
        function: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<u16>> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        let table = read_function_arg(function)?;
        self.dev
            .wire(py, move |i| i.read_registers(table, address, count))
    }

    /// One coil (0x01).
    fn read_coil(&self, py: Python<'_>, address: &Bound<'_, PyAny>) -> PyResult<bool> {
        self.read_bit(py, Table::Coils, address)
    }

    /// ``count`` coils from ``address`` (0x01), in requests of at most ``max_read_bits``.
    fn read_coils(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<bool>> {
        self.read_many_bits(py, Table::Coils, address, count)
    }

    /// One discrete input (0x02).
    fn read_discrete_input(&self, py: Python<'_>, address: &Bound<'_, PyAny>) -> PyResult<bool> {
        self.read_bit(py, Table::Discrete, address)
    }

    /// ``count`` discrete inputs from ``address`` (0x02), in requests of at most
    /// ``max_read_bits``.
    fn read_discrete_inputs(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<bool>> {
        self.read_many_bits(py, Table::Discrete, address, count)
    }

    /// Set one coil on (True) or off (False) with 0x05; the reply must echo it.
    fn write_coil(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let address = u16_arg(address, "address")?;
        let value = coil_arg(value)?;
        self.dev.wire(py, move |i| i.write_coil(address, value))
    }

    /// Set the coils from ``address`` to ``values`` (True or False each) with 0x0F, in
    /// requests of at most ``max_write_bits``.
    fn write_coils(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let address = u16_arg(address, "address")?;
        let values = bool_sequence(values, "True / False", coil_arg)?;
        let most = 0x1_0000 - usize::from(address);
        if values.is_empty() || values.len() > most {
            return Err(PyValueError::new_err(format!(
                "values must hold 1 to {most} coils from {address:#06x}, got {}",
                values.len()
            )));
        }
        self.dev.wire(py, move |i| i.write_coils(address, &values))
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

    /// An integer of ``bits`` (32 or 64) over the 2 or 4 registers from ``address``,
    /// signed or not, laid out by ``order``, as profiles and :func:`benchbus.from_registers`
    /// name it: ``"ABCD"`` (most significant register and byte first), ``"CDAB"`` (words
    /// swapped), ``"BADC"`` (bytes swapped in each register) or ``"DCBA"``.
    ///
    /// For 0x01020304: ABCD ``[0x0102, 0x0304]``, CDAB ``[0x0304, 0x0102]``, BADC
    /// ``[0x0201, 0x0403]``, DCBA ``[0x0403, 0x0201]``; a 64-bit value lies the same way
    /// over four registers.
    ///
    /// ``word_order`` (which register first) and ``byte_order`` (which byte of each
    /// register first), each ``"big"`` or ``"little"``, are accepted aliases:
    /// ``word_order="little"`` is ``order="CDAB"``, ``byte_order="little"`` ``"BADC"``.
    /// Giving ``order`` with either is a TypeError.
    #[pyo3(
        signature = (address, signed=false, word_order=None, *, byte_order=None, bits=None, function=None, order=None),
        text_signature = "($self, address, signed=False, word_order=None, *, byte_order=None, bits=32, function=3, order='ABCD')"
    )]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn read_long<'py>(
        &self,
        py: Python<'py>,
        address: &Bound<'py, PyAny>,
        signed: bool,
        word_order: Option<&Bound<'py, PyAny>>,
        byte_order: Option<&Bound<'py, PyAny>>,
        bits: Option<&Bound<'py, PyAny>>,
        function: Option<&Bound<'py, PyAny>>,
        order: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let bits = bits_arg(bits)?;
        let address = value_address(address, bits)?;
        let layout = layout_arg(order, word_order, byte_order)?;
        let table = read_function_arg(function)?;
        let v = self
            .dev
            .wire(py, move |i| i.read_uint(table, address, bits, layout))?;
        Ok(match (signed, bits) {
            (true, 32) => (v as u32 as i32).into_pyobject(py)?.into_any(),
            (true, _) => (v as i64).into_pyobject(py)?.into_any(),
            (false, _) => v.into_pyobject(py)?.into_any(),
        })
    }

    /// Write an integer of ``bits`` (32 or 64) over 2 or 4 registers, laid out as
    /// :meth:`read_long` reads it (``order``, or its aliases ``word_order`` /
    /// ``byte_order``), in one request (more if ``max_write`` is smaller).
    #[pyo3(
        signature = (address, value, signed=false, word_order=None, *, byte_order=None, bits=None, order=None),
        text_signature = "($self, address, value, signed=False, word_order=None, *, byte_order=None, bits=32, order='ABCD')"
    )]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn write_long(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        signed: bool,
        word_order: Option<&Bound<'_, PyAny>>,
        byte_order: Option<&Bound<'_, PyAny>>,
        bits: Option<&Bound<'_, PyAny>>,
        order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let bits = bits_arg(bits)?;
        let address = value_address(address, bits)?;
        let value = int_bits(value, bits, signed)?;
        let layout = layout_arg(order, word_order, byte_order)?;
        self.dev
            .wire(py, move |i| i.write_uint(address, value, bits, layout))
    }

    /// An IEEE 754 float of ``bits`` (32: single, 64: double) over 2 or 4 registers, laid
    /// out as :meth:`read_long` reads an integer (``order``, or its aliases ``word_order`` /
    /// ``byte_order``).
    #[pyo3(
        signature = (address, word_order=None, *, byte_order=None, bits=None, function=None, order=None),
        text_signature = "($self, address, word_order=None, *, byte_order=None, bits=32, function=3, order='ABCD')"
    )]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn read_float(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        word_order: Option<&Bound<'_, PyAny>>,
        byte_order: Option<&Bound<'_, PyAny>>,
        bits: Option<&Bound<'_, PyAny>>,
        function: Option<&Bound<'_, PyAny>>,
        order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<f64> {
        let bits = bits_arg(bits)?;
        let address = value_address(address, bits)?;
        let layout = layout_arg(order, word_order, byte_order)?;
        let table = read_function_arg(function)?;
        self.dev
            .wire(py, move |i| i.read_float(table, address, bits, layout))
    }

    /// Write an IEEE 754 float of ``bits`` (32 or 64) over 2 or 4 registers (NaN,
    /// infinities and, in 32 bits, numbers beyond a single's range are refused), laid out
    /// as :meth:`read_long` reads an integer (``order``, or its aliases ``word_order`` /
    /// ``byte_order``).
    #[pyo3(
        signature = (address, value, word_order=None, *, byte_order=None, bits=None, order=None),
        text_signature = "($self, address, value, word_order=None, *, byte_order=None, bits=32, order='ABCD')"
    )]
    #[allow(clippy::too_many_arguments)] // the Python signature's, one by one
    fn write_float(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        word_order: Option<&Bound<'_, PyAny>>,
        byte_order: Option<&Bound<'_, PyAny>>,
        bits: Option<&Bound<'_, PyAny>>,
        order: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let bits = bits_arg(bits)?;
        let address = value_address(address, bits)?;
        let value = number(value, "value")?;
        let layout = layout_arg(order, word_order, byte_order)?;
        self.dev
            .wire(py, move |i| i.write_float(address, value, bits, layout))
    }

    /// ``count`` registers as text, two Latin-1 characters a register (high byte first),
    /// without the NULs that pad it (``function=4``: input registers).
    #[pyo3(signature = (address, count, *, function=None), text_signature = "($self, address, count, *, function=3)")]
    fn read_string(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
        function: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<String> {
        let address = u16_arg(address, "address")?;
        let count = count_arg(count, address)?;
        let table = read_function_arg(function)?;
        self.dev
            .wire(py, move |i| i.read_string(table, address, count))
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
    #[pyo3(signature = (level=py_basic()), text_signature = "($self, level='basic')")]
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

    /// The status word (0xFFFF busy, 0x0000 not) and event counter (function 0x0B), as a
    /// ``CommEventCounter(status, event_count)``.
    fn get_comm_event_counter<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (status, count) = self.dev.wire(py, |i| i.get_comm_event_counter())?;
        public(py, RESULTS, "CommEventCounter", (status, count), None)
    }

    /// The status word, event and message counters and events (function 0x0C), as a
    /// ``CommEventLog(status, event_count, message_count, events)``.
    fn get_comm_event_log<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let log = self.dev.wire(py, |i| i.get_comm_event_log())?;
        comm_event_log(py, log)
    }

    /// File records (function 0x14): for each group ``(file, record, length)``,
    /// ``length`` registers from record ``record`` of file ``file``; one list per group.
    fn read_file_record(
        &self,
        py: Python<'_>,
        groups: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<Vec<u16>>> {
        let groups = read_file_groups(groups)?;
        self.dev.wire(py, move |i| i.read_file_record(&groups))
    }

    /// Write file records (function 0x15): for each group ``(file, record, values)``,
    /// ``values`` from record ``record`` of file ``file``; the reply must echo the request.
    fn write_file_record(&self, py: Python<'_>, groups: &Bound<'_, PyAny>) -> PyResult<()> {
        let groups = write_file_groups(groups)?;
        self.dev.wire(py, move |i| i.write_file_record(&groups))
    }

    /// The values queued in the FIFO whose count register is at ``address`` (function
    /// 0x18), oldest first: at most 31.
    fn read_fifo_queue(&self, py: Python<'_>, address: &Bound<'_, PyAny>) -> PyResult<Vec<u16>> {
        let address = u16_arg(address, "address")?;
        self.dev.wire(py, move |i| i.read_fifo_queue(address))
    }
}
