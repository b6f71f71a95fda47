//! PyO3 bindings: argument conversion, exception mapping, GIL release. Nothing else.
//!
//! Every call that touches the wire runs inside `py.detach`, so other Python threads (and
//! other buses) go on while one waits for its device.

mod cancel;
mod doctor;
mod drive;
mod instrument;
mod j2;
mod pbl;
mod poll;
mod ports;
mod profile;
mod ticks;
mod values;

use crate::bus::{self, BusConfig, TxOptions, STANDARD_UNITS, UNITS};
use crate::codec::ascii::AsciiError;
use crate::codec::pdu::decode;
use crate::codec::pdu::{
    Request, MAX_FILE_RECORD, MAX_PDU_DATA, MAX_READ_BITS, MAX_READ_COUNT, MAX_READ_WRITE_COUNT,
    MAX_WRITE_BITS, MAX_WRITE_COUNT, WRITE_MULTIPLE_COILS, WRITE_MULTIPLE_REGISTERS,
    WRITE_SINGLE_COIL, WRITE_SINGLE_REGISTER,
};
use crate::codec::{hex, mbap, reply, Echo, FrameError, Framing};
use crate::device::Device;
use crate::error::Error;
use crate::timing::{LineFormat, Parity};
use crate::transport::tuning::Rs485;
use pyo3::exceptions::{PyAttributeError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{
    PyBool, PyByteArray, PyBytes, PyDict, PyFloat, PyInt, PyMapping, PyModule, PyString, PyTuple,
};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

static LOG_RESET: OnceLock<pyo3_log::ResetHandle> = OnceLock::new();
static EXCEPTIONS: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

thread_local! {
    /// The exception a signal handler raised between two attempts of this thread's call
    /// (see [`signal_raised`]), until [`to_pyerr`] raises it.
    static RAISED: std::cell::RefCell<Option<PyErr>> = const { std::cell::RefCell::new(None) };
}

/// Every Bus's [`BusConfig::interrupted`]: runs Python's signal handlers (from a detached
/// call, so it takes the GIL for that moment) and says whether one raised, Ctrl-C's
/// `KeyboardInterrupt` above all. Handlers run only in the main thread; elsewhere this is a
/// cheap no.
fn signal_raised() -> bool {
    Python::attach(|py| match py.check_signals() {
        Ok(()) => false,
        Err(e) => {
            RAISED.with(|slot| *slot.borrow_mut() = Some(e));
            true
        }
    })
}

/// The module `benchbus.exceptions`, imported once.
fn exceptions(py: Python<'_>) -> PyResult<&Bound<'_, PyModule>> {
    EXCEPTIONS
        .get_or_try_init(py, || {
            PyModule::import(py, "benchbus.exceptions").map(Bound::unbind)
        })
        .map(|m| m.bind(py))
}

/// Maps a crate error to the Python exception tree of `benchbus.exceptions` (the one place
/// this happens).
fn to_pyerr(py: Python<'_>, err: Error) -> PyErr {
    let message = err.to_string();
    let frame = err.frame().map(hex);
    let (class, unit, function) = match &err {
        Error::InvalidArgument(m) => return PyValueError::new_err(m.clone()),
        // The signal handler's own exception (KeyboardInterrupt), as Python would raise it.
        Error::Interrupted { unit, function, .. } => match RAISED.with(|slot| slot.take()) {
            Some(raised) => return raised,
            None => ("BenchbusError", Some(*unit), Some(*function)),
        },
        // The check's own exception (WrongDevice, the timeout of its reads).
        Error::Unvouched { unit, .. } => match RAISED.with(|slot| slot.take()) {
            Some(raised) => return raised,
            None => ("BenchbusError", Some(*unit), None),
        },
        Error::Cancelled { unit, function, .. } => ("Cancelled", Some(*unit), Some(*function)),
        Error::Port { .. } | Error::Closed { .. } | Error::Forked { .. } => {
            ("PortError", None, None)
        }
        Error::Timeout { unit, function, .. } => ("ResponseTimeout", Some(*unit), Some(*function)),
        Error::Frame {
            unit,
            function,
            kind: FrameError::Crc { .. } | FrameError::Ascii(AsciiError::Lrc { .. }),
            ..
        } => ("CrcError", Some(*unit), Some(*function)),
        Error::Frame { unit, function, .. } => ("FrameError", Some(*unit), Some(*function)),
        Error::State { unit, .. } => ("StateError", Some(*unit), None),
        Error::Exception {
            unit,
            function,
            code,
            ..
        } if crate::codec::is_gateway_exception(*code) => {
            ("GatewayError", Some(*unit), Some(*function))
        }
        Error::Exception { unit, function, .. } => {
            ("ModbusException", Some(*unit), Some(*function))
        }
        Error::Internal(_) => ("BenchbusError", None, None),
    };
    let build = || -> PyResult<PyErr> {
        let module = exceptions(py)?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("unit", unit)?;
        kwargs.set_item("function", function)?;
        kwargs.set_item("frame", frame)?;
        if let Error::Exception { code, meaning, .. } = &err {
            kwargs.set_item("code", *code)?;
            kwargs.set_item("meaning", meaning.as_str())?;
        }
        let instance = module.getattr(class)?.call((message,), Some(&kwargs))?;
        Ok(PyErr::from_value(instance))
    };
    build().unwrap_or_else(|e| e)
}

/// The Python module of the Bus's result types (`CommEventCounter`, `CommEventLog`).
const RESULTS: &str = "benchbus._results";

/// A comm event log (function 0x0C: status word, event and message counters, events) as
/// the `CommEventLog` users see, for the Bus and the Instrument alike.
fn comm_event_log(
    py: Python<'_>,
    (status, events, messages, log): (u16, u16, u16, Vec<u8>),
) -> PyResult<Bound<'_, PyAny>> {
    let log = PyBytes::new(py, &log);
    public(
        py,
        RESULTS,
        "CommEventLog",
        (status, events, messages, log),
        None,
    )
}

/// An instance of the public Python type `module.name` (a dataclass, an enum) made from
/// `args` and `kwargs`: how a binding returns a result typed as users see it, without a
/// Python method in between. The module is imported on first use (it is already loaded
/// whenever a device exists).
fn public<'py>(
    py: Python<'py>,
    module: &str,
    name: &str,
    args: impl pyo3::call::PyCallArgs<'py>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    PyModule::import(py, module)?
        .getattr(name)?
        .call(args, kwargs)
}

/// The member of the public enum `module.name` whose value is `value`, or its `UNKNOWN`
/// value carrying the number when the enum has none (a device may report a code its manual
/// does not list): `benchbus._device.as_enum`, the one rule for every family.
fn member<'py>(
    py: Python<'py>,
    module: &str,
    name: &str,
    value: i64,
) -> PyResult<Bound<'py, PyAny>> {
    let enum_type = PyModule::import(py, module)?.getattr(name)?;
    public(py, "benchbus._device", "as_enum", (enum_type, value), None)
}

/// What a wire call runs on: a Bus, or a device on one.
trait OnBus: Send + Sync {
    /// The Bus its calls go over (None: no Bus, for the test hook `_panic_on_wire`).
    fn on_bus(&self) -> Option<&bus::Bus>;
}

impl OnBus for bus::Bus {
    fn on_bus(&self) -> Option<&bus::Bus> {
        Some(self)
    }
}

impl<D: Device> OnBus for D {
    fn on_bus(&self) -> Option<&bus::Bus> {
        Some(self.bus())
    }
}

impl OnBus for () {
    fn on_bus(&self) -> Option<&bus::Bus> {
        None
    }
}

/// Runs `f` on a device core (or a Bus) with the GIL released; its error as the Python
/// exception. An exception reply that came over Modbus TCP is worded for it
/// ([`mbap::exception_meaning`]: a 0x06 may be a benchbus gateway's).
fn on_wire<D: OnBus, T: Send>(
    py: Python<'_>,
    device: &Arc<D>,
    f: impl FnOnce(&D) -> crate::Result<T> + Send,
) -> PyResult<T> {
    let device = Arc::clone(device);
    let on = Arc::clone(&device);
    let result = py.detach(move || crate::error::guarded(|| f(&device)));
    // A Ctrl-C that lands while the wire log calls into Python (pyo3-log, from the detached
    // thread) can leave the KeyboardInterrupt set: raise it, rather than return a value
    // with an exception pending (which Python reports as a SystemError).
    if let Some(pending) = PyErr::take(py) {
        return Err(pending);
    }
    result.map_err(|e| to_pyerr(py, over_modbus_tcp(on.on_bus(), e)))
}

/// `err`, with the meaning of an exception reply worded for Modbus TCP if `bus` speaks it.
fn over_modbus_tcp(bus: Option<&bus::Bus>, err: Error) -> Error {
    let tcp = bus.is_some_and(|b| b.config().endpoint().framing() == Framing::Mbap);
    match err {
        Error::Exception {
            unit,
            function,
            code,
            meaning,
            frame,
        } if tcp => Error::Exception {
            unit,
            function,
            code,
            meaning: mbap::exception_meaning(code, &meaning),
            frame,
        },
        other => other,
    }
}

