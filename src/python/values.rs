//! `from_registers` / `to_registers`: values over registers ([`crate::device::value`]) for
//! whoever reads raw registers (a Bus call, the command line).

use super::{number, to_pyerr, u16_arg};
use crate::device::value::{Kind, Layout, Number};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyInt, PyString};

/// A `type` argument: "u16" (absent), "i16", "u32", "i32", "u64", "i64", "f32" or "f64".
fn kind_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Kind> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Kind::U16);
    };
    let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
    let name: String = obj
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("type must be one of {}", names.join(", "))))?;
    Kind::from_name(&name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "type must be one of {}, got {name:?}",
            names.join(", ")
        ))
    })
}

/// An `order` argument: "ABCD" (absent), "CDAB", "BADC" or "DCBA" (any case), the
/// vocabulary of profiles, `from_registers` and the Instrument's value methods.
pub(super) fn layout_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Layout> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Layout::Abcd);
    };
    let name: String = obj.extract().map_err(|_| {
        PyTypeError::new_err("order must be \"ABCD\", \"CDAB\", \"BADC\" or \"DCBA\"")
    })?;
    Layout::from_name(&name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "order must be \"ABCD\", \"CDAB\", \"BADC\" or \"DCBA\", got {name:?}"
        ))
    })
}

/// A value for `kind`: an int for the integer kinds, a number for the float ones.
fn value_arg(obj: &Bound<'_, PyAny>, kind: Kind) -> PyResult<Number> {
    if matches!(kind, Kind::F32 | Kind::F64) {
        return number(obj, "value").map(Number::Float);
    }
    if obj.is_instance_of::<PyBool>() || !obj.is_instance_of::<PyInt>() {
        return Err(PyTypeError::new_err(format!(
            "a {} value must be an int, got {}",
            kind.name(),
            obj.get_type().name()?
        )));
    }
    match obj.extract::<i64>() {
        Ok(v) => Ok(Number::Int(v.into())),
        Err(_) => obj
            .extract::<u64>()
            .map(|v| Number::Int(v.into()))
            .map_err(|_| {
                PyValueError::new_err(format!("a {} value is out of range: {obj}", kind.name()))
            }),
    }
}

/// The values ``registers`` hold, each of ``type`` ("u16" unless given: "i16", "u32",
/// "i32", "u64", "i64", "f32", "f64") over as many registers as it takes, laid out as
/// ``order`` ("ABCD" unless given: "CDAB", "BADC", "DCBA"; see ``Instrument.read_long``).
#[pyfunction]
#[pyo3(signature = (registers, r#type=None, order=None), text_signature = "(registers, type='u16', order='ABCD')")]
pub fn from_registers<'py>(
    py: Python<'py>,
    registers: &Bound<'py, PyAny>,
    r#type: Option<&Bound<'py, PyAny>>,
    order: Option<&Bound<'py, PyAny>>,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let kind = kind_arg(r#type)?;
    let layout = layout_arg(order)?;
    if registers.is_instance_of::<PyString>() || registers.is_instance_of::<PyBytes>() {
        return Err(PyTypeError::new_err(
            "registers must be a sequence of ints, not str or bytes",
        ));
    }
    let registers = registers
        .try_iter()
        .map_err(|_| PyTypeError::new_err("registers must be a sequence of ints"))?
        .map(|item| u16_arg(&item?, "each register"))
        .collect::<PyResult<Vec<u16>>>()?;
    let numbers = kind
        .decode(&registers, layout)
        .map_err(|e| to_pyerr(py, e))?;
    numbers
        .into_iter()
        .map(|n| match n {
            Number::Int(v) if v < 0 => Ok((v as i64).into_pyobject(py)?.into_any()),
            Number::Int(v) => Ok((v as u64).into_pyobject(py)?.into_any()),
            Number::Float(v) => Ok(v.into_pyobject(py)?.into_any()),
        })
        .collect()
}

/// The registers that hold ``values`` (one number, or a sequence of them), each of
/// ``type`` laid out as ``order`` (as :func:`from_registers` reads them); a value that does
/// not fit its type raises ValueError.
#[pyfunction]
#[pyo3(signature = (values, r#type=None, order=None), text_signature = "(values, type='u16', order='ABCD')")]
pub fn to_registers(
    py: Python<'_>,
    values: &Bound<'_, PyAny>,
    r#type: Option<&Bound<'_, PyAny>>,
    order: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<u16>> {
    let kind = kind_arg(r#type)?;
    let layout = layout_arg(order)?;
    let items: Vec<Bound<'_, PyAny>> =
        if values.is_instance_of::<PyString>() || values.is_instance_of::<PyBytes>() {
            return Err(PyTypeError::new_err(
                "values must be a number or a sequence of numbers, not str or bytes",
            ));
        } else if let Ok(iter) = values.try_iter() {
            iter.collect::<PyResult<_>>()?
        } else {
            vec![values.clone()]
        };
    if items.is_empty() {
        return Err(PyValueError::new_err("values must hold at least one value"));
    }
    let mut out = Vec::with_capacity(items.len() * kind.registers());
    for item in &items {
        let value = value_arg(item, kind)?;
        out.extend(kind.encode(value, layout).map_err(|e| to_pyerr(py, e))?);
    }
    Ok(out)
}
