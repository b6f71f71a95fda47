//! `list_ports`: the serial ports the system knows, as Python dicts.

use crate::transport::ports::{self, PortInfo};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The serial ports of this system, sorted by path: a dict for each with `path`, `driver`,
/// and for a USB adapter `vid`, `pid`, `manufacturer`, `product`, `serial_number` and `chip`
/// (None where the system does not say). `sysfs_root` reads another sysfs tree than `/sys`
/// (Linux only). Runs without the GIL.
#[pyfunction]
#[pyo3(signature = (sysfs_root=None))]
pub fn list_ports<'py>(
    py: Python<'py>,
    sysfs_root: Option<PathBuf>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let found = py.detach(move || find(sysfs_root))?;
    found.iter().map(|p| as_dict(py, p)).collect()
}

#[cfg(target_os = "linux")]
fn find(root: Option<PathBuf>) -> PyResult<Vec<PortInfo>> {
    match root {
        Some(root) => Ok(ports::list_ports_in(&root)?),
        None => Ok(ports::list_ports()?),
    }
}

#[cfg(not(target_os = "linux"))]
fn find(root: Option<PathBuf>) -> PyResult<Vec<PortInfo>> {
    if root.is_some() {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "sysfs_root is for Linux only",
        ));
    }
    Ok(ports::list_ports()?)
}

fn as_dict<'py>(py: Python<'py>, port: &PortInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("path", &port.path)?;
    d.set_item("driver", port.driver.as_deref())?;
    let usb = port.usb.as_ref();
    d.set_item("vid", usb.map(|u| u.vid))?;
    d.set_item("pid", usb.map(|u| u.pid))?;
    d.set_item("manufacturer", usb.and_then(|u| u.manufacturer.as_deref()))?;
    d.set_item("product", usb.and_then(|u| u.product.as_deref()))?;
    d.set_item(
        "serial_number",
        usb.and_then(|u| u.serial_number.as_deref()),
    )?;
    d.set_item("chip", usb.and_then(|u| u.chip()))?;
    Ok(d)
}