/// `#[pymethods] impl $class { ... }` with the `__new__` every compiled device class has:
/// an empty object made by `$make` (a closure from the [`Attached`] to the class), which
/// takes any arguments so that the Python class's `__init__` may have its own, and attaches
/// it (`_attach`). After `tabled;`, also `get` and `set` of any row by name, the same for
/// every family with a table ([`crate::device::Tabled`]), and `get_many` / `set_many`. After `attach = Xy::new;`, the
/// `_attach` of a family whose core takes only the Bus and the unit (1..=255).
macro_rules! device_methods {
    ($class:ident = $make:expr; attach = $new:path; $($body:tt)*) => {
        device_methods! {
            $class = $make;
            $($body)*

            /// Attaches the device at ``unit`` to ``bus`` (what its class's ``__init__``
            /// does); ``timeout`` / ``retries`` replace the Bus's.
            #[pyo3(signature = (bus, unit, timeout=None, retries=None))]
            fn _attach(
                slf: &Bound<'_, Self>,
                bus: Bound<'_, PyBus>,
                unit: &Bound<'_, PyAny>,
                timeout: Option<&Bound<'_, PyAny>>,
                retries: Option<&Bound<'_, PyAny>>,
            ) -> PyResult<()> {
                let station = slf.as_super().get();
                let units = $crate::python::unit_arg;
                slf.get()
                    .dev
                    .attach(station, bus, unit, units, timeout, retries, |b, u| Ok($new(b, u)))
            }
        }
    };
    ($class:ident = $make:expr; tabled; $($body:tt)*) => {
        device_methods! {
            $class = $make;

            /// Reads the register called ``name`` (see the table), in engineering units: an
            /// int, or a float for a scaled register; a member of its enum where the
            /// device's class names its values.
            fn get<'py>(
                slf: &Bound<'py, Self>,
                py: Python<'py>,
                name: &Bound<'py, PyAny>,
            ) -> PyResult<Bound<'py, PyAny>> {
                use $crate::device::Tabled;
                let name = $crate::python::row_name(name)?;
                let read = move |d: &_| Ok((Tabled::row(d, &name)?, Tabled::get(d, &name)?));
                let (row, raw) = slf.get().dev.wire(py, read)?;
                let shown = $crate::python::shown_row(py, row, raw);
                $crate::python::named(slf.as_any(), &row.register.name, shown)
            }

            /// Writes ``value`` (engineering units) to the register called ``name``, checked
            /// against its range, steps, access and the family's rules before anything is sent.
            fn set(
                &self,
                py: Python<'_>,
                name: &Bound<'_, PyAny>,
                value: &Bound<'_, PyAny>,
            ) -> PyResult<()> {
                let name = $crate::python::row_name(name)?;
                let value = $crate::python::number(value, &name)?;
                self.dev.wire(py, move |d| $crate::device::Tabled::set(d, &name, value))
            }

            /// Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
            /// each as :meth:`get` gives it,
            /// in as few requests as the table's limits allow (neighbours share one).
            fn get_many<'py>(
                slf: &Bound<'py, Self>,
                py: Python<'py>,
                names: &Bound<'py, PyAny>,
            ) -> PyResult<Bound<'py, PyDict>> {
                use $crate::device::Tabled;
                let names = $crate::python::name_list(names)?;
                let read = move |d: &_| {
                    let values = Tabled::get_many(d, &names)?;
                    names
                        .iter()
                        .zip(values)
                        .map(|(n, v)| Ok((Tabled::row(d, n)?, v)))
                        .collect::<$crate::Result<Vec<_>>>()
                };
                let out = PyDict::new(py);
                for (row, value) in slf.get().dev.wire(py, read)? {
                    let shown = $crate::python::shown_row(py, row, value);
                    let name = &row.register.name;
                    out.set_item(name, $crate::python::named(slf.as_any(), name, shown)?)?;
                }
                Ok(out)
            }

            /// Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
            /// as :meth:`set` does. Every value is checked against its register (range,
            /// steps, access) before the first is sent; the family's rules are checked write
            /// by write, so a refusal there leaves the earlier writes done.
            fn set_many(&self, py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<()> {
                let mut pairs = Vec::new();
                for (name, value) in $crate::python::named_pairs(py, values)? {
                    let value = $crate::python::number(&value, &name)?;
                    pairs.push((name, value));
                }
                self.dev.wire(py, move |d| $crate::device::Tabled::set_many(d, &pairs))
            }

            $($body)*
        }
    };
    ($class:ident = $make:expr; $($body:tt)*) => {
        #[pymethods]
        impl $class {
            #[new]
            #[pyo3(signature = (*_args, **_kwargs))]
            fn new(
                _args: &Bound<'_, PyTuple>,
                _kwargs: Option<&Bound<'_, PyDict>>,
            ) -> PyClassInitializer<Self> {
                Attached::class($make)
            }

            $($body)*
        }
    };
}
pub(super) use device_methods;

/// A device core, once its Python object is attached to a Bus: what every device binding
/// holds. The object is made empty (`__new__` takes any arguments, so that a subclass's
/// `__init__` may have its own) and attached by its class's `__init__`, through the one
/// path every family shares, [`Attached::attach`].
pub(super) struct Attached<D> {
    device: OnceLock<Arc<D>>,
    identity: Arc<Identity>,
}

/// Whether a device's unit has been found to be of its family: checked before the device's
/// first exchange (by a Python callable its class gives, `_check_identity_with`), once.
enum Vouch {
    /// Nothing to check: a device without an identity check, or one that passed it.
    Vouched,
    /// To check: the callable returns if the unit may be of the family, raises
    /// `WrongDevice` if it looks like another, or an error that says nothing of it (a
    /// timeout: a unit off now is checked when it answers).
    Unchecked(Py<PyAny>),
    /// Found to be another family's: the `WrongDevice`, raised again by every call.
    Refused(Py<PyAny>),
}

/// The identity check of one device, shared by its [`PyStation`] and its [`Attached`].
pub(super) struct Identity(std::sync::Mutex<Vouch>);

impl Identity {
    fn state(&self) -> std::sync::MutexGuard<'_, Vouch> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Ok once the unit is vouched for; runs the check if it is due (without the lock:
    /// the check calls the Bus, which lets other threads run). The WrongDevice it raises
    /// is kept and raised again by every later call, with nothing sent.
    fn vouch_now(&self, py: Python<'_>) -> PyResult<()> {
        let check = match &*self.state() {
            Vouch::Vouched => return Ok(()),
            Vouch::Refused(err) => return Err(refused(py, err)),
            Vouch::Unchecked(check) => check.clone_ref(py),
        };
        match check.call0(py) {
            Ok(_) => {
                let mut state = self.state();
                if matches!(*state, Vouch::Unchecked(_)) {
                    *state = Vouch::Vouched;
                }
                Ok(())
            }
            Err(err) => {
                let wrong = exceptions(py)?.getattr(intern!(py, "WrongDevice"))?;
                if err.is_instance(py, &wrong) {
                    *self.state() = Vouch::Refused(err.value(py).clone().into_any().unbind());
                }
                Err(err)
            }
        }
    }

    /// Whether the unit was found to be another family's.
    fn refused(&self) -> bool {
        matches!(*self.state(), Vouch::Refused(_))
    }
}

impl std::fmt::Debug for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let state = match &*self.state() {
            Vouch::Vouched => "vouched",
            Vouch::Unchecked(_) => "unchecked",
            Vouch::Refused(_) => "refused",
        };
        f.write_str(state)
    }
}

/// The core's side of the check: run from a request with the GIL released, it takes the
/// GIL for the check (whose reads release it again), and hands the check's Python
/// exception to [`to_pyerr`] through [`RAISED`], as a signal handler's is.
impl crate::device::Vouch for Identity {
    fn vouch(&self, unit: u8) -> crate::Result<()> {
        if matches!(*self.state(), Vouch::Vouched) {
            return Ok(());
        }
        Python::attach(|py| self.vouch_now(py)).map_err(|err| {
            let reason = err.to_string();
            RAISED.with(|slot| *slot.borrow_mut() = Some(err));
            Error::Unvouched { unit, reason }
        })
    }
}

/// The kept WrongDevice `err`, to raise again (its old traceback dropped).
fn refused(py: Python<'_>, err: &Py<PyAny>) -> PyErr {
    let err = err.bind(py);
    // A traceback that cannot be cleared only makes the new one longer.
    let _ = err.setattr(intern!(py, "__traceback__"), py.None());
    PyErr::from_value(err.clone())
}

impl<D: Device + 'static> Attached<D> {
    /// The empty device class `T` that `wrap` makes, on an empty [`PyStation`]: what a
    /// device binding's `#[new]` returns.
    fn class<T: pyo3::PyClass<BaseType = PyStation>>(
        wrap: impl FnOnce(Self) -> T,
    ) -> PyClassInitializer<T> {
        let identity = Arc::new(Identity(std::sync::Mutex::new(Vouch::Vouched)));
        let station = PyStation {
            at: OnceLock::new(),
            identity: Arc::clone(&identity),
        };
        let empty = Attached {
            device: OnceLock::new(),
            identity,
        };
        PyClassInitializer::from(station).add_subclass(wrap(empty))
    }

    /// Converts the arguments every device takes (`unit`, checked by the family's `units`:
    /// [`unit_arg`] or [`standard_unit_arg`]; its own `timeout` and `retries`), builds the
    /// core with `build` on the Bus and the unit (which validates the family's own
    /// arguments), gives it its own timing, and attaches it here and the Bus and unit to
    /// `station`. Once only: a device attached already raises RuntimeError.
    #[allow(clippy::too_many_arguments)]
    fn attach(
        &self,
        station: &PyStation,
        bus: Bound<'_, PyBus>,
        unit: &Bound<'_, PyAny>,
        units: fn(&Bound<'_, PyAny>) -> PyResult<u8>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
        build: impl FnOnce(Arc<bus::Bus>, u8) -> crate::Result<D>,
    ) -> PyResult<()> {
        let already = || PyRuntimeError::new_err("the device is attached to a Bus already");
        if station.at.get().is_some() {
            return Err(already());
        }
        let unit = units(unit)?;
        let (timeout, retries) = own_timing(timeout, retries)?;
        let device = build(Arc::clone(&bus.get().bus), unit)
            .map_err(|e| to_pyerr(bus.py(), e))?
            .with_timing(timeout, retries)
            .with_vouch(Arc::clone(&self.identity) as Arc<dyn crate::device::Vouch>);
        station
            .at
            .set((bus.unbind(), unit))
            .map_err(|_| already())?;
        self.device.set(Arc::new(device)).map_err(|_| already())
    }

    /// The core, for what needs no wire; RuntimeError before the device is attached.
    fn device(&self) -> PyResult<&Arc<D>> {
        self.device.get().ok_or_else(unattached)
    }

    /// Runs `f` on the core with the GIL released; its error as the Python exception.
    /// Each request of the core is sent once the unit is vouched for (see [`Identity`]).
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&D) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        on_wire(py, self.device()?, f)
    }

    /// What leaving a motor's `with` block sends, `f` (an urgent stop goes without the
    /// unit's check: see [`crate::device::Station::write_urgent`]): nothing to a unit found
    /// to be another family's.
    fn stop_on_exit(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&D) -> crate::Result<()> + Send,
    ) -> PyResult<()> {
        if self.identity.refused() {
            return Ok(());
        }
        self.wire(py, f)
    }
}

