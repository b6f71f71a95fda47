//! `load_profile`: a device profile file, checked by the core, as plain Python data; its
//! mistakes as `benchbus.ProfileError`.

use super::EXCEPTIONS;
use crate::device::profile::{Profile, ProfileError, ProfileRegister, ProfileValue, ValueType};
use crate::device::{Access, Table};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyModule};
use std::path::PathBuf;

/// Reads and checks the device profile (TOML) at `path`.
///
/// Returns a dict: ``name``, ``description``, ``line`` (``baudrate``, ``parity``,
/// ``stopbits``, ``timeout``, ``framing``, ``bytesize``; None where the file is silent),
/// ``limits`` (``max_read``, ``max_write``, ``min_write_interval``, ``block_reads``; None
/// where silent) and ``registers``, one dict per ``[[register]]`` in the file's order:
/// ``name``, ``address``, ``table`` ("holding", "input", "coil", "discrete"), ``type``,
/// ``bit``, ``length``, ``order``, ``scale``, ``offset``, ``signed``, ``unit``, ``access``
/// ("r", "rw", "w"), ``min``, ``max`` (None for a bool or a string), ``enum`` ({number:
/// name}), ``default``, ``description`` and ``line``.
///
/// Raises ``ProfileError`` (a ``ValueError``) naming the file, the line and the key of the
/// first mistake; nothing is opened.
#[pyfunction]
pub(super) fn load_profile(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    let profile = Profile::load(&path).map_err(|e| profile_error(py, &e))?;
    profile_dict(py, &profile)
}

/// The `benchbus.ProfileError` of `err`.
fn profile_error(py: Python<'_>, err: &ProfileError) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let module = EXCEPTIONS.get_or_try_init(py, || {
            PyModule::import(py, "benchbus.exceptions").map(Bound::unbind)
        })?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("path", err.path.as_str())?;
        kwargs.set_item("line", err.line)?;
        kwargs.set_item("key", err.key.as_str())?;
        let instance = module
            .bind(py)
            .getattr("ProfileError")?
            .call((err.to_string(),), Some(&kwargs))?;
        Ok(PyErr::from_value(instance))
    };
    build().unwrap_or_else(|e| e)
}

fn profile_dict<'py>(py: Python<'py>, p: &Profile) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("name", p.name.as_str())?;
    out.set_item("description", p.description.as_str())?;
    let line = PyDict::new(py);
    line.set_item("baudrate", p.line.baudrate)?;
    line.set_item("parity", p.line.parity.map(String::from))?;
    line.set_item("stopbits", p.line.stopbits)?;
    line.set_item("timeout", p.line.timeout)?;
    line.set_item("framing", p.line.framing.as_deref())?;
    line.set_item("bytesize", p.line.bytesize)?;
    out.set_item("line", line)?;
    let limits = PyDict::new(py);
    limits.set_item("max_read", p.limits.max_read)?;
    limits.set_item("max_write", p.limits.max_write)?;
    limits.set_item("min_write_interval", p.limits.min_write_interval)?;
    limits.set_item("block_reads", p.limits.block_reads)?;
    out.set_item("limits", limits)?;
    let rows = PyList::empty(py);
    for r in &p.registers {
        rows.append(register_dict(py, r)?)?;
    }
    out.set_item("registers", rows)?;
    Ok(out)
}

fn register_dict<'py>(py: Python<'py>, r: &ProfileRegister) -> PyResult<Bound<'py, PyDict>> {
    let reg = &r.register;
    let d = PyDict::new(py);
    d.set_item("name", reg.name.as_str())?;
    d.set_item("address", reg.address)?;
    d.set_item(
        "table",
        match r.table {
            Table::Holding => "holding",
            Table::Input => "input",
            Table::Coils => "coil",
            Table::Discrete => "discrete",
        },
    )?;
    d.set_item("type", r.value.name())?;
    let (bit, length) = match r.value {
        ValueType::Bool { bit } => (bit, None),
        ValueType::Text { length } => (None, Some(length)),
        ValueType::Number(_) => (None, None),
    };
    d.set_item("bit", bit)?;
    d.set_item("length", length)?;
    d.set_item("order", r.layout.name())?;
    d.set_item("scale", reg.scale)?;
    d.set_item("offset", r.offset)?;
    d.set_item("signed", reg.signed)?;
    d.set_item("unit", reg.unit.as_str())?;
    d.set_item(
        "access",
        match reg.access {
            Access::Read => "r",
            Access::Write => "w",
            Access::ReadWrite | Access::WriteWhenStopped => "rw",
        },
    )?;
    let number = matches!(r.value, ValueType::Number(_));
    d.set_item("min", number.then_some(reg.range.0))?;
    d.set_item("max", number.then_some(reg.range.1))?;
    let members = PyDict::new(py);
    for (n, name) in &r.members {
        members.set_item(n, name.as_str())?;
    }
    d.set_item("enum", members)?;
    match &r.default {
        None => d.set_item("default", py.None())?,
        Some(ProfileValue::Int(n)) => d.set_item("default", n)?,
        Some(ProfileValue::Float(f)) => d.set_item("default", f)?,
        Some(ProfileValue::Bool(b)) => d.set_item("default", b)?,
        Some(ProfileValue::Text(t)) => d.set_item("default", t.as_str())?,
    }
    d.set_item("description", r.description.as_str())?;
    d.set_item("line", r.line)?;
    Ok(d)
}
