//! A serial port's check-up, as data: what stands between a program and the devices on a
//! port, each finding with a verdict and the fix (`benchbus doctor`, `bb.doctor`).
//!
//! In order: the platform; on macOS a `/dev/tty.*` path (its `/dev/cu.*` twin is the one to
//! open); whether the port exists; who else holds it (Linux, from `/proc/<pid>/fd`); the
//! permission to open it; whether it opens (exclusively, at the line format given); the USB
//! chip behind it (from [`super::ports`]); an FTDI's latency timer (Linux); the driver's
//! low-latency mode and the kernel RS485 mode as the open found them ([`super::tuning`]; a
//! mode that is off is set again as it is, to see whether the driver could switch it on);
//! and whether a request comes back as a local echo (a read of one register, sent once).
//!
//! The system's trees are parameters ([`Checkup::sysfs`], [`Checkup::proc_root`]) so tests
//! can build their own.

use super::ports::{self, PortInfo};
use super::tuning::{LowLatency, Rs485State};
use super::{describe_open_error, parse_endpoint, Endpoint, SerialTransport, Transport};
use crate::codec::{encode_request, Request};
use crate::timing::LineFormat;
#[cfg(target_os = "linux")]
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How a finding stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// As it should be.
    Ok,
    /// Worth knowing; nothing to do.
    Info,
    /// Works, but slower or less sure than it could: see the fix.
    Warn,
    /// Stops benchbus from using the port: see the fix.
    Fail,
}

impl Verdict {
    /// `"ok"`, `"info"`, `"warn"` or `"fail"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Ok => "ok",
            Verdict::Info => "info",
            Verdict::Warn => "warn",
            Verdict::Fail => "fail",
        }
    }
}

/// One thing the check-up found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// What was checked: `platform`, `tty-vs-cu`, `port`, `holders`, `permissions`, `open`,
    /// `usb`, `latency-timer`, `low-latency`, `rs485`, `echo`.
    pub name: &'static str,
    /// How it stands.
    pub verdict: Verdict,
    /// What was found, in a sentence.
    pub message: String,
    /// What to do about it, if anything.
    pub fix: Option<String>,
}

fn finding(name: &'static str, verdict: Verdict, message: impl Into<String>) -> Finding {
    Finding {
        name,
        verdict,
        message: message.into(),
        fix: None,
    }
}

impl Finding {
    fn fix(mut self, fix: impl Into<String>) -> Finding {
        self.fix = Some(fix.into());
        self
    }
}

/// A process that holds a device open (Linux: from `/proc/<pid>/fd`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Holder {
    /// Its process id.
    pub pid: u32,
    /// Its command name (`/proc/<pid>/comm`), if readable.
    pub command: Option<String>,
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let who = if self.pid == std::process::id() {
            "this process"
        } else {
            self.command.as_deref().unwrap_or("?")
        };
        write!(f, "pid {} ({who})", self.pid)
    }
}

/// What the check-up uses: the line format and unit of its echo test, and the system's
/// trees.
#[derive(Debug, Clone)]
pub struct Checkup {
    /// The line format to open the port at.
    pub line: LineFormat,
    /// The unit the echo test's read goes to.
    pub unit: u8,
    /// How long the echo test waits for its request to come back.
    pub timeout: Duration,
    /// The sysfs root (`/sys`; Linux).
    pub sysfs: PathBuf,
    /// The procfs root (`/proc`; Linux).
    pub proc_root: PathBuf,
}

impl Checkup {
    /// A check-up at `line`, echo test to unit 1 within 100 ms, on the running system.
    pub fn new(line: LineFormat) -> Checkup {
        Checkup {
            line,
            unit: 1,
            timeout: Duration::from_millis(100),
            sysfs: PathBuf::from("/sys"),
            proc_root: PathBuf::from("/proc"),
        }
    }
}

/// The udev rule that sets every FTDI adapter's latency timer to 1 ms when it is plugged in.
pub const FTDI_UDEV_RULE: &str =
    r#"ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1""#;