/// The error of a device used before its `__init__` attached it to a Bus.
fn unattached() -> PyErr {
    PyRuntimeError::new_err(
        "the device is not attached to a Bus: its class's __init__ did not run (a subclass's \
         __init__ must call super().__init__(...))",
    )
}

/// The base of every compiled device class: the Bus the device talks through and its unit,
/// once for all families (set when the device is attached: see [`Attached::attach`]).
#[pyclass(subclass, frozen, module = "benchbus._core", name = "_Station")]
pub(super) struct PyStation {
    at: OnceLock<(Py<PyBus>, u8)>,
    identity: Arc<Identity>,
}

#[pymethods]
impl PyStation {
    /// The Bus the device talks through.
    #[getter]
    fn bus(&self, py: Python<'_>) -> PyResult<Py<PyBus>> {
        let (bus, _) = self.at.get().ok_or_else(unattached)?;
        Ok(bus.clone_ref(py))
    }

    /// The device's unit address.
    #[getter]
    fn unit(&self) -> PyResult<u8> {
        let (_, unit) = self.at.get().ok_or_else(unattached)?;
        Ok(*unit)
    }

    /// Checks now, if not done yet, that the unit is of the device's family (what the
    /// device's first exchange does): ``WrongDevice`` if it answers as another family, a
    /// timeout if it does not answer (it is checked again on the next call). Nothing to
    /// check for a device made with ``check_identity=False`` or without an identity (an
    /// ``Instrument``, a profile's ``Device``).
    fn verify_identity(&self, py: Python<'_>) -> PyResult<()> {
        self.at.get().ok_or_else(unattached)?;
        self.identity.vouch_now(py)
    }

    /// Makes ``check()`` the identity check before the first exchange (what a family's
    /// ``__init__`` does, unless made with ``check_identity=False``).
    fn _check_identity_with(&self, check: Py<PyAny>) {
        *self.identity.state() = Vouch::Unchecked(check);
    }
}

/// A write's `write_interval` in seconds, 0..=60 (None: 0, no pacing).
fn write_interval_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Duration> {
    let interval = opt(obj, Duration::ZERO, |w| seconds(w, "write_interval", true))?;
    if interval > Duration::from_secs(60) {
        return Err(PyValueError::new_err(format!(
            "write_interval must be 0 to 60 seconds, got {}",
            interval.as_secs_f64()
        )));
    }
    Ok(interval)
}

/// A line format from `baudrate` (default 19200), `parity` (a letter, default "N") and
/// `stopbits` (default 1).
fn line_arg(
    baudrate: Option<&Bound<'_, PyAny>>,
    parity: Option<&Bound<'_, PyAny>>,
    stopbits: Option<&Bound<'_, PyAny>>,
) -> PyResult<LineFormat> {
    let baudrate = opt(baudrate, 19_200, |b| int_in(b, "baudrate", 50, 4_000_000))? as u32;
    let letter: String = opt(parity, "N".to_string(), |p| {
        p.extract()
            .map_err(|_| PyTypeError::new_err("parity must be 'N', 'E' or 'O'"))
    })?;
    let parity = Parity::from_letter(&letter).ok_or_else(|| {
        PyValueError::new_err(format!("parity must be 'N', 'E' or 'O', got {letter:?}"))
    })?;
    let stop_bits = opt(stopbits, 1, |s| u8_in(s, "stopbits", 1, 2))?;
    Ok(LineFormat::new(baudrate, parity, stop_bits))
}

/// `framing` of a Bus ("rtu", the default, or "ascii") and its line format with
/// `bytesize` (7 or 8): whether the Bus speaks Modbus ASCII, and `line` (from
/// [`line_arg`]) with the data bits and the framing's defaults for what was not given. In
/// ASCII the serial line spec's 7E1 (parity "E", 7 data bits), and 2 stop bits for 7 data
/// bits without parity (7N2: 7N1 is not allowed, and is refused when the Bus opens); in RTU
/// 8 data bits.
fn framing_arg(
    framing: Option<&Bound<'_, PyAny>>,
    bytesize: Option<&Bound<'_, PyAny>>,
    parity: Option<&Bound<'_, PyAny>>,
    stopbits: Option<&Bound<'_, PyAny>>,
    mut line: LineFormat,
) -> PyResult<(bool, LineFormat)> {
    let name: String = opt(framing, "rtu".to_string(), |f| {
        f.extract()
            .map_err(|_| PyTypeError::new_err("framing must be 'rtu' or 'ascii'"))
    })?;
    let ascii = match name.as_str() {
        "rtu" => false,
        "ascii" => true,
        _ => {
            return Err(PyValueError::new_err(format!(
                "framing must be 'rtu' or 'ascii', got {name:?}"
            )))
        }
    };
    let given = |arg: Option<&Bound<'_, PyAny>>| arg.is_some_and(|a| !a.is_none());
    let default_bits = if ascii {
        crate::codec::ascii::DATA_BITS
    } else {
        8
    };
    line.data_bits = opt(bytesize, default_bits, |b| u8_in(b, "bytesize", 7, 8))?;
    if ascii && !given(parity) {
        line.parity = Parity::Even;
    }
    if ascii && !given(stopbits) && line.data_bits == 7 && line.parity == Parity::None {
        line.stop_bits = 2;
    }
    Ok((ascii, line))
}

/// `rs485` and `rts_delay` of a Bus: the kernel RS485 mode to set, if any. `rts_delay` is
/// `(before, after)` in seconds, each 0 to 0.1, and only with `rs485=True`.
fn rs485_arg(
    rs485: Option<&Bound<'_, PyAny>>,
    rts_delay: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<Rs485>> {
    let on = opt(rs485, false, |r| bool_arg(r, "rs485"))?;
    let Some(delay) = rts_delay.filter(|d| !d.is_none()) else {
        return Ok(on.then(Rs485::default));
    };
    if !on {
        return Err(PyValueError::new_err(
            "rts_delay is for the kernel RS485 mode: give rs485=True with it",
        ));
    }
    let not_a_pair =
        || PyTypeError::new_err("rts_delay must be a pair of seconds: (before, after)");
    if delay.is_instance_of::<PyString>() || delay.is_instance_of::<PyBytes>() {
        return Err(not_a_pair());
    }
    let pair = delay
        .try_iter()
        .map_err(|_| not_a_pair())?
        .collect::<PyResult<Vec<_>>>()?;
    if pair.len() != 2 {
        return Err(not_a_pair());
    }
    let mut each = [Duration::ZERO; 2];
    for (slot, (obj, name)) in each
        .iter_mut()
        .zip(pair.iter().zip(["rts_delay before", "rts_delay after"]))
    {
        let value = seconds_value(obj, name)?;
        if !(value.is_finite() && value >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "{name} sending must be 0 or more seconds, got {value}"
            )));
        }
        *slot = Duration::try_from_secs_f64(value)
            .map_err(|_| PyValueError::new_err(format!("{name} is out of range: {value}")))?;
    }
    Rs485::new(each[0], each[1])
        .map(Some)
        .map_err(PyValueError::new_err)
}

/// A bool argument (True or False, nothing truthy in their place).
fn bool_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    obj.cast::<PyBool>()
        .map(|b| b.is_true())
        .map_err(|_| PyTypeError::new_err(format!("{name} must be True or False")))
}

/// An int argument in `lo..=hi`: TypeError for a non-int, ValueError (never OverflowError)
/// for an int out of range.
fn int_in(obj: &Bound<'_, PyAny>, name: &str, lo: i64, hi: i64) -> PyResult<i64> {
    if obj.is_instance_of::<PyBool>() || !obj.is_instance_of::<PyInt>() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be an int, got {}",
            obj.get_type().name()?
        )));
    }
    match obj.extract::<i64>() {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v),
        _ => Err(PyValueError::new_err(format!(
            "{name} must be {lo} to {hi}, got {obj}"
        ))),
    }
}

