//! Device profiles: `Profile` (a profile file checked by the core; its mistakes as
//! `benchbus.ProfileError`) and `ProfileCore`, the compiled base of `benchbus.Device`.

use super::device_methods;
use super::{named_pairs, public, to_pyerr, Attached, PyBus, PyStation, EXCEPTIONS};
use crate::device::export::{family_note, FAMILIES};
use crate::device::family;
use crate::device::profile::{
    access_name, table_name, Names, Profile, ProfileError, ProfileRegister, ProfileValue, ValueType,
};
use crate::device::profiled::ProfiledDevice;
use crate::device::suggest::did_you_mean;
use pyo3::exceptions::{PyKeyError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyModule, PyString, PyTuple};
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// One request of a plan, as Python has it: table, first address, count, register names.
type PlannedRead = (&'static str, u16, u16, Vec<String>);

/// Where the public row types live.
const ROWS: &str = "benchbus._profile";

/// A device profile: a device described in a TOML file, checked by the core.
#[pyclass(frozen, module = "benchbus._core", name = "Profile")]
pub(super) struct PyProfile {
    profile: Arc<Profile>,
    /// The registers' indices in the order of their names: a name is found by a binary
    /// search (a scan for each name made reading every register quadratic).
    by_name: Vec<usize>,
    path: String,
    /// Comment lines for the top of the file `to_toml` writes ("" for none).
    note: String,
    /// A built-in family's file, which `to_toml` gives back as it is (its comments too).
    file: Option<&'static str>,
}

/// The name of the register at `index` ("" for none).
fn name_at(profile: &Profile, index: usize) -> &str {
    profile
        .registers
        .get(index)
        .map_or("", |r| r.register.name.as_str())
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

/// A value as Python has it.
fn to_object<'py>(py: Python<'py>, value: &ProfileValue) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        ProfileValue::Int(n) => n.into_pyobject(py)?.into_any(),
        ProfileValue::Float(f) => PyFloat::new(py, *f).into_any(),
        ProfileValue::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        ProfileValue::Text(t) => PyString::new(py, t).into_any(),
    })
}

/// `obj` as a value for the register `r`: TypeError for one of the wrong kind (a number for
/// a bool, text for a number that is not an enum, ...).
fn value_arg(r: &ProfileRegister, obj: &Bound<'_, PyAny>) -> PyResult<ProfileValue> {
    let name = &r.register.name;
    let wrong = |what: &str| -> PyResult<ProfileValue> {
        Err(PyTypeError::new_err(format!(
            "{name} takes {what}, got {}",
            obj.get_type().name()?
        )))
    };
    let enum_register = !r.members.is_empty();
    match r.value {
        ValueType::Bool { .. } => match obj.cast::<PyBool>() {
            Ok(b) => Ok(ProfileValue::Bool(b.is_true())),
            Err(_) => wrong("True or False"),
        },
        ValueType::Text { .. } => match obj.cast::<PyString>() {
            Ok(s) => Ok(ProfileValue::Text(s.to_cow()?.into_owned())),
            Err(_) => wrong("a str"),
        },
        ValueType::Number(_) => {
            if obj.is_instance_of::<PyBool>() {
                return wrong(if enum_register {
                    "a member, its name or its number"
                } else {
                    "a number"
                });
            }
            if let Ok(s) = obj.cast::<PyString>() {
                if enum_register {
                    return Ok(ProfileValue::Text(s.to_cow()?.into_owned()));
                }
                return wrong("a number");
            }
            if obj.is_instance_of::<PyFloat>() && !enum_register {
                return Ok(ProfileValue::Float(obj.extract()?));
            }
            if let Ok(n) = obj.extract::<i128>() {
                return Ok(ProfileValue::Int(n));
            }
            match obj.extract::<f64>() {
                Ok(f) if !enum_register => Ok(ProfileValue::Float(f)),
                _ => wrong(if enum_register {
                    "a member, its name or its number"
                } else {
                    "a number"
                }),
            }
        }
    }
}

impl PyProfile {
    fn new_checked(
        py: Python<'_>,
        path: String,
        loaded: Result<Profile, Box<ProfileError>>,
    ) -> PyResult<Self> {
        let profile = loaded.map_err(|e| profile_error(py, &e))?;
        Ok(PyProfile::made(profile, path, String::new()))
    }