/// The findings for the serial port `port`.
///
/// # Errors
/// A message if `port` names a network transport (`tcp://`, `rtu+tcp://`) or nothing.
pub fn diagnose(port: &str, checkup: &Checkup) -> Result<Vec<Finding>, String> {
    match parse_endpoint(port)? {
        Endpoint::Serial(p) if !p.is_empty() => {}
        Endpoint::Serial(_) => return Err("port must not be empty".into()),
        _ => {
            return Err(format!(
                "doctor checks a serial port, not {port:?}: over the network the gateway or \
                 device server holds the line"
            ))
        }
    }
    let mut out = vec![platform(checkup)];
    out.extend(cu_twin(port).map(|twin| {
        finding(
            "tty-vs-cu",
            Verdict::Warn,
            format!("{port} is a macOS dial-in port: opening it waits for a carrier signal"),
        )
        .fix(format!("open {twin} instead"))
    }));
    let names = tty_names(port);
    #[cfg(unix)]
    {
        match std::fs::metadata(port) {
            Err(e) => {
                out.push(finding("port", Verdict::Fail, format!("{port}: {e}")).fix(
                    "run 'benchbus ports' to list the serial ports (is the adapter plugged in?)",
                ));
                return Ok(out);
            }
            Ok(meta) => {
                let found = exists(port, &meta);
                let stop = found.verdict == Verdict::Fail;
                out.push(found);
                if stop {
                    return Ok(out);
                }
            }
        }
        out.push(permissions(port, may_read_and_write(port)));
    }
    #[cfg(target_os = "linux")]
    let holders = {
        let canonical = std::fs::canonicalize(port).unwrap_or_else(|_| PathBuf::from(port));
        super::linux::holders(&checkup.proc_root, &[Path::new(port), &canonical])
    };
    #[cfg(not(target_os = "linux"))]
    let holders: Vec<Holder> = Vec::new();
    let info = port_info(&names, checkup);
    #[cfg(target_os = "linux")]
    let timer_before = ftdi_name(info.as_ref(), &names)
        .and_then(|name| super::linux::latency_timer(&checkup.sysfs, name).map(|ms| (name, ms)));
    let opened = SerialTransport::open(port, &checkup.line);
    out.extend(open_findings(&opened, &holders, &checkup.line));
    out.push(usb(info.as_ref()));
    let transport = opened.ok();
    #[cfg(target_os = "linux")]
    if let Some((name, before)) = timer_before {
        let after = super::linux::latency_timer(&checkup.sysfs, name);
        out.push(latency_timer(name, before, after));
    }
    if let Some(transport) = transport {
        out.push(low_latency(&transport.tuned().low_latency));
        #[cfg(target_os = "linux")]
        let settable = || super::linux::rs485_settable(transport.as_raw_fd());
        #[cfg(not(target_os = "linux"))]
        let settable = || false;
        out.push(rs485(&transport.tuned().rs485, settable));
        out.push(echo(transport, checkup));
    }
    Ok(out)
}

fn platform(checkup: &Checkup) -> Finding {
    let _ = checkup;
    #[cfg(target_os = "linux")]
    let release = std::fs::read_to_string(checkup.proc_root.join("sys/kernel/osrelease"))
        .ok()
        .map(|r| format!(", kernel {}", r.trim()))
        .unwrap_or_default();
    #[cfg(not(target_os = "linux"))]
    let release = String::new();
    let os = match std::env::consts::OS {
        "linux" => "Linux",
        "macos" => "macOS",
        "windows" => "Windows",
        other => other,
    };
    finding(
        "platform",
        Verdict::Info,
        format!(
            "{os} {}{release}, benchbus {}",
            std::env::consts::ARCH,
            env!("CARGO_PKG_VERSION")
        ),
    )
}

/// The `/dev/cu.*` twin of a macOS `/dev/tty.*` path (the call-out device, which opens
/// without waiting for a carrier signal).
pub fn cu_twin(path: &str) -> Option<String> {
    let rest = path.strip_prefix("/dev/tty.")?;
    (!rest.is_empty()).then(|| format!("/dev/cu.{rest}"))
}