/// `obj`, an int (not a bool) that `choices` lists, as the value listed with it: TypeError
/// ("`name` must be `kind`") for another type, ValueError ("must be `allowed`") for an int
/// not listed.
fn int_choice<T: Copy>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    kind: &str,
    allowed: &str,
    choices: &[(i64, T)],
) -> PyResult<T> {
    if obj.is_instance_of::<PyBool>() || !obj.is_instance_of::<PyInt>() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be {kind}, got {}",
            obj.get_type().name()?
        )));
    }
    let n = obj.extract::<i64>().ok();
    match choices.iter().find(|(code, _)| Some(*code) == n) {
        Some((_, value)) => Ok(*value),
        None => Err(PyValueError::new_err(format!(
            "{name} must be {allowed}, got {}",
            obj.repr()?
        ))),
    }
}

/// A register's name given to `get` / `set`: a str, else TypeError.
fn row_name(name: &Bound<'_, PyAny>) -> PyResult<String> {
    if !name.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "a register is named by a str, got {}",
            name.get_type().name()?
        )));
    }
    name.extract()
}

/// `obj` as a list of its items; TypeError naming `name` for a str, bytes or a non-iterable.
fn listed<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let refuse = || -> PyResult<PyErr> {
        Ok(PyTypeError::new_err(format!(
            "{name} must be {what}, got {}",
            obj.get_type().name()?
        )))
    };
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
        return Err(refuse()?);
    }
    match obj.try_iter() {
        Ok(items) => items.collect(),
        Err(_) => Err(refuse()?),
    }
}

/// `values`, ``{name: value}`` or ``(name, value)`` pairs, as (name, value) in order: each
/// name a str ([`row_name`]), the values as given, for the caller to convert.
fn named_pairs<'py>(
    py: Python<'py>,
    values: &Bound<'py, PyAny>,
) -> PyResult<Vec<(String, Bound<'py, PyAny>)>> {
    let what = "{name: value} or (name, value) pairs";
    let items = match values.cast::<PyMapping>() {
        Ok(mapping) => listed(mapping.items()?.as_any(), "values", what)?,
        Err(_) => listed(values, "values", what)?,
    };
    let mut pairs = Vec::with_capacity(items.len());
    for item in &items {
        let pair = listed(item, "values", what)?;
        if pair.len() != 2 {
            return Err(PyValueError::new_err(format!(
                "values must be {what}, got an item of {}: {}",
                pair.len(),
                PyTuple::new(py, &pair)?.repr()?
            )));
        }
        pairs.push((row_name(&pair[0])?, pair[1].clone()));
    }
    Ok(pairs)
}

/// `names`, a list of register names (not one str), each checked a str.
fn name_list(names: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
    let names = listed(names, "names", "a list of names ([\"speed\", \"current\"])")?;
    names.iter().map(row_name).collect()
}

/// `value` of the row `name` as `device`'s class names it: what its `_named(name, value)`
/// gives (a family's Python class: a member of the register's enum), else as it is.
fn named<'py>(
    device: &Bound<'py, PyAny>,
    name: &str,
    value: Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let py = device.py();
    match device.getattr(intern!(py, "_named")) {
        Ok(hook) => hook.call1((name, value)),
        Err(e) if e.is_instance_of::<PyAttributeError>(py) => Ok(value),
        Err(e) => Err(e),
    }
}

/// A value of `register` as Python shows it: an int for a whole-number register, else a
/// float.
fn shown<'py>(
    py: Python<'py>,
    register: &crate::device::Register<String>,
    value: f64,
) -> Bound<'py, PyAny> {
    if register.is_integer() {
        PyInt::new(py, value as i64).into_any()
    } else {
        PyFloat::new(py, value).into_any()
    }
}

/// A row's value as Python shows it: a flag (a bool row) as a bool, else as [`shown`].
fn shown_row<'py>(
    py: Python<'py>,
    row: &crate::device::profile::ProfileRegister,
    value: f64,
) -> Bound<'py, PyAny> {
    match row.value {
        crate::device::profile::ValueType::Bool { .. } => {
            PyBool::new(py, value != 0.0).to_owned().into_any()
        }
        _ => shown(py, &row.register, value),
    }
}

/// A number (int or float, not bool) as f64: TypeError for anything else.
fn number(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if obj.is_instance_of::<PyBool>()
        || !(obj.is_instance_of::<PyInt>() || obj.is_instance_of::<PyFloat>())
    {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a number, got {}",
            obj.get_type().name()?
        )));
    }
    obj.extract::<f64>()
        .map_err(|_| PyValueError::new_err(format!("{name} is out of range: {obj}")))
}

/// An optional argument: its default when absent (or None), else converted by `f`.
fn opt<'py, T>(
    obj: Option<&Bound<'py, PyAny>>,
    default: T,
    f: impl FnOnce(&Bound<'py, PyAny>) -> PyResult<T>,
) -> PyResult<T> {
    match obj {
        Some(o) if !o.is_none() => f(o),
        _ => Ok(default),
    }
}

fn u8_in(obj: &Bound<'_, PyAny>, name: &str, lo: u8, hi: u8) -> PyResult<u8> {
    int_in(obj, name, lo.into(), hi.into()).map(|v| v as u8)
}

fn u16_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<u16> {
    int_in(obj, name, 0, 0xFFFF).map(|v| v as u16)
}

/// ValueError if `count` registers from `address` run past address 0xFFFF.
fn within_map(address: u16, count: usize) -> PyResult<()> {
    if usize::from(address) + count > 0x1_0000 {
        return Err(PyValueError::new_err(format!(
            "registers {address:#06x}+{count} run past address 0xFFFF"
        )));
    }
    Ok(())
}

/// A unit address a request may go to: 1..=255.
fn unit_arg(obj: &Bound<'_, PyAny>) -> PyResult<u8> {
    u8_in(obj, "unit", *UNITS.start(), *UNITS.end())
}

/// A unit address a device of the standard range (1..=247) may have.
fn standard_unit_arg(obj: &Bound<'_, PyAny>) -> PyResult<u8> {
    u8_in(obj, "unit", *STANDARD_UNITS.start(), *STANDARD_UNITS.end())
}

/// A number of seconds (int or float, not bool) as given: TypeError for anything else. An
/// int too big for a float is infinite, so out of any range.
fn seconds_value(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if obj.is_instance_of::<PyBool>()
        || !(obj.is_instance_of::<PyInt>() || obj.is_instance_of::<PyFloat>())
    {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a number of seconds, got {}",
            obj.get_type().name()?
        )));
    }
    Ok(obj.extract().unwrap_or(f64::INFINITY))
}

fn seconds(obj: &Bound<'_, PyAny>, name: &str, allow_zero: bool) -> PyResult<Duration> {
    let value = seconds_value(obj, name)?;
    let ok = value.is_finite() && (value > 0.0 || (allow_zero && value == 0.0)) && value <= 3600.0;
    if !ok || obj.is_instance_of::<PyString>() {
        let range = if allow_zero {
            "from 0 to 3600"
        } else {
            "more than 0 and at most 3600"
        };
        return Err(PyValueError::new_err(format!(
            "{name} must be {range} seconds, got {value}"
        )));
    }
    Ok(Duration::from_secs_f64(value))
}

/// A device's own `timeout` and `retries` (None: the Bus's).
fn own_timing(
    timeout: Option<&Bound<'_, PyAny>>,
    retries: Option<&Bound<'_, PyAny>>,
) -> PyResult<(Option<Duration>, Option<u32>)> {
    let timeout = opt(timeout, None, |t| seconds(t, "timeout", false).map(Some))?;
    let retries = opt(retries, None, |r| {
        int_in(r, "retries", 0, bus::MAX_RETRIES.into()).map(|n| Some(n as u32))
    })?;
    Ok((timeout, retries))
}

fn register_values(obj: &Bound<'_, PyAny>) -> PyResult<Vec<u16>> {
    register_list(obj, usize::from(MAX_WRITE_COUNT))
}

/// The `address` and `values` of a 0x10 write, checked: a start address, 1..=123 register
/// values, and a block that stays within the register map.
fn register_block(
    address: &Bound<'_, PyAny>,
    values: &Bound<'_, PyAny>,
) -> PyResult<(u16, Vec<u16>)> {
    let address = u16_arg(address, "address")?;
    let values = register_values(values)?;
    within_map(address, values.len())?;
    Ok((address, values))
}

/// A sequence of 1..=`max` register values (ints 0..=0xFFFF).
fn register_list(obj: &Bound<'_, PyAny>, max: usize) -> PyResult<Vec<u16>> {
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
        return Err(PyTypeError::new_err(
            "values must be a sequence of ints, not str or bytes",
        ));
    }
    let values = obj
        .try_iter()
        .map_err(|_| PyTypeError::new_err("values must be a sequence of ints"))?
        .map(|item| u16_arg(&item?, "each value"))
        .collect::<PyResult<Vec<u16>>>()?;
    if values.is_empty() || values.len() > max {
        return Err(PyValueError::new_err(format!(
            "values must hold 1 to {max} registers, got {}",
            values.len()
        )));
    }
    Ok(values)
}

/// The items of a `groups` argument (file record groups), each a sequence of three:
/// refused as a TypeError if `groups` is text, bytes or not iterable, or an item is not a
/// sequence of three.
fn group_items<'py>(obj: &Bound<'py, PyAny>, third: &str) -> PyResult<Vec<[Bound<'py, PyAny>; 3]>> {
    let shape = || {
        PyTypeError::new_err(format!(
            "groups must be a sequence of (file, record, {third}) tuples"
        ))
    };
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
        return Err(shape());
    }
    obj.try_iter()
        .map_err(|_| shape())?
        .map(|item| {
            let item = item?;
            if item.is_instance_of::<PyString>() || item.is_instance_of::<PyBytes>() {
                return Err(shape());
            }
            let fields = item
                .try_iter()
                .map_err(|_| shape())?
                .collect::<PyResult<Vec<_>>>()?;
            <[Bound<'py, PyAny>; 3]>::try_from(fields).map_err(|_| shape())
        })
        .collect()
}