    fn made(profile: Profile, path: String, note: String) -> PyProfile {
        let mut by_name: Vec<usize> = (0..profile.registers.len()).collect();
        by_name.sort_unstable_by(|a, b| name_at(&profile, *a).cmp(name_at(&profile, *b)));
        PyProfile {
            profile: Arc::new(profile),
            by_name,
            path,
            note,
            file: None,
        }
    }

    /// The index of the register called `name`, if there is one.
    fn find(&self, name: &str) -> Option<usize> {
        let at = self
            .by_name
            .binary_search_by(|i| name_at(&self.profile, *i).cmp(name))
            .ok()?;
        self.by_name.get(at).copied()
    }

    /// The register called `name`, or ValueError naming the profile.
    fn index(&self, name: &str) -> PyResult<usize> {
        self.find(name).ok_or_else(|| {
            let names = self
                .profile
                .registers
                .iter()
                .map(|r| r.register.name.as_str());
            let hint = did_you_mean(name, names);
            PyValueError::new_err(format!(
                "{} has no register {name:?}{hint}",
                self.profile.name
            ))
        })
    }

    /// The index of the register called `name` and `obj` as a value for it (ValueError for
    /// no such register, TypeError for a value of the wrong kind).
    fn value_for(&self, name: &str, obj: &Bound<'_, PyAny>) -> PyResult<(usize, ProfileValue)> {
        let index = self.index(name)?;
        let register = self
            .profile
            .registers
            .get(index)
            .ok_or_else(|| PyValueError::new_err(format!("no register {name:?}")))?;
        Ok((index, value_arg(register, obj)?))
    }

    /// The ``ProfileRegister`` class rows are made of.
    fn row_type(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        PyModule::import(py, ROWS)?.getattr("ProfileRegister")
    }

    /// The register `r` as a ``ProfileRegister`` (`row_type`: that class, looked up once for
    /// many rows). The keywords' names are interned: Python then matches them to the
    /// parameters by identity, where new strings were compared by their text.
    fn row<'py>(
        py: Python<'py>,
        row_type: &Bound<'py, PyAny>,
        r: &ProfileRegister,
    ) -> PyResult<Bound<'py, PyAny>> {
        let reg = &r.register;
        let (bit, length) = match r.value {
            ValueType::Bool { bit } => (bit, None),
            ValueType::Text { length } => (None, Some(length)),
            ValueType::Number(_) => (None, None),
        };
        let number = matches!(r.value, ValueType::Number(_));
        let members = PyDict::new(py);
        for (n, name) in &r.members {
            members.set_item(n, name.as_str())?;
        }
        let default = match &r.default {
            None => py.None().into_bound(py),
            Some(v) => to_object(py, v)?,
        };
        let kwargs = PyDict::new(py);
        kwargs.set_item(intern!(py, "name"), reg.name.as_str())?;
        kwargs.set_item(intern!(py, "address"), reg.address)?;
        kwargs.set_item(intern!(py, "table"), table_name(r.table))?;
        kwargs.set_item(intern!(py, "type"), r.value.name())?;
        kwargs.set_item(intern!(py, "bit"), bit)?;
        kwargs.set_item(intern!(py, "length"), length)?;
        kwargs.set_item(intern!(py, "order"), r.layout.name())?;
        kwargs.set_item(intern!(py, "scale"), reg.scale)?;
        kwargs.set_item(intern!(py, "offset"), r.offset)?;
        kwargs.set_item(intern!(py, "unit"), reg.unit.as_str())?;
        kwargs.set_item(intern!(py, "access"), access_name(reg.access))?;
        kwargs.set_item(intern!(py, "min"), number.then_some(reg.range.0))?;
        kwargs.set_item(intern!(py, "max"), number.then_some(reg.range.1))?;
        kwargs.set_item(intern!(py, "enum"), members)?;
        kwargs.set_item(intern!(py, "default"), default)?;
        kwargs.set_item(intern!(py, "description"), r.description.as_str())?;
        kwargs.set_item(intern!(py, "line"), r.line)?;
        kwargs.set_item(intern!(py, "models"), PyTuple::new(py, &r.models)?)?;
        let ranges = PyDict::new(py);
        for (model, range) in &r.ranges {
            ranges.set_item(model.as_str(), *range)?;
        }
        kwargs.set_item(intern!(py, "ranges"), ranges)?;
        kwargs.set_item(intern!(py, "bits"), r.bits)?;
        kwargs.set_item(intern!(py, "decimals"), r.decimals.as_deref())?;
        row_type.call((), Some(&kwargs))
    }
}