/// The tty names a port may go by in sysfs: its file name as given, then as its links
/// resolve (`/dev/serial/by-id/usb-FTDI_...` is `ttyUSB0`).
fn tty_names(port: &str) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    let given = Path::new(port).to_path_buf();
    let canonical = std::fs::canonicalize(port).ok();
    for p in std::iter::once(given).chain(canonical) {
        if let Some(name) = p.file_name().and_then(|n| n.to_str()) {
            if !names.iter().any(|n| n == name) {
                names.push(name.to_owned());
            }
        }
    }
    names
}

#[cfg(unix)]
fn exists(port: &str, meta: &std::fs::Metadata) -> Finding {
    use std::os::unix::fs::FileTypeExt;
    if !meta.file_type().is_char_device() {
        return finding(
            "port",
            Verdict::Fail,
            format!("{port} exists but is not a serial device"),
        )
        .fix("run 'benchbus ports' to list the serial ports");
    }
    let also = match std::fs::canonicalize(port) {
        Ok(device) if device != Path::new(port) => format!(", a link to {}", device.display()),
        _ => String::new(),
    };
    finding("port", Verdict::Ok, format!("{port} exists{also}"))
}

/// Whether this process may open `port` for reading and writing (`access`).
#[cfg(unix)]
fn may_read_and_write(port: &str) -> bool {
    std::ffi::CString::new(port).is_ok_and(|c| {
        // SAFETY: a NUL-terminated path; access only reads it.
        unsafe { libc::access(c.as_ptr(), libc::R_OK | libc::W_OK) == 0 }
    })
}

#[cfg_attr(not(unix), allow(dead_code))]
fn permissions(port: &str, allowed: bool) -> Finding {
    if allowed {
        finding("permissions", Verdict::Ok, "you may read and write it")
    } else {
        finding(
            "permissions",
            Verdict::Fail,
            format!("you may not open {port} for reading and writing"),
        )
        .fix(super::serial::PERMISSION_HINT)
    }
}

/// Whether the port opened (exclusively, at `line`), and who else has it open: the
/// processes in `holders` that are not this one. A port in use names who holds it (this
/// process if no other does: a Bus left open here).
fn open_findings(
    opened: &serialport::Result<SerialTransport>,
    holders: &[Holder],
    line: &LineFormat,
) -> Vec<Finding> {
    let me = std::process::id();
    let others: Vec<String> = holders
        .iter()
        .filter(|h| h.pid != me)
        .map(Holder::to_string)
        .collect();
    let e = match opened {
        Ok(_) => {
            let mut out = vec![finding(
                "open",
                Verdict::Ok,
                format!("opens, exclusively, at {line}"),
            )];
            if !others.is_empty() {
                out.push(
                    finding(
                        "holders",
                        Verdict::Warn,
                        format!(
                            "also open in {}: it may read the replies before benchbus does",
                            others.join(", ")
                        ),
                    )
                    .fix(
                        "close that program (a terminal such as minicom or screen, \
                         ModemManager, another script)",
                    ),
                );
            }
            return out;
        }
        Err(e) => e,
    };
    let message = format!("cannot open: {}", describe_open_error(e));
    vec![match e.kind() {
        serialport::ErrorKind::NoDevice => {
            let who = if others.is_empty() {
                holders.iter().map(Holder::to_string).collect()
            } else {
                others
            };
            let held = if who.is_empty() {
                message
            } else {
                format!("{message}; held by {}", who.join(", "))
            };
            finding("open", Verdict::Fail, held)
                .fix("close the program or Bus that holds it, then try again")
        }
        // The hint goes in the fix, not in the message too.
        serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied) => finding(
            "open",
            Verdict::Fail,
            format!("cannot open: {}", e.description),
        )
        .fix(super::serial::PERMISSION_HINT),
        _ => finding("open", Verdict::Fail, message),
    }]
}

/// What the system knows of the port, from the port list ([`ports::list_ports_in`] under
/// the check-up's sysfs on Linux).
fn port_info(names: &[String], checkup: &Checkup) -> Option<PortInfo> {
    #[cfg(target_os = "linux")]
    let listed = ports::list_ports_in(&checkup.sysfs);
    #[cfg(not(target_os = "linux"))]
    let listed = {
        let _ = checkup;
        ports::list_ports()
    };
    let listed = listed.ok()?;
    names.iter().find_map(|name| {
        listed
            .iter()
            .find(|p| Path::new(&p.path).file_name().and_then(|n| n.to_str()) == Some(name))
            .cloned()
    })
}