/// A group's file (1..=0xFFFF) and record (0..=0x270F).
fn file_and_record(file: &Bound<'_, PyAny>, record: &Bound<'_, PyAny>) -> PyResult<(u16, u16)> {
    let file = int_in(file, "file", 1, 0xFFFF)? as u16;
    let record = int_in(record, "record", 0, i64::from(MAX_FILE_RECORD))? as u16;
    Ok((file, record))
}

/// The request's own limits (a request and reply within a PDU, no record past 0x270F),
/// as a ValueError before anything is sent.
fn valid(request: Request) -> PyResult<Request> {
    request
        .validate()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(request)
}

/// The `groups` of a Read File Record (0x14): `(file, record, length)` each, checked.
fn read_file_groups(obj: &Bound<'_, PyAny>) -> PyResult<Vec<(u16, u16, u16)>> {
    let groups = group_items(obj, "length")?
        .iter()
        .map(|[file, record, length]| {
            let (file, record) = file_and_record(file, record)?;
            let length = int_in(length, "length", 1, i64::from(MAX_FILE_RECORD) + 1)? as u16;
            Ok((file, record, length))
        })
        .collect::<PyResult<Vec<_>>>()?;
    match valid(Request::ReadFileRecord { groups })? {
        Request::ReadFileRecord { groups } => Ok(groups),
        _ => Err(PyRuntimeError::new_err(
            "unreachable: not a read file record",
        )),
    }
}

/// The `groups` of a Write File Record (0x15): `(file, record, values)` each, checked.
fn write_file_groups(obj: &Bound<'_, PyAny>) -> PyResult<Vec<(u16, u16, Vec<u16>)>> {
    let groups = group_items(obj, "values")?
        .iter()
        .map(|[file, record, values]| {
            let (file, record) = file_and_record(file, record)?;
            Ok((file, record, register_list(values, MAX_PDU_DATA / 2)?))
        })
        .collect::<PyResult<Vec<_>>>()?;
    match valid(Request::WriteFileRecord { groups })? {
        Request::WriteFileRecord { groups } => Ok(groups),
        _ => Err(PyRuntimeError::new_err(
            "unreachable: not a write file record",
        )),
    }
}

/// The `unit`, `address` and `count` (1..=`max`) of a read, checked: the block stays within
/// the address map.
fn read_args(
    unit: &Bound<'_, PyAny>,
    address: &Bound<'_, PyAny>,
    count: &Bound<'_, PyAny>,
    max: u16,
) -> PyResult<(u8, u16, u16)> {
    let unit = unit_arg(unit)?;
    let address = u16_arg(address, "address")?;
    let count = int_in(count, "count", 1, max.into())? as u16;
    within_map(address, count.into())?;
    Ok((unit, address, count))
}

/// `values` as a list of bools, each converted by `each`: TypeError ("values must be a
/// sequence of {what}") for a str, bytes or anything not iterable.
fn bool_sequence(
    values: &Bound<'_, PyAny>,
    what: &str,
    each: impl Fn(&Bound<'_, PyAny>) -> PyResult<bool>,
) -> PyResult<Vec<bool>> {
    if values.is_instance_of::<PyString>() || values.is_instance_of::<PyBytes>() {
        return Err(PyTypeError::new_err(format!(
            "values must be a sequence of {what}, not str or bytes"
        )));
    }
    values
        .try_iter()
        .map_err(|_| PyTypeError::new_err(format!("values must be a sequence of {what}")))?
        .map(|item| each(&item?))
        .collect()
}

/// The `address` and `values` of a 0x0F write, checked: a start address, 1..=1968 coil
/// values (each True or False) and a block that stays within the address map.
fn coil_block(address: &Bound<'_, PyAny>, values: &Bound<'_, PyAny>) -> PyResult<(u16, Vec<bool>)> {
    let address = u16_arg(address, "address")?;
    let values = bool_sequence(values, "bools", |item| bool_arg(item, "each value"))?;
    let max = usize::from(MAX_WRITE_BITS);
    if values.is_empty() || values.len() > max {
        return Err(PyValueError::new_err(format!(
            "values must hold 1 to {max} coils, got {}",
            values.len()
        )));
    }
    within_map(address, values.len())?;
    Ok((address, values))
}

/// `b"\0\0"`, the default data of `diagnostics` (a bytes argument when given, never None).
fn two_zero_bytes() -> Py<PyAny> {
    Python::attach(|py| PyBytes::new(py, &[0, 0]).into_any().unbind())
}

/// A bytes argument (bytes or bytearray) of at most `max` bytes.
fn bytes_arg(obj: &Bound<'_, PyAny>, name: &str, max: usize) -> PyResult<Vec<u8>> {
    let data = if let Ok(b) = obj.cast::<PyBytes>() {
        b.as_bytes().to_vec()
    } else if let Ok(b) = obj.cast::<PyByteArray>() {
        b.to_vec()
    } else {
        return Err(PyTypeError::new_err(format!(
            "{name} must be bytes, got {}",
            obj.get_type().name()?
        )));
    };
    if data.len() > max {
        return Err(PyValueError::new_err(format!(
            "{name} must be at most {max} bytes, got {}",
            data.len()
        )));
    }
    Ok(data)
}

/// Counters of what happened on a Bus since it was opened.
#[pyclass(frozen, get_all, module = "benchbus._core", name = "Stats")]
#[derive(Clone)]
struct PyStats {
    transactions: u64,
    retries: u64,
    timeouts: u64,
    crc_errors: u64,
    frame_errors: u64,
    exceptions: u64,
    stale_bytes: u64,
    broadcasts: u64,
    reopens: u64,
    resyncs: u64,
}

impl From<bus::Stats> for PyStats {
    fn from(s: bus::Stats) -> Self {
        PyStats {
            transactions: s.transactions,
            retries: s.retries,
            timeouts: s.timeouts,
            crc_errors: s.crc_errors,
            frame_errors: s.frame_errors,
            exceptions: s.exceptions,
            stale_bytes: s.stale_bytes,
            broadcasts: s.broadcasts,
            reopens: s.reopens,
            resyncs: s.resyncs,
        }
    }
}

#[pymethods]
impl PyStats {
    /// The counters as a dict.
    fn as_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in self.fields() {
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let parts: Vec<String> = self
            .fields()
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        format!("Stats({})", parts.join(", "))
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<PyStats>()
            .map(|o| o.get().fields() == self.fields())
            .unwrap_or(false)
    }
}

impl PyStats {
    fn fields(&self) -> [(&'static str, u64); 10] {
        [
            ("transactions", self.transactions),
            ("retries", self.retries),
            ("timeouts", self.timeouts),
            ("crc_errors", self.crc_errors),
            ("frame_errors", self.frame_errors),
            ("exceptions", self.exceptions),
            ("stale_bytes", self.stale_bytes),
            ("broadcasts", self.broadcasts),
            ("reopens", self.reopens),
            ("resyncs", self.resyncs),
        ]
    }
}

/// A Modbus RTU master on one serial line.
#[pyclass(frozen, module = "benchbus._core", name = "Bus")]
struct PyBus {
    bus: Arc<bus::Bus>,
}

impl PyBus {
    /// Runs `f` on the bus with the GIL released and maps its error.
    fn wire<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&bus::Bus) -> crate::Result<T> + Send,
    ) -> PyResult<T> {
        on_wire(py, &self.bus, f)
    }

    /// Sends the write `function` (0x05, 0x06, 0x0F or 0x10) from `address` to every unit
    /// (unit 0) and waits no reply: `value` is one value, or a sequence for 0x0F and 0x10,
    /// converted and checked as the write to one unit checks it. The `broadcast_write_*`
    /// methods are this.
    fn broadcast_write(
        &self,
        py: Python<'_>,
        function: u8,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let request = match function {
            WRITE_SINGLE_REGISTER => Request::WriteSingleRegister {
                address: u16_arg(address, "address")?,
                value: u16_arg(value, "value")?,
            },
            WRITE_MULTIPLE_REGISTERS => {
                let (address, values) = register_block(address, value)?;
                Request::WriteMultipleRegisters { address, values }
            }
            WRITE_SINGLE_COIL => Request::WriteSingleCoil {
                address: u16_arg(address, "address")?,
                value: bool_arg(value, "value")?,
            },
            WRITE_MULTIPLE_COILS => {
                let (address, values) = coil_block(address, value)?;
                Request::WriteMultipleCoils { address, values }
            }
            _ => {
                return Err(PyRuntimeError::new_err(format!(
                    "unreachable: no broadcast write of function {function:#04x}"
                )))
            }
        };
        self.wire(py, |b| b.broadcast(&request))
    }
}