/// Python's rules for a profile's names: `benchbus._names`, asked for each name.
struct PyNames<'py> {
    register: Bound<'py, PyAny>,
    member: Bound<'py, PyAny>,
}

impl<'py> PyNames<'py> {
    fn new(py: Python<'py>) -> PyResult<Self> {
        let names = PyModule::import(py, "benchbus._names")?;
        Ok(PyNames {
            register: names.getattr("register_refusal")?,
            member: names.getattr("member_refusal")?,
        })
    }

    /// What `rule` says of `args`: its refusal, or None; a rule that fails refuses, saying
    /// so.
    fn ask(rule: &Bound<'py, PyAny>, args: impl pyo3::call::PyCallArgs<'py>) -> Option<String> {
        match rule.call1(args) {
            Ok(said) => said.extract::<Option<String>>().unwrap_or_else(|_| {
                Some(format!(
                    "cannot be checked: {} returned {said}",
                    rule_name(rule)
                ))
            }),
            Err(e) => Some(format!("cannot be checked: {e}")),
        }
    }
}

/// A Python callable's name, for a message.
fn rule_name(rule: &Bound<'_, PyAny>) -> String {
    rule.getattr("__name__")
        .and_then(|n| n.extract::<String>())
        .unwrap_or_else(|_| "the rule".to_string())
}

impl Names for PyNames<'_> {
    fn register(&self, name: &str) -> Option<String> {
        PyNames::ask(&self.register, (name,))
    }

    fn member(&self, register: &str, member: &str) -> Option<String> {
        PyNames::ask(&self.member, (register, member))
    }
}

#[pymethods]
impl PyProfile {
    /// Reads and checks the device profile (TOML) at `path`; ``ProfileError`` (a
    /// ``ValueError``) names the file, the line and the key of its first mistake.
    /// ``path`` may also be a profile's name (``"sdm630"``): ``BENCHBUS_PROFILES``'
    /// folders, then the profiles the package ships; a file that exists wins.
    #[new]
    fn new(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Self> {
        // The object as given (a str keeps "./x" and "x/", which a path would not).
        let path: PathBuf = PyModule::import(py, "benchbus._library")?
            .getattr("locate")?
            .call1((path,))?
            .extract()?;
        let shown = path.display().to_string();
        let loaded = Profile::load_with(&path, &PyNames::new(py)?);
        PyProfile::new_checked(py, shown, loaded)
    }

    /// Checks the profile `text`; `path` names it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, path = "<string>"))]
    fn parse(py: Python<'_>, text: &str, path: &str) -> PyResult<Self> {
        let parsed = Profile::parse_with(path, text, &PyNames::new(py)?);
        PyProfile::new_checked(py, path.to_string(), parsed)
    }

    /// The built-in family ``key`` ("drive", "pbl" or "j2") as a profile: the family's file
    /// as the package ships it (``families/``); "drive-c20" is its C20 model
    /// (``for_model("C20")``; the file's rows are the BLD's). ValueError for another key.
    #[staticmethod]
    fn family(key: &str) -> PyResult<Self> {
        let Some(profile) = Profile::family(key) else {
            return Err(PyValueError::new_err(format!(
                "no built-in family {key:?}: one of {}",
                FAMILIES.join(", ")
            )));
        };
        let file = family::text(key);
        let note = family_note(key).unwrap_or_default();
        Ok(PyProfile {
            file,
            ..PyProfile::made(profile, format!("<{key}>"), note)
        })
    }

    /// The keys :meth:`family` takes: the built-in families whose register map is a file
    /// ("drive", "drive-c20", "pbl", "j2").
    #[staticmethod]
    fn families() -> Vec<&'static str> {
        FAMILIES.to_vec()
    }

    /// The profile as a TOML file that reads back as the same profile (a built-in family's
    /// file as it is; each starts with comments on what its class does in code and the
    /// file cannot say).
    fn to_toml(&self) -> String {
        if let Some(file) = self.file {
            return file.to_string();
        }
        let mut out: String = self.note.lines().map(|l| format!("# {l}\n")).collect();
        if !out.is_empty() {
            out.push('\n');
        }
        out.push_str(&self.profile.to_toml());
        out
    }

    /// The device's name (``[device] name``).
    #[getter]
    fn name(&self) -> &str {
        &self.profile.name
    }