/// The tty name of an FTDI adapter's port, if this is one.
#[cfg(target_os = "linux")]
fn ftdi_name<'a>(info: Option<&'a PortInfo>, names: &'a [String]) -> Option<&'a str> {
    let info = info?;
    let ftdi = info.driver.as_deref() == Some("ftdi_sio")
        || info.usb.as_ref().and_then(|u| u.chip()) == Some("FTDI");
    ftdi.then(|| Path::new(&info.path).file_name().and_then(|n| n.to_str()))
        .flatten()
        .or_else(|| ftdi.then(|| names.first().map(String::as_str)).flatten())
}

fn usb(info: Option<&PortInfo>) -> Finding {
    let Some(info) = info else {
        return finding(
            "usb",
            Verdict::Info,
            "not a serial port the system lists (a pseudo-terminal, or a virtual port)",
        );
    };
    let driver = info
        .driver
        .as_deref()
        .map(|d| format!(", driver {d}"))
        .unwrap_or_default();
    let Some(u) = &info.usb else {
        return finding(
            "usb",
            Verdict::Info,
            format!("not a USB adapter: the board's own UART{driver}"),
        );
    };
    let strings: Vec<&str> = [&u.manufacturer, &u.product]
        .into_iter()
        .filter_map(|s| s.as_deref())
        .collect();
    let serial = u
        .serial_number
        .as_deref()
        .map(|s| format!(", serial {s}"))
        .unwrap_or_default();
    let what = format!(
        "{:04x}:{:04x} {}{serial}{driver}",
        u.vid,
        u.pid,
        strings.join(" ")
    );
    match u.chip() {
        Some(chip) => finding(
            "usb",
            Verdict::Ok,
            format!("{chip} adapter ({})", what.trim_end()),
        ),
        None => finding(
            "usb",
            Verdict::Info,
            format!(
                "a USB device of a chip benchbus does not know ({})",
                what.trim_end()
            ),
        ),
    }
}

/// The FTDI latency timer finding: `before` the port was opened, `after` the open's
/// low-latency request (the driver then shows 1 ms).
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
fn latency_timer(name: &str, before: u32, after: Option<u32>) -> Finding {
    let fix = format!(
        "write 1 to /sys/bus/usb-serial/devices/{name}/latency_timer (as root), and keep it with \
         a udev rule in /etc/udev/rules.d/99-ftdi-latency.rules: {FTDI_UDEV_RULE}"
    );
    if before <= 1 {
        return finding(
            "latency-timer",
            Verdict::Ok,
            format!("FTDI latency timer {before} ms"),
        );
    }
    let cost = format!("FTDI latency timer {before} ms: it adds up to {before} ms to every reply");
    if after == Some(1) {
        finding(
            "latency-timer",
            Verdict::Info,
            format!("{cost}; benchbus's low-latency request sets 1 ms while the adapter stays plugged in, other programs get {before} ms until then"),
        )
        .fix(fix)
    } else {
        finding("latency-timer", Verdict::Warn, cost).fix(fix)
    }
}

fn low_latency(state: &LowLatency) -> Finding {
    match state {
        LowLatency::On => finding(
            "low-latency",
            Verdict::Ok,
            "the driver's low-latency mode is on (benchbus asks for it at every open)",
        ),
        LowLatency::Unsupported => finding(
            "low-latency",
            Verdict::Info,
            "not supported: this port's driver has no low-latency mode (a pseudo-terminal, \
             some drivers): nothing to set",
        ),
        LowLatency::Refused(why) => finding(
            "low-latency",
            Verdict::Warn,
            format!("the driver refused its low-latency mode: {why}"),
        )
        .fix("as root: setserial PORT low_latency"),
        LowLatency::NotChecked => {
            finding("low-latency", Verdict::Info, "not checked on this platform")
        }
    }
}