#[pymethods]
impl PyBus {
    #[new]
    #[pyo3(
        signature = (port, baudrate=None, parity=None, stopbits=None, timeout=None, retries=None, *, turnaround=None, reconnect=None, echo=None, rs485=None, rts_delay=None, silence=None, framing=None, bytesize=None),
        text_signature = "(port, baudrate=19200, parity='N', stopbits=1, timeout=0.1, retries=2, *, turnaround=0.1, reconnect=False, echo=False, rs485=False, rts_delay=None, silence=0.0, framing='rtu', bytesize=None)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        port: &Bound<'_, PyAny>,
        baudrate: Option<&Bound<'_, PyAny>>,
        parity: Option<&Bound<'_, PyAny>>,
        stopbits: Option<&Bound<'_, PyAny>>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
        turnaround: Option<&Bound<'_, PyAny>>,
        reconnect: Option<&Bound<'_, PyAny>>,
        echo: Option<&Bound<'_, PyAny>>,
        rs485: Option<&Bound<'_, PyAny>>,
        rts_delay: Option<&Bound<'_, PyAny>>,
        silence: Option<&Bound<'_, PyAny>>,
        framing: Option<&Bound<'_, PyAny>>,
        bytesize: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let port: std::path::PathBuf = port
            .extract()
            .map_err(|_| PyTypeError::new_err("port must be a str or os.PathLike"))?;
        let port = port.to_string_lossy().into_owned();
        if port.is_empty() {
            return Err(PyValueError::new_err("port must not be empty"));
        }
        let line = line_arg(baudrate, parity, stopbits)?;
        let (ascii, line) = framing_arg(framing, bytesize, parity, stopbits, line)?;
        // "scheme://..." names a network transport: a malformed one is refused here, before
        // anything is opened (the message gives the forms expected).
        let mut config = BusConfig::new(&port, line).map_err(|e| to_pyerr(py, e))?;
        config.ascii = ascii;
        config.timeout = opt(timeout, config.timeout, |t| seconds(t, "timeout", false))?;
        config.retries = opt(retries, 2, |r| {
            int_in(r, "retries", 0, bus::MAX_RETRIES.into())
        })? as u32;
        config.turnaround = opt(turnaround, config.turnaround, |t| {
            seconds(t, "turnaround", true)
        })?;
        config.reconnect = opt(reconnect, false, |r| bool_arg(r, "reconnect"))?;
        config.echo = opt(echo, false, |e| bool_arg(e, "echo"))?;
        config.rs485 = rs485_arg(rs485, rts_delay)?;
        config.silence = opt(silence, Duration::ZERO, |t| seconds(t, "silence", true))?;
        config.interrupted = Some(signal_raised);
        // Logging levels are read when a bus opens (pyo3-log caches them).
        if let Some(handle) = LOG_RESET.get() {
            handle.reset();
        }
        let bus = py
            .detach(move || crate::error::guarded(|| bus::Bus::open(config)))
            .map_err(|e| to_pyerr(py, e))?;
        Ok(PyBus { bus: Arc::new(bus) })
    }

    /// Reads `count` (1..=125) holding registers from `address` (function 0x03).
    fn read_holding_registers(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let (unit, address, count) = read_args(unit, address, count, MAX_READ_COUNT)?;
        self.wire(py, |b| {
            b.read_holding_registers(unit, address, count, &TxOptions::default())
        })
    }

    /// Reads `count` (1..=2000) coils from `address` (function 0x01).
    fn read_coils(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<bool>> {
        let (unit, address, count) = read_args(unit, address, count, MAX_READ_BITS)?;
        self.wire(py, |b| {
            b.read_coils(unit, address, count, &TxOptions::default())
        })
    }

    /// Reads `count` (1..=2000) discrete inputs from `address` (function 0x02).
    fn read_discrete_inputs(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<bool>> {
        let (unit, address, count) = read_args(unit, address, count, MAX_READ_BITS)?;
        self.wire(py, |b| {
            b.read_discrete_inputs(unit, address, count, &TxOptions::default())
        })
    }

    /// Reads `count` (1..=125) input registers from `address` (function 0x04).
    fn read_input_registers(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let (unit, address, count) = read_args(unit, address, count, MAX_READ_COUNT)?;
        self.wire(py, |b| {
            b.read_input_registers(unit, address, count, &TxOptions::default())
        })
    }

    /// Sets one coil on (True) or off (False) (function 0x05); the reply must echo it.
    fn write_coil(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let address = u16_arg(address, "address")?;
        let value = bool_arg(value, "value")?;
        self.wire(py, |b| {
            b.write_coil(unit, address, value, &TxOptions::default())
        })
    }

    /// Sets 1..=1968 consecutive coils from `address` (function 0x0F).
    fn write_coils(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let (address, values) = coil_block(address, values)?;
        self.wire(py, |b| {
            b.write_coils(unit, address, &values, &TxOptions::default())
        })
    }

    /// Changes bits of one register (function 0x16): it becomes (value AND `and_mask`) OR
    /// (`or_mask` AND NOT `and_mask`); the reply must echo the request.
    fn mask_write_register(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        and_mask: &Bound<'_, PyAny>,
        or_mask: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let address = u16_arg(address, "address")?;
        let and_mask = u16_arg(and_mask, "and_mask")?;
        let or_mask = u16_arg(or_mask, "or_mask")?;
        self.wire(py, |b| {
            b.mask_write_register(unit, address, and_mask, or_mask, &TxOptions::default())
        })
    }

    /// Writes `values` (1..=121) from `write_address`, then reads `read_count` (1..=125)
    /// registers from `read_address`, in one transaction (function 0x17).
    fn read_write_registers(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        read_address: &Bound<'_, PyAny>,
        read_count: &Bound<'_, PyAny>,
        write_address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let unit = unit_arg(unit)?;
        let read_address = u16_arg(read_address, "read_address")?;
        let read_count = int_in(read_count, "read_count", 1, MAX_READ_COUNT.into())? as u16;
        within_map(read_address, read_count.into())?;
        let write_address = u16_arg(write_address, "write_address")?;
        let values = register_list(values, usize::from(MAX_READ_WRITE_COUNT))?;
        within_map(write_address, values.len())?;
        self.wire(py, |b| {
            b.read_write_registers(
                unit,
                read_address,
                read_count,
                write_address,
                &values,
                &TxOptions::default(),
            )
        })
    }

    /// Reads the eight exception status outputs (function 0x07) as an int.
    fn read_exception_status(&self, py: Python<'_>, unit: &Bound<'_, PyAny>) -> PyResult<u8> {
        let unit = unit_arg(unit)?;
        self.wire(py, |b| b.read_exception_status(unit, &TxOptions::default()))
    }

    /// Runs diagnostics sub-function `sub_function` with `data` (function 0x08): the
    /// reply's data after its sub-function, as bytes.
    #[pyo3(
        signature = (unit, sub_function, data=two_zero_bytes()),
        text_signature = "($self, unit, sub_function, data=b'\\x00\\x00')"
    )]
    fn diagnostics<'py>(
        &self,
        py: Python<'py>,
        unit: &Bound<'py, PyAny>,
        sub_function: &Bound<'py, PyAny>,
        data: Py<PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let unit = unit_arg(unit)?;
        let sub_function = u16_arg(sub_function, "sub_function")?;
        let data = bytes_arg(data.bind(py), "data", MAX_PDU_DATA - 2)?;
        let reply = self.wire(py, |b| {
            b.diagnostics(unit, sub_function, &data, &TxOptions::default())
        })?;
        Ok(PyBytes::new(py, &reply))
    }

    /// The data field of the unit's Report Server ID reply (function 0x11), after its byte
    /// count, as the device sent it.
    fn report_server_id<'py>(
        &self,
        py: Python<'py>,
        unit: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let unit = unit_arg(unit)?;
        let reply = self.wire(py, |b| b.report_server_id(unit, &TxOptions::default()))?;
        Ok(PyBytes::new(py, &reply))
    }

    /// The unit's status word and event counter (function 0x0B), as a
    /// ``CommEventCounter(status, event_count)``.
    fn get_comm_event_counter<'py>(
        &self,
        py: Python<'py>,
        unit: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let unit = unit_arg(unit)?;
        let (status, count) = self.wire(py, |b| {
            b.get_comm_event_counter(unit, &TxOptions::default())
        })?;
        public(py, RESULTS, "CommEventCounter", (status, count), None)
    }

    /// The unit's status word, event and message counters and events (function 0x0C), as
    /// a ``CommEventLog(status, event_count, message_count, events)``.
    fn get_comm_event_log<'py>(
        &self,
        py: Python<'py>,
        unit: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let unit = unit_arg(unit)?;
        let log = self.wire(py, |b| b.get_comm_event_log(unit, &TxOptions::default()))?;
        comm_event_log(py, log)
    }

    /// Reads file records (function 0x14): for each group ``(file, record, length)``,
    /// ``length`` registers from record ``record`` of file ``file``; one list per group.
    fn read_file_record(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        groups: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<Vec<u16>>> {
        let unit = unit_arg(unit)?;
        let groups = read_file_groups(groups)?;
        self.wire(py, |b| {
            b.read_file_record(unit, &groups, &TxOptions::default())
        })
    }

    /// Writes file records (function 0x15): for each group ``(file, record, values)``,
    /// ``values`` from record ``record`` of file ``file``; the reply must echo the request.
    fn write_file_record(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        groups: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let groups = write_file_groups(groups)?;
        self.wire(py, |b| {
            b.write_file_record(unit, &groups, &TxOptions::default())
        })
    }

    /// The values queued in the FIFO whose count register is at ``address`` (function
    /// 0x18), oldest first: at most 31.
    fn read_fifo_queue(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<u16>> {
        let unit = unit_arg(unit)?;
        let address = u16_arg(address, "address")?;
        self.wire(py, |b| {
            b.read_fifo_queue(unit, address, &TxOptions::default())
        })
    }

    /// Sends function `function` (1..=127) with `data`, the PDU after the function code,
    /// and returns the reply's bytes after its function code: read by `reply_length`, or
    /// without it until the line is quiet (the Bus's `silence`, at least t3.5). It is paced
    /// as a write by `write_interval`. `timeout` and `retries`, if given, replace the Bus's
    /// for this call.
    #[pyo3(
        signature = (unit, function, data, *, reply_length=None, write_interval=None, timeout=None, retries=None),
        text_signature = "($self, unit, function, data, *, reply_length=None, write_interval=0.0, timeout=None, retries=None)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn request<'py>(
        &self,
        py: Python<'py>,
        unit: &Bound<'py, PyAny>,
        function: &Bound<'py, PyAny>,
        data: &Bound<'py, PyAny>,
        reply_length: Option<&Bound<'py, PyAny>>,
        write_interval: Option<&Bound<'py, PyAny>>,
        timeout: Option<&Bound<'py, PyAny>>,
        retries: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let unit = unit_arg(unit)?;
        // 0 is no function, and 0x80 | f is f's exception reply.
        let function = int_in(function, "function", 1, 0x7F).map_err(|e| {
            if e.is_instance_of::<PyValueError>(py) {
                PyValueError::new_err(format!(
                    "{} (0x80 and up are exception replies)",
                    e.value(py)
                ))
            } else {
                e
            }
        })? as u8;
        let data = bytes_arg(data, "data", MAX_PDU_DATA)?;
        let reply_length = opt(reply_length, None, |r| {
            int_in(r, "reply_length", 0, MAX_PDU_DATA as i64).map(|n| Some(n as usize))
        })?;
        let (timeout, retries) = own_timing(timeout, retries)?;
        let opts = TxOptions {
            timeout,
            retries,
            write_interval: write_interval_arg(write_interval)?,
            ..TxOptions::default()
        };
        let reply = self.wire(py, |b| {
            b.request(unit, function, &data, reply_length, &opts)
        })?;
        Ok(PyBytes::new(py, &reply))
    }

    /// Writes one register (function 0x06). `timeout` and `retries`, if given, replace
    /// the Bus's for this call only.
    #[pyo3(
        signature = (unit, address, value, *, accept_count_echo=false, write_interval=None, timeout=None, retries=None),
        text_signature = "($self, unit, address, value, *, accept_count_echo=False, write_interval=0.0, timeout=None, retries=None)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn write_register(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
        accept_count_echo: bool,
        write_interval: Option<&Bound<'_, PyAny>>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let address = u16_arg(address, "address")?;
        let value = u16_arg(value, "value")?;
        let (timeout, retries) = own_timing(timeout, retries)?;
        let opts = TxOptions {
            timeout,
            retries,
            echo: if accept_count_echo {
                Echo::CountForSingleWrite
            } else {
                Echo::Strict
            },
            write_interval: write_interval_arg(write_interval)?,
            ..TxOptions::default()
        };
        self.wire(py, |b| b.write_register(unit, address, value, &opts))
    }

    /// Writes 1..=123 consecutive registers from `address` (function 0x10). `timeout` and
    /// `retries`, if given, replace the Bus's for this call only.
    #[pyo3(
        signature = (unit, address, values, *, write_interval=None, timeout=None, retries=None),
        text_signature = "($self, unit, address, values, *, write_interval=0.0, timeout=None, retries=None)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn write_registers(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
        write_interval: Option<&Bound<'_, PyAny>>,
        timeout: Option<&Bound<'_, PyAny>>,
        retries: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let unit = unit_arg(unit)?;
        let (address, values) = register_block(address, values)?;
        let (timeout, retries) = own_timing(timeout, retries)?;
        let opts = TxOptions {
            timeout,
            retries,
            write_interval: write_interval_arg(write_interval)?,
            ..TxOptions::default()
        };
        self.wire(py, |b| b.write_registers(unit, address, &values, &opts))
    }

    /// Reads the device identification objects (function 0x2B, MEI 0x0E) as
    /// `{object_id: text}` (one character per byte, Latin-1), following "more follows".
    #[pyo3(
        signature = (unit, read_code=None, object_id=None),
        text_signature = "($self, unit, read_code=1, object_id=0)"
    )]
    fn read_device_identification(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        read_code: Option<&Bound<'_, PyAny>>,
        object_id: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<std::collections::BTreeMap<u8, String>> {
        let unit = unit_arg(unit)?;
        let read_code = opt(read_code, 1, |r| u8_in(r, "read_code", 1, 4))?;
        let object_id = opt(object_id, 0, |o| u8_in(o, "object_id", 0, 255))?;
        let id = self.wire(py, |b| {
            b.read_device_identification(unit, read_code, object_id, &TxOptions::default())
        })?;
        Ok(id.texts())
    }

    /// The unit's identification as the gateway forwards it: `(conformity, {object_id:
    /// raw bytes})`, the conformity level the device sent and its objects undecoded
    /// (internal: `read_device_identification` is the public form).
    #[pyo3(signature = (unit, read_code, object_id))]
    fn _device_identification(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        read_code: &Bound<'_, PyAny>,
        object_id: &Bound<'_, PyAny>,
    ) -> PyResult<(u8, std::collections::BTreeMap<u8, Vec<u8>>)> {
        let unit = unit_arg(unit)?;
        let read_code = u8_in(read_code, "read_code", 1, 4)?;
        let object_id = u8_in(object_id, "object_id", 0, 255)?;
        let id = self.wire(py, |b| {
            b.read_device_identification(unit, read_code, object_id, &TxOptions::default())
        })?;
        // PyO3 gives each Vec<u8> to Python as bytes.
        Ok((id.conformity, id.objects))
    }

    /// Writes one register on every unit (unit 0); waits no reply.
    fn broadcast_write_register(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.broadcast_write(py, WRITE_SINGLE_REGISTER, address, value)
    }

    /// Writes 1..=123 consecutive registers from `address` on every unit (unit 0, function
    /// 0x10); waits no reply.
    fn broadcast_write_registers(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.broadcast_write(py, WRITE_MULTIPLE_REGISTERS, address, values)
    }

    /// Sends the request PDU `function` / `data` to every unit (unit 0), if it is a write
    /// that can be broadcast (internal: the gateway's), as a write to units that want
    /// `write_interval` between writes; waits no reply.
    #[pyo3(
        signature = (function, data, *, write_interval=None),
        text_signature = "($self, function, data, *, write_interval=0.0)"
    )]
    fn _broadcast(
        &self,
        py: Python<'_>,
        function: &Bound<'_, PyAny>,
        data: &Bound<'_, PyAny>,
        write_interval: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let function = u8_in(function, "function", 0, 255)?;
        let data = bytes_arg(data, "data", MAX_PDU_DATA)?;
        let request =
            decode::decode(function, &data).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let interval = write_interval_arg(write_interval)?;
        self.wire(py, |b| b.broadcast_paced(&request, interval))
    }

    /// Sets one coil on every unit (unit 0, function 0x05); waits no reply.
    fn broadcast_write_coil(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.broadcast_write(py, WRITE_SINGLE_COIL, address, value)
    }

    /// Sets 1..=1968 consecutive coils from `address` on every unit (unit 0, function
    /// 0x0F); waits no reply.
    fn broadcast_write_coils(
        &self,
        py: Python<'_>,
        address: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.broadcast_write(py, WRITE_MULTIPLE_COILS, address, values)
    }

    /// The units among `units` that answer a read of register `address` within `timeout`
    /// seconds (an exception reply counts as an answer), each unit's window counted from the
    /// start of its request. Ctrl-C stops the scan.
    #[pyo3(
        signature = (units=None, timeout=None, address=None),
        text_signature = "($self, units=None, timeout=0.05, address=0)"
    )]
    fn scan(
        &self,
        py: Python<'_>,
        units: Option<&Bound<'_, PyAny>>,
        timeout: Option<&Bound<'_, PyAny>>,
        address: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<u16>> {
        let units: Vec<u8> = match units {
            None => STANDARD_UNITS.collect(),
            Some(obj) => obj
                .try_iter()
                .map_err(|_| PyTypeError::new_err("units must be an iterable of ints"))?
                .map(|u| unit_arg(&u?))
                .collect::<PyResult<_>>()?,
        };
        let timeout = opt(timeout, Duration::from_millis(50), |t| {
            seconds(t, "timeout", false)
        })?;
        let address = opt(address, 0, |a| u16_arg(a, "address"))?;
        // u16, not u8: PyO3 turns a Vec<u8> into bytes, and scan promises a list of ints.
        let mut found: Vec<u16> = Vec::new();
        for unit in units {
            if self.wire(py, |b| b.probe(unit, address, timeout))? {
                found.push(u16::from(unit));
            }
            py.check_signals()?;
        }
        Ok(found)
    }

    /// Reads `count` holding registers every `interval` seconds on absolute deadlines,
    /// for `duration` seconds or (None) for ever: an iterator of `(t, values)`.
    #[pyo3(
        signature = (unit, address, count=None, *, interval, duration=None),
        text_signature = "($self, unit, address, count=1, *, interval, duration=None)"
    )]
    fn poll(
        &self,
        py: Python<'_>,
        unit: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        count: Option<&Bound<'_, PyAny>>,
        interval: &Bound<'_, PyAny>,
        duration: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<poll::PyPoll> {
        poll::PyPoll::new(py, &self.bus, unit, address, count, interval, duration)
    }

    /// Counters of what happened on this bus.
    #[getter]
    fn stats(&self, py: Python<'_>) -> PyResult<PyStats> {
        self._owned(py)?;
        // Without the GIL: a call on the line holds the state and may log into Python.
        let bus = Arc::clone(&self.bus);
        Ok(py.detach(move || bus.stats()).into())
    }

    /// PortError in a process other than the one that opened the bus (a child made by
    /// fork), saying what to do; None in that one.
    fn _owned(&self, py: Python<'_>) -> PyResult<()> {
        self.bus.owned().map_err(|e| to_pyerr(py, e))
    }

    /// Closes the port. Further calls raise PortError; closing twice is harmless. In a
    /// process other than the one that opened the bus (a child made by fork) it sends
    /// nothing and leaves the port to that process.
    fn close(&self, py: Python<'_>) {
        let bus = Arc::clone(&self.bus);
        py.detach(move || bus.close());
    }

    /// True once the bus is closed (and not reopened since), and in a process other than
    /// the one that opened it (a child made by fork), which cannot use it.
    #[getter]
    fn closed(&self, py: Python<'_>) -> bool {
        let bus = Arc::clone(&self.bus);
        py.detach(move || bus.is_closed())
    }

    /// Closes the port and opens the same path again with the same settings (also after
    /// close()); the stats and device objects on this bus carry on. PortError if the path
    /// cannot be opened (the bus is then left without a port until a reopen succeeds).
    fn reopen(&self, py: Python<'_>) -> PyResult<()> {
        self.wire(py, |b| b.reopen())
    }

    /// Whether a call that finds the port lost reopens it first (once per call).
    #[getter]
    fn reconnect(&self) -> bool {
        self.bus.config().reconnect
    }

    /// Whether the adapter's local echo of each request is read back and checked.
    #[getter]
    fn echo(&self) -> bool {
        self.bus.config().echo
    }

    /// Whether the port was opened in the kernel's RS485 mode (``rs485=True``).
    #[getter]
    fn rs485(&self) -> bool {
        self.bus.config().rs485.is_some()
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close(py);
        false
    }

    /// The port path.
    #[getter]
    fn port(&self) -> String {
        self.bus.config().port().to_string()
    }

    /// Bits per second.
    #[getter]
    fn baudrate(&self) -> u32 {
        self.bus.config().line.baudrate
    }

    /// Parity letter: "N", "E" or "O".
    #[getter]
    fn parity(&self) -> String {
        self.bus.config().line.parity.letter().to_string()
    }

    /// Stop bits: 1 or 2.
    #[getter]
    fn stopbits(&self) -> u8 {
        self.bus.config().line.stop_bits
    }

    /// Data bits: 8, or 7 (Modbus ASCII's usual line format).
    #[getter]
    fn bytesize(&self) -> u8 {
        self.bus.config().line.data_bits
    }

    /// The framing on the line: "rtu", or "ascii" (Modbus ASCII).
    #[getter]
    fn framing(&self) -> &'static str {
        if self.bus.config().ascii {
            "ascii"
        } else {
            "rtu"
        }
    }

    /// Reply timeout per attempt, in seconds. Settable (``bus.timeout = 5`` for a slow
    /// command): the calls that start from then on use it, a call in flight keeps its own; a
    /// bad value raises TypeError or ValueError, as in the constructor, and changes nothing.
    #[getter]
    fn timeout(&self) -> f64 {
        self.bus.timeout().as_secs_f64()
    }

    #[setter]
    fn set_timeout(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let timeout = seconds(value, "timeout", false)?;
        self.bus.set_timeout(timeout).map_err(|e| to_pyerr(py, e))
    }

    /// Further attempts after a timeout or a corrupt frame. Settable, like :attr:`timeout`.
    #[getter]
    fn retries(&self) -> u32 {
        self.bus.retries()
    }

    #[setter]
    fn set_retries(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let retries = int_in(value, "retries", 0, bus::MAX_RETRIES.into())? as u32;
        self.bus.set_retries(retries).map_err(|e| to_pyerr(py, e))
    }

    /// The quiet gap, in seconds, that ends a raw request's reply read without a
    /// `reply_length` (t3.5 when longer; 0.0: t3.5).
    #[getter]
    fn silence(&self) -> f64 {
        self.bus.config().silence.as_secs_f64()
    }

    /// Quiet time after a broadcast, in seconds.
    #[getter]
    fn turnaround(&self) -> f64 {
        self.bus.config().turnaround.as_secs_f64()
    }

    /// Time one character takes on the wire, in seconds.
    #[getter]
    fn char_time(&self) -> f64 {
        self.bus.config().line.char_time().as_secs_f64()
    }

    /// The silence between frames (t3.5), in seconds.
    #[getter]
    fn t3_5(&self) -> f64 {
        self.bus.config().line.t3_5().as_secs_f64()
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let bus = Arc::clone(&self.bus);
        let (closed, lost) = py.detach(move || (bus.is_closed(), bus.is_lost()));
        let state = match self.bus.owned() {
            Err(Error::Forked { owner, .. }) => format!(", of process {owner}"),
            _ if closed => ", closed".into(),
            _ if lost => ", lost".into(),
            _ => String::new(),
        };
        let c = self.bus.config();
        format!(
            "Bus('{}', baudrate={}, parity='{}', stopbits={}, timeout={}, retries={}{}{}{}{}{}{})",
            c.port().replace('\\', "\\\\").replace('\'', "\\'"),
            c.line.baudrate,
            c.line.parity.letter(),
            c.line.stop_bits,
            self.bus.timeout().as_secs_f64(),
            self.bus.retries(),
            if c.ascii {
                format!(", framing='ascii', bytesize={}", c.line.data_bits)
            } else {
                String::new()
            },
            if c.reconnect { ", reconnect=True" } else { "" },
            if c.echo { ", echo=True" } else { "" },
            if c.rs485.is_some() {
                ", rs485=True"
            } else {
                ""
            },
            if c.silence.is_zero() {
                String::new()
            } else {
                format!(", silence={}", c.silence.as_secs_f64())
            },
            state
        )
    }
}