    /// The device's description ("" if the file has none).
    #[getter]
    fn description(&self) -> &str {
        &self.profile.description
    }

    /// Who makes the device (``[device] maker``; "" if the file does not say).
    #[getter]
    fn maker(&self) -> &str {
        &self.profile.about.maker
    }

    /// The model or series the file covers (``[device] model``; "").
    #[getter]
    fn model(&self) -> &str {
        &self.profile.about.model
    }

    /// What sort of device it is (``[device] kind``: "energy-meter", "sensor",
    /// "temperature-controller"...; "").
    #[getter]
    fn kind(&self) -> &str {
        &self.profile.about.kind
    }

    /// The document its registers were written from (``[device] source``: title, version,
    /// sections; "").
    #[getter]
    fn source(&self) -> &str {
        &self.profile.about.source
    }

    /// The models the file describes (``[device] models``; the first is the one its rows
    /// are written for), ``()`` for a file of one model.
    #[getter]
    fn models<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.profile.models)
    }

    /// The profile of ``model``, one of :attr:`models`: the registers that model has, each
    /// with its range there (a register's ``ranges``); ValueError for another name.
    fn for_model(&self, model: &str) -> PyResult<Self> {
        let Some(profile) = self.profile.for_model(model) else {
            return Err(PyValueError::new_err(format!(
                "{}: no model {model:?} (models: {})",
                self.path,
                if self.profile.models.is_empty() {
                    "none".to_string()
                } else {
                    self.profile.models.join(", ")
                }
            )));
        };
        Ok(PyProfile::made(
            profile,
            format!("{}[{model}]", self.path),
            String::new(),
        ))
    }

    /// The file it was read from (what ``parse`` was given for text).
    #[getter]
    fn path(&self) -> &str {
        &self.path
    }

    /// The ``[line]`` section as a ``ProfileLine`` (None where the file is silent).
    #[getter]
    fn line<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let l = &self.profile.line;
        let kwargs = PyDict::new(py);
        kwargs.set_item("baudrate", l.baudrate)?;
        kwargs.set_item("parity", l.parity.map(String::from))?;
        kwargs.set_item("stopbits", l.stopbits)?;
        kwargs.set_item("timeout", l.timeout)?;
        kwargs.set_item("framing", l.framing.as_deref())?;
        kwargs.set_item("bytesize", l.bytesize)?;
        public(py, ROWS, "ProfileLine", (), Some(&kwargs))
    }

    /// The ``[limits]`` section as a ``ProfileLimits`` (None where the file is silent).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let l = &self.profile.limits;
        let kwargs = PyDict::new(py);
        kwargs.set_item("max_read", l.max_read)?;
        kwargs.set_item("max_write", l.max_write)?;
        kwargs.set_item("min_write_interval", l.min_write_interval)?;
        kwargs.set_item("block_reads", l.block_reads)?;
        kwargs.set_item("read_gaps", l.read_gaps)?;
        let echo = l.write_echo.map(crate::device::profile::echo_name);
        kwargs.set_item("write_echo", echo)?;
        kwargs.set_item("write_multiple", l.write_multiple)?;
        public(py, ROWS, "ProfileLimits", (), Some(&kwargs))
    }

    /// Every register as a ``ProfileRegister``, in the file's order.
    #[getter]
    fn registers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let row_type = PyProfile::row_type(py)?;
        let rows = self
            .profile
            .registers
            .iter()
            .map(|r| PyProfile::row(py, &row_type, r))
            .collect::<PyResult<Vec<_>>>()?;
        PyTuple::new(py, rows)
    }

    /// The register called `name` (KeyError if there is none).
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let r = self
            .find(name)
            .and_then(|i| self.profile.registers.get(i))
            .ok_or_else(|| PyKeyError::new_err(name.to_string()))?;
        PyProfile::row(py, &PyProfile::row_type(py)?, r)
    }

    /// Whether a register is called `name`.
    fn __contains__(&self, name: &str) -> bool {
        self.find(name).is_some()
    }

    /// How many registers.
    fn __len__(&self) -> usize {
        self.profile.registers.len()
    }

    /// Checks ``value`` for the register ``name`` as writing it would, and sends nothing:
    /// ValueError for no such register, a read-only one, a value out of range, off the
    /// scale's steps, not a member or more than the type holds; TypeError for a value of
    /// the wrong kind. A family's rules that ask the device (a drive's registers that take
    /// writes only while stopped, the J2's SV within LSP..USP) are checked when writing;
    /// a register with ``decimals`` is checked against the widest range its places allow,
    /// and at its places (range, steps) when writing.
    fn check(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let (index, value) = self.value_for(name, value)?;
        self.profile
            .precheck(index, &value)
            .map_err(|e| to_pyerr(py, e))
    }

    /// The requests that read the registers `names` (repeats once): ``(table, start, count,
    /// names)`` each, tables apart, neighbours together where the limits allow; with the
    /// registers giving any of them their decimal places (``decimals``), read with them.
    fn plan(&self, names: Vec<String>) -> PyResult<Vec<PlannedRead>> {
        let indices = names
            .iter()
            .map(|n| self.index(n))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(self
            .profile
            .plan(&self.profile.with_places(&indices))
            .into_iter()
            .map(|b| {
                let members = b
                    .members
                    .iter()
                    .filter_map(|i| self.profile.registers.get(*i))
                    .map(|r| r.register.name.clone())
                    .collect();
                (table_name(b.table), b.start, b.count, members)
            })
            .collect())
    }

    /// ``<Profile 'NAME' (N registers) from PATH>``.
    fn __repr__(&self) -> String {
        format!(
            "<Profile {:?} ({} registers) from {}>",
            self.profile.name,
            self.profile.registers.len(),
            self.path
        )
    }
}