/// The RS485 finding from the mode the open read; `settable` asks the driver, for a mode
/// that is off, whether it could switch it on (see [`super::linux::rs485_settable`]).
fn rs485(state: &Rs485State, settable: impl FnOnce() -> bool) -> Finding {
    let none = "no kernel RS485 mode (a USB RS485 adapter switches direction by itself; a \
                pseudo-terminal or a plain UART has none): leave rs485 off";
    match state {
        Rs485State::On {
            rts_on_send,
            rts_delay_ms: (before, after),
            rx_during_tx,
        } => finding(
            "rs485",
            Verdict::Info,
            format!(
                "kernel RS485 mode on: RTS {} while sending, delays {before} ms before and \
                 {after} ms after{}",
                if *rts_on_send { "high" } else { "low" },
                if *rx_during_tx {
                    "; the receiver stays on while sending (open the Bus with echo=True)"
                } else {
                    ""
                }
            ),
        ),
        Rs485State::Off if settable() => finding(
            "rs485",
            Verdict::Info,
            "this UART's driver has a kernel RS485 mode, and it is off",
        )
        .fix(
            "if it drives an RS485 transceiver (a HAT, an industrial PC's port), open the Bus \
             with rs485=True",
        ),
        Rs485State::Off | Rs485State::Unsupported => finding("rs485", Verdict::Info, none),
        Rs485State::NotChecked => finding("rs485", Verdict::Info, "not checked on this platform"),
    }
}

/// How many leading bytes of the request a reply cannot repeat by chance (a read's reply
/// repeats its unit and function): more, and it is a piece of the echo.
const ECHO_PREFIX: usize = 3;

/// Sends a read of one holding register to the check-up's unit and reads what comes back
/// first: the request itself (a local echo), a reply, or nothing.
fn echo(mut transport: SerialTransport, checkup: &Checkup) -> Finding {
    let request = encode_request(
        checkup.unit,
        &Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        },
    );
    let sent = transport
        .discard_input()
        .and_then(|_| transport.write_all(&request));
    if let Err(e) = sent {
        return finding("echo", Verdict::Fail, format!("cannot send a request: {e}"));
    }
    let deadline = Instant::now() + checkup.line.frame_time(request.len()) + checkup.timeout;
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    while got.len() < request.len() {
        let left = deadline.saturating_duration_since(Instant::now());
        match transport.read(&mut buf, left) {
            Ok(0) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) => return finding("echo", Verdict::Fail, format!("cannot read: {e}")),
        }
    }
    echo_finding(&request, &got, checkup)
}