/// CRC-16/MODBUS of `data` (as sent: low byte first on the wire).
#[pyfunction]
fn crc16(data: &[u8]) -> u16 {
    crate::codec::crc16(data)
}

/// Re-reads the Python logging levels (they are cached for speed; a Bus reads them when it
/// opens). Call after changing the level of `benchbus.wire` while a Bus is open.
#[pyfunction]
fn refresh_logging() {
    if let Some(handle) = LOG_RESET.get() {
        handle.reset();
    }
}

/// What a server needs to forward the request PDU `function` / `data`, by the core's rules
/// (for the gateway): `(refusal, reply_length, write)`. `refusal` is None for a well-formed
/// request, else `(exception code, why)`: 0x01 for a function code no request has, 0x03 for
/// a malformed request; `reply_length` the reply's bytes after its function code where the
/// request tells them, else None; `write` whether it is paced as a write.
#[pyfunction]
fn _request_rules(function: u8, data: &[u8]) -> (Option<(u8, String)>, Option<usize>, bool) {
    match decode::decode(function, data) {
        Ok(request) => (None, reply::data_len(&request), !request.is_read()),
        Err(e) => (Some((decode::refusal(&e), e.to_string())), None, false),
    }
}

/// `; did you mean 'a' or 'b'?` naming the closest of `known` to `name`, or `""`: the one
/// rule of the core's hints, for `benchbus._device.did_you_mean`.
#[pyfunction]
fn _did_you_mean(name: &str, known: Vec<String>) -> String {
    crate::device::suggest::did_you_mean(name, known.iter().map(String::as_str))
}