/// The compiled base of a device described by a profile (`benchbus.Device`).
#[pyclass(extends = PyStation, subclass, frozen, module = "benchbus._core", name = "ProfileCore")]
pub(super) struct PyProfileCore {
    dev: Attached<ProfiledDevice>,
    profile: OnceLock<Py<PyProfile>>,
}

impl PyProfileCore {
    fn profile_ref(&self) -> PyResult<&Py<PyProfile>> {
        self.profile.get().ok_or_else(|| {
            PyRuntimeError::new_err(
                "the device is not attached to a Bus: its class's __init__ did not run",
            )
        })
    }
}

device_methods! {
PyProfileCore = |dev| PyProfileCore {
            dev,
            profile: OnceLock::new(),
        };

    /// Attaches the device `profile` describes at `unit` to `bus` (what ``Device.__init__``
    /// does); `timeout` / `retries` replace the Bus's.
    #[pyo3(signature = (bus, unit, profile, timeout=None, retries=None))]
    fn _attach(
        slf: &Bound<'_, Self>,
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        profile: Bound<'_, PyProfile>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let me = slf.get();
        let described = Arc::clone(&profile.get().profile);
        me.dev.attach(
            slf.as_super().get(),
            bus,
            unit,
            super::unit_arg,
            timeout,
            retries,
            |bus, unit| Ok(ProfiledDevice::new(bus, unit, described)),
        )?;
        me.profile
            .set(profile.unbind())
            .map_err(|_| PyRuntimeError::new_err("the device is attached to a Bus already"))
    }

    /// The profile the device follows.
    #[getter]
    fn profile(&self, py: Python<'_>) -> PyResult<Py<PyProfile>> {
        Ok(self.profile_ref()?.clone_ref(py))
    }

    /// The values of the registers `names`, in that order, read in the fewest requests the
    /// profile's limits allow; enum registers as their numbers.
    fn _read<'py>(&self, py: Python<'py>, names: Vec<String>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let indices = {
            let profile = self.profile_ref()?.get();
            names
                .iter()
                .map(|n| profile.index(n))
                .collect::<PyResult<Vec<_>>>()?
        };
        let values = self.dev.wire(py, move |d| d.read(&indices))?;
        values.iter().map(|v| to_object(py, v)).collect()
    }

    /// Writes `values` ({name: value} or (name, value) pairs) in order; every value is
    /// checked before the first is sent.
    fn _write_many(&self, py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<()> {
        let profile = self.profile_ref()?.get();
        let pairs = named_pairs(py, values)?
            .iter()
            .map(|(name, value)| profile.value_for(name, value))
            .collect::<PyResult<Vec<_>>>()?;
        self.dev.wire(py, move |d| d.write_many(&pairs))
    }

    /// Writes `value` to the register `name`, every check made before anything is sent.
    fn _write(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let (index, value) = self.profile_ref()?.get().value_for(name, value)?;
        self.dev.wire(py, move |d| d.write(index, &value))
    }
}