fn echo_finding(request: &[u8], got: &[u8], checkup: &Checkup) -> Finding {
    let wait = format!("{} ms", checkup.timeout.as_millis());
    let read = format!("a read of register 0 from unit {}", checkup.unit);
    if got.starts_with(request) {
        return finding(
            "echo",
            Verdict::Warn,
            format!("local echo: {read} came back as sent (the adapter hears itself)"),
        )
        .fix("open the Bus with echo=True: bb.Bus(port, echo=True)");
    }
    let common = got.iter().zip(request).take_while(|(a, b)| a == b).count();
    if common >= ECHO_PREFIX || (!got.is_empty() && common == got.len() && got.len() >= 2) {
        return finding(
            "echo",
            Verdict::Warn,
            format!(
                "part of {read} came back ({} of {} bytes as sent): a broken echo, another \
                 talker on the line, or a wrong line format",
                common,
                request.len()
            ),
        )
        .fix("check the baud rate and parity; if the adapter echoes, open the Bus with echo=True");
    }
    if got.is_empty() {
        finding(
            "echo",
            Verdict::Ok,
            format!("no echo: nothing came back within {wait} of {read}"),
        )
    } else {
        finding(
            "echo",
            Verdict::Ok,
            format!("no echo: a reply came back first to {read}"),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timing::Parity;

    fn checkup() -> Checkup {
        Checkup::new(LineFormat::new(19_200, Parity::None, 1))
    }

    #[test]
    fn a_macos_tty_path_suggests_its_cu_twin() {
        assert_eq!(
            cu_twin("/dev/tty.usbserial-A50285BI").as_deref(),
            Some("/dev/cu.usbserial-A50285BI")
        );
        for other in ["/dev/cu.usbserial-1", "/dev/ttyUSB0", "/dev/tty.", "COM3"] {
            assert_eq!(cu_twin(other), None, "{other}");
        }
        let found = diagnose("/dev/tty.usbserial-X", &checkup()).unwrap();
        let cu = found.iter().find(|f| f.name == "tty-vs-cu").unwrap();
        assert_eq!(cu.verdict, Verdict::Warn);
        assert_eq!(cu.fix.as_deref(), Some("open /dev/cu.usbserial-X instead"));
    }

    #[test]
    fn the_echo_test_tells_an_echo_from_a_reply() {
        let c = checkup();
        let req = encode_request(
            1,
            &Request::ReadHoldingRegisters {
                address: 0,
                count: 1,
            },
        );
        let echoed = [req.clone(), vec![1, 3, 2, 0, 7]].concat();
        assert_eq!(echo_finding(&req, &echoed, &c).verdict, Verdict::Warn);
        assert!(echo_finding(&req, &echoed, &c)
            .fix
            .unwrap()
            .contains("echo=True"));
        let reply = [1, 3, 2, 0, 7, 0xF9, 0x86];
        let f = echo_finding(&req, &reply, &c);
        assert_eq!(
            (f.verdict, f.message.contains("a reply")),
            (Verdict::Ok, true)
        );
        let f = echo_finding(&req, &[], &c);
        assert_eq!(
            (f.verdict, f.message.contains("nothing")),
            (Verdict::Ok, true)
        );
        let f = echo_finding(&req, &req[..4], &c);
        assert_eq!(
            (f.verdict, f.message.contains("part of")),
            (Verdict::Warn, true)
        );
    }

    #[test]
    fn an_ftdi_latency_timer_above_1_ms_is_a_warning_with_the_udev_rule() {
        let f = latency_timer("ttyUSB0", 16, Some(16));
        assert_eq!(f.verdict, Verdict::Warn);
        assert!(f.message.contains("16 ms"), "{}", f.message);
        let fix = f.fix.unwrap();
        assert!(fix.contains("/sys/bus/usb-serial/devices/ttyUSB0/latency_timer"));
        assert!(fix.contains(FTDI_UDEV_RULE));
        assert_eq!(latency_timer("ttyUSB0", 16, Some(1)).verdict, Verdict::Info);
        assert_eq!(latency_timer("ttyUSB0", 1, Some(1)).verdict, Verdict::Ok);
        assert_eq!(latency_timer("ttyUSB0", 1, Some(1)).fix, None);
    }

    #[test]
    fn a_port_the_user_may_not_open_gets_the_permission_hint() {
        let f = permissions("/dev/ttyUSB0", false);
        assert_eq!(f.verdict, Verdict::Fail);
        assert_eq!(
            f.fix.as_deref(),
            Some(super::super::serial::PERMISSION_HINT)
        );
        #[cfg(target_os = "linux")]
        assert!(f.fix.unwrap().contains("sudo usermod -aG dialout $USER"));
        assert_eq!(permissions("/dev/ttyUSB0", true).verdict, Verdict::Ok);
    }

    #[cfg(unix)]
    #[test]
    fn a_file_that_is_no_serial_device_stops_the_check_up() {
        let file = std::env::temp_dir().join(format!("benchbus-not-a-tty-{}", std::process::id()));
        std::fs::write(&file, "").unwrap();
        let found = diagnose(file.to_str().unwrap(), &checkup()).unwrap();
        std::fs::remove_file(&file).unwrap();
        let last = found.last().unwrap();
        assert_eq!((last.name, last.verdict), ("port", Verdict::Fail));
        assert!(
            last.message.contains("not a serial device"),
            "{}",
            last.message
        );
    }

    #[test]
    fn a_port_in_use_names_who_holds_it_and_a_refused_one_the_permission() {
        let line = checkup().line;
        let minicom = Holder {
            pid: std::process::id() + 1,
            command: Some("minicom".into()),
        };
        let me = Holder {
            pid: std::process::id(),
            command: Some("python3".into()),
        };
        let busy = Err(serialport::Error::new(
            serialport::ErrorKind::NoDevice,
            "Unable to acquire exclusive lock on serial port",
        ));
        let found = open_findings(&busy, &[me.clone(), minicom.clone()], &line);
        assert_eq!(found.len(), 1);
        assert!(
            found[0]
                .message
                .ends_with(&format!("; held by pid {} (minicom)", minicom.pid)),
            "{}",
            found[0].message
        );
        let found = open_findings(&busy, &[me], &line);
        assert!(found[0].message.ends_with("(this process)"), "{found:?}");
        let denied = Err(serialport::Error::new(
            serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied),
            "Permission denied",
        ));
        let found = open_findings(&denied, &[], &line);
        assert_eq!(found[0].message, "cannot open: Permission denied");
        assert_eq!(
            found[0].fix.as_deref(),
            Some(super::super::serial::PERMISSION_HINT)
        );
    }

    #[test]
    fn rs485_mode_off_is_worth_a_fix_only_where_the_driver_can_set_it() {
        let off = rs485(&Rs485State::Off, || true);
        assert!(off
            .message
            .contains("has a kernel RS485 mode, and it is off"));
        assert!(off.fix.unwrap().contains("rs485=True"));
        // A 16550A reads its mode (off) but has no rs485_config to set one.
        let plain = rs485(&Rs485State::Off, || false);
        assert!(
            plain.message.starts_with("no kernel RS485 mode"),
            "{plain:?}"
        );
        assert_eq!(plain.fix, None);
        let on = rs485(
            &Rs485State::On {
                rts_on_send: true,
                rts_delay_ms: (1, 2),
                rx_during_tx: false,
            },
            || unreachable!(),
        );
        assert_eq!(
            on.message,
            "kernel RS485 mode on: RTS high while sending, delays 1 ms before and 2 ms after"
        );
    }

    #[test]
    fn a_network_port_is_not_diagnosed() {
        assert!(diagnose("tcp://127.0.0.1:502", &checkup()).is_err());
        assert!(diagnose("", &checkup()).is_err());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_pty_opens_without_low_latency_rs485_mode_or_echo() {
        let (master, path) = crate::transport::test_pty();
        let mut c = checkup();
        c.sysfs = PathBuf::from("/nonexistent/sysfs");
        let found = diagnose(&path, &c).unwrap();
        let names: Vec<&str> = found.iter().map(|f| f.name).collect();
        assert_eq!(
            names,
            [
                "platform",
                "port",
                "permissions",
                "open",
                "usb",
                "low-latency",
                "rs485",
                "echo"
            ]
        );
        let by = |name: &str| found.iter().find(|f| f.name == name).unwrap();
        assert_eq!(by("open").verdict, Verdict::Ok);
        assert!(by("low-latency").message.starts_with("not supported"));
        assert!(by("rs485").message.starts_with("no kernel RS485 mode"));
        // Nothing answers on the master side: the request is read there, never echoed.
        assert_eq!(by("echo").verdict, Verdict::Ok, "{:?}", by("echo"));
        let mut sent = [0u8; 16];
        // SAFETY: our own fd and buffer.
        let n = unsafe { libc::read(master, sent.as_mut_ptr().cast(), sent.len()) };
        assert_eq!(&sent[..2], &[1, 3], "{n}");
        // SAFETY: our own fd, closed once.
        unsafe { libc::close(master) };
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn rs485_on_a_pty_is_refused_and_leaves_the_port_closed() {
        let (master, path) = crate::transport::test_pty();
        let line = checkup().line;
        let rs485 = super::super::tuning::Rs485::default();
        let e = SerialTransport::open_with(&path, &line, Some(&rs485))
            .err()
            .map(|e| describe_open_error(&e));
        assert_eq!(e.as_deref(), Some(super::super::tuning::NO_RS485_MODE));
        let t = SerialTransport::open(&path, &line).unwrap();
        assert_eq!(t.tuned().low_latency, LowLatency::Unsupported);
        assert_eq!(t.tuned().rs485, Rs485State::Unsupported);
        drop(t);
        // SAFETY: our own fd, closed once.
        unsafe { libc::close(master) };
    }
}