/// What `port` reaches, read as a Bus reads it: "serial", "tcp" (Modbus TCP) or "rtu+tcp";
/// ValueError for a port string a Bus refuses. For the command line, which decides before
/// it opens a Bus.
#[pyfunction]
fn _endpoint_kind(port: &str) -> PyResult<&'static str> {
    use crate::transport::Endpoint;
    match crate::transport::parse_endpoint(port).map_err(PyValueError::new_err)? {
        Endpoint::Serial(_) => Ok("serial"),
        Endpoint::ModbusTcp { .. } => Ok("tcp"),
        Endpoint::RtuOverTcp { .. } => Ok("rtu+tcp"),
    }
}

/// Panics on the path every wire call takes, to show that the panic comes out as a
/// BenchbusError (for the test suite; not part of the API).
#[pyfunction]
fn _panic_on_wire(py: Python<'_>) -> PyResult<()> {
    on_wire(py, &Arc::new(()), |_: &()| -> crate::Result<()> {
        panic!("a deliberate panic on the wire path")
    })
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    if LOG_RESET.get().is_none() {
        let logger = pyo3_log::Logger::new(py, pyo3_log::Caching::LoggersAndLevels)?;
        if let Ok(handle) = logger.install() {
            let _ = LOG_RESET.set(handle);
        }
    }
    m.add_class::<PyBus>()?;
    m.add_class::<cancel::PyCancelToken>()?;
    m.add_class::<PyStats>()?;
    m.add_class::<PyStation>()?;
    m.add_class::<drive::PyDriveCore>()?;
    m.add_class::<instrument::PyInstrumentCore>()?;
    m.add_class::<j2::PyJ2Core>()?;
    m.add_class::<pbl::PyPblCore>()?;
    m.add_class::<poll::PyPoll>()?;
    m.add_class::<ticks::PyTicks>()?;
    m.add_function(wrap_pyfunction!(crc16, m)?)?;
    m.add_function(wrap_pyfunction!(values::from_registers, m)?)?;
    m.add_function(wrap_pyfunction!(values::to_registers, m)?)?;
    m.add_function(wrap_pyfunction!(ports::list_ports, m)?)?;
    m.add_class::<profile::PyProfile>()?;
    m.add_class::<profile::PyProfileCore>()?;
    m.add_function(wrap_pyfunction!(doctor::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(refresh_logging, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_on_wire, m)?)?;
    m.add_function(wrap_pyfunction!(_did_you_mean, m)?)?;
    m.add_function(wrap_pyfunction!(_endpoint_kind, m)?)?;
    m.add_function(wrap_pyfunction!(_request_rules, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
