//! What Linux tells and lets benchbus set of a serial port beyond its line format: the
//! driver's low-latency mode (`TIOCGSERIAL` / `TIOCSSERIAL`, what `setserial low_latency`
//! does), the kernel's RS485 mode (`TIOCGRS485` / `TIOCSRS485`, `serial_rs485`), and which
//! processes hold a device open (`/proc/<pid>/fd`). Each probe takes a raw file descriptor
//! or a path (and the `/proc` root as a parameter, so tests can use a tree of their own).

use super::doctor::Holder;
use super::tuning::{LowLatency, Rs485, Rs485State};
use std::io;
use std::os::unix::io::RawFd;
use std::path::Path;

/// `struct serial_struct` of `<linux/serial.h>` (`TIOCGSERIAL` / `TIOCSSERIAL`).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub(crate) struct SerialStruct {
    pub kind: libc::c_int,
    pub line: libc::c_int,
    pub port: libc::c_uint,
    pub irq: libc::c_int,
    pub flags: libc::c_int,
    pub xmit_fifo_size: libc::c_int,
    pub custom_divisor: libc::c_int,
    pub baud_base: libc::c_int,
    pub close_delay: libc::c_ushort,
    pub io_type: libc::c_char,
    pub reserved_char: [libc::c_char; 1],
    pub hub6: libc::c_int,
    pub closing_wait: libc::c_ushort,
    pub closing_wait2: libc::c_ushort,
    pub iomem_base: *mut libc::c_uchar,
    pub iomem_reg_shift: libc::c_ushort,
    pub port_high: libc::c_uint,
    pub iomap_base: libc::c_ulong,
}

/// `ASYNC_LOW_LATENCY` (`1 << ASYNCB_LOW_LATENCY`, bit 13) of `<linux/tty_flags.h>`: the
/// driver hands received bytes on at once (`ftdi_sio` also sets its latency timer to 1 ms).
pub(crate) const ASYNC_LOW_LATENCY: libc::c_int = 1 << 13;

/// `struct serial_rs485` of `<linux/serial.h>` (`TIOCGRS485` / `TIOCSRS485`): 32 bytes.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SerialRs485 {
    pub flags: u32,
    /// Milliseconds from RTS on to the first start bit.
    pub delay_rts_before_send: u32,
    /// Milliseconds from the last stop bit to RTS off.
    pub delay_rts_after_send: u32,
    pub padding: [u32; 5],
}

/// `SER_RS485_ENABLED`: the kernel drives RTS as the transceiver's driver enable.
pub(crate) const SER_RS485_ENABLED: u32 = 1 << 0;
/// `SER_RS485_RTS_ON_SEND`: RTS high (logical 1) while sending.
pub(crate) const SER_RS485_RTS_ON_SEND: u32 = 1 << 1;
/// `SER_RS485_RTS_AFTER_SEND`: RTS high after sending (the other polarity; not set).
#[cfg(test)]
pub(crate) const SER_RS485_RTS_AFTER_SEND: u32 = 1 << 2;
/// `SER_RS485_RX_DURING_TX`: the receiver stays on while sending (a local echo).
pub(crate) const SER_RS485_RX_DURING_TX: u32 = 1 << 4;

/// Whether an ioctl's error means the port has no such mode (`ENOTTY`: the driver has no
/// handler, as on a pseudo-terminal; `EINVAL`, `EOPNOTSUPP`: it refuses the request).
fn unsupported(e: &io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(libc::ENOTTY | libc::EINVAL | libc::EOPNOTSUPP)
    )
}

fn get_serial(fd: RawFd) -> io::Result<SerialStruct> {
    // SAFETY: all-zero is a valid SerialStruct (integers and a null pointer).
    let mut ss: SerialStruct = unsafe { std::mem::zeroed() };
    // SAFETY: TIOCGSERIAL writes one serial_struct into the buffer we own.
    let rc = unsafe { libc::ioctl(fd, libc::TIOCGSERIAL, &mut ss as *mut SerialStruct) };
    if rc < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(ss)
}

/// Asks the driver of `fd` for its low-latency mode (`ASYNC_LOW_LATENCY`), and says whether
/// it is on afterwards. Never an error: a port without the mode (a pseudo-terminal) is
/// [`LowLatency::Unsupported`], one whose driver refuses the change
/// [`LowLatency::Refused`].
pub(crate) fn ask_low_latency(fd: RawFd) -> LowLatency {
    let mut ss = match get_serial(fd) {
        Ok(ss) => ss,
        Err(e) if unsupported(&e) => return LowLatency::Unsupported,
        Err(e) => return LowLatency::Refused(e.to_string()),
    };
    if ss.flags & ASYNC_LOW_LATENCY != 0 {
        return LowLatency::On;
    }
    ss.flags |= ASYNC_LOW_LATENCY;
    // SAFETY: TIOCSSERIAL reads one serial_struct from the buffer we own.
    let rc = unsafe { libc::ioctl(fd, libc::TIOCSSERIAL, &ss as *const SerialStruct) };
    if rc < 0 {
        let e = io::Error::last_os_error();
        return if unsupported(&e) {
            LowLatency::Unsupported
        } else {
            LowLatency::Refused(e.to_string())
        };
    }
    match get_serial(fd) {
        Ok(ss) if ss.flags & ASYNC_LOW_LATENCY != 0 => LowLatency::On,
        Ok(_) => LowLatency::Unsupported,
        Err(e) => LowLatency::Refused(e.to_string()),
    }
}

/// The kernel RS485 mode of `fd`; [`Rs485State::Unsupported`] for a port without one.
///
/// # Errors
/// Another error of `TIOCGRS485` (a port gone).
pub(crate) fn rs485_state(fd: RawFd) -> io::Result<Rs485State> {
    let mut conf = SerialRs485::default();
    // SAFETY: TIOCGRS485 writes one serial_rs485 into the buffer we own.
    let rc = unsafe { libc::ioctl(fd, libc::TIOCGRS485, &mut conf as *mut SerialRs485) };
    if rc < 0 {
        let e = io::Error::last_os_error();
        return if unsupported(&e) {
            Ok(Rs485State::Unsupported)
        } else {
            Err(e)
        };
    }
    Ok(state_of(&conf))
}

/// Whether the driver of `fd` can set a kernel RS485 mode: its current one is set again,
/// unchanged (a UART whose driver has no `rs485_config` reads its mode but refuses to set
/// any). False for a port without the mode at all.
pub(crate) fn rs485_settable(fd: RawFd) -> bool {
    let mut conf = SerialRs485::default();
    // SAFETY: TIOCGRS485 writes one serial_rs485 into the buffer we own.
    if unsafe { libc::ioctl(fd, libc::TIOCGRS485, &mut conf as *mut SerialRs485) } < 0 {
        return false;
    }
    // SAFETY: TIOCSRS485 reads one serial_rs485 from the buffer we own.
    unsafe { libc::ioctl(fd, libc::TIOCSRS485, &conf as *const SerialRs485) == 0 }
}

fn state_of(conf: &SerialRs485) -> Rs485State {
    if conf.flags & SER_RS485_ENABLED == 0 {
        return Rs485State::Off;
    }
    Rs485State::On {
        rts_on_send: conf.flags & SER_RS485_RTS_ON_SEND != 0,
        rts_delay_ms: (conf.delay_rts_before_send, conf.delay_rts_after_send),
        rx_during_tx: conf.flags & SER_RS485_RX_DURING_TX != 0,
    }
}

/// The `serial_rs485` that turns RS485 mode on as `rs485` asks: RTS high while sending,
/// low after, with its delays in whole milliseconds.
pub(crate) fn rs485_conf(rs485: &Rs485) -> SerialRs485 {
    let (before, after) = rs485.rts_delay_ms();
    SerialRs485 {
        flags: SER_RS485_ENABLED | SER_RS485_RTS_ON_SEND,
        delay_rts_before_send: before,
        delay_rts_after_send: after,
        padding: [0; 5],
    }
}

/// Turns the kernel RS485 mode of `fd` on as `rs485` asks, and checks that it took.
///
/// # Errors
/// A message for the user: the port has no kernel RS485 mode (a pseudo-terminal, a USB
/// adapter), or the ioctl failed otherwise.
pub(crate) fn set_rs485(fd: RawFd, rs485: &Rs485) -> Result<Rs485State, String> {
    let conf = rs485_conf(rs485);
    // SAFETY: TIOCSRS485 reads one serial_rs485 from the buffer we own (and may write back
    // what the driver kept).
    let rc = unsafe { libc::ioctl(fd, libc::TIOCSRS485, &conf as *const SerialRs485) };
    if rc < 0 {
        let e = io::Error::last_os_error();
        return Err(if unsupported(&e) {
            super::tuning::NO_RS485_MODE.to_string()
        } else {
            format!("cannot set RS485 mode: {e}")
        });
    }
    match rs485_state(fd) {
        Ok(state @ Rs485State::On { .. }) => Ok(state),
        Ok(_) => Err(super::tuning::NO_RS485_MODE.to_string()),
        Err(e) => Err(format!("cannot read back the RS485 mode: {e}")),
    }
}

/// The processes under `proc_root` (`/proc` on a running system) with a file descriptor on
/// one of `paths` (a device's path as given and as its links resolve), by pid. Processes
/// whose `fd` directory cannot be read (another user's, without privileges) are not seen.
pub(crate) fn holders(proc_root: &Path, paths: &[&Path]) -> Vec<Holder> {
    let Ok(entries) = std::fs::read_dir(proc_root) else {
        return Vec::new();
    };
    let mut out: Vec<Holder> = entries
        .filter_map(|entry| {
            let entry = entry.ok()?;
            let pid: u32 = entry.file_name().to_str()?.parse().ok()?;
            let fds = std::fs::read_dir(entry.path().join("fd")).ok()?;
            let holds = fds.filter_map(Result::ok).any(|fd| {
                std::fs::read_link(fd.path()).is_ok_and(|target| paths.contains(&&*target))
            });
            holds.then(|| Holder {
                pid,
                command: std::fs::read_to_string(entry.path().join("comm"))
                    .ok()
                    .map(|c| c.trim().to_owned())
                    .filter(|c| !c.is_empty()),
            })
        })
        .collect();
    out.sort_by_key(|h| h.pid);
    out
}

/// The FTDI latency timer of the tty `name` in milliseconds, read from
/// `<sysfs>/bus/usb-serial/devices/<name>/latency_timer`; None if there is none.
pub(crate) fn latency_timer(sysfs: &Path, name: &str) -> Option<u32> {
    let path = sysfs
        .join("bus/usb-serial/devices")
        .join(name)
        .join("latency_timer");
    std::fs::read_to_string(path).ok()?.trim().parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};
    use std::os::fd::AsRawFd;
    use std::os::unix::fs::OpenOptionsExt;
    use std::time::Duration;

    #[test]
    fn serial_rs485_matches_the_kernel_header() {
        // <linux/serial.h>: __u32 flags, delay_rts_before_send, delay_rts_after_send, then a
        // union of __u32 padding[5]: 32 bytes.
        assert_eq!(size_of::<SerialRs485>(), 32);
        assert_eq!(offset_of!(SerialRs485, flags), 0);
        assert_eq!(offset_of!(SerialRs485, delay_rts_before_send), 4);
        assert_eq!(offset_of!(SerialRs485, delay_rts_after_send), 8);
        assert_eq!(
            (
                SER_RS485_ENABLED,
                SER_RS485_RTS_ON_SEND,
                SER_RS485_RTS_AFTER_SEND,
                SER_RS485_RX_DURING_TX
            ),
            (0x01, 0x02, 0x04, 0x10)
        );
        // <asm-generic/ioctls.h> on the common architectures.
        #[cfg(any(target_arch = "x86_64", target_arch = "aarch64", target_arch = "x86"))]
        assert_eq!(
            (
                i128::from(libc::TIOCGRS485),
                i128::from(libc::TIOCSRS485),
                i128::from(libc::TIOCGSERIAL),
                i128::from(libc::TIOCSSERIAL)
            ),
            (0x542E, 0x542F, 0x541E, 0x541F)
        );
    }

    #[test]
    fn serial_struct_matches_the_kernel_header() {
        assert_eq!(offset_of!(SerialStruct, flags), 16);
        assert_eq!(offset_of!(SerialStruct, close_delay), 32);
        assert_eq!(offset_of!(SerialStruct, hub6), 36);
        #[cfg(target_pointer_width = "64")]
        assert_eq!(
            (
                offset_of!(SerialStruct, iomem_base),
                size_of::<SerialStruct>()
            ),
            (48, 72)
        );
        #[cfg(target_pointer_width = "32")]
        assert_eq!(
            (
                offset_of!(SerialStruct, iomem_base),
                size_of::<SerialStruct>()
            ),
            (44, 60)
        );
        assert_eq!(ASYNC_LOW_LATENCY, 0x2000);
    }

    #[test]
    fn rs485_is_asked_with_rts_on_send_and_the_delays_in_milliseconds() {
        let rs485 = Rs485::new(Duration::from_micros(2_400), Duration::from_millis(1)).unwrap();
        let conf = rs485_conf(&rs485);
        assert_eq!(conf.flags, SER_RS485_ENABLED | SER_RS485_RTS_ON_SEND);
        assert_eq!(
            (conf.delay_rts_before_send, conf.delay_rts_after_send),
            (2, 1)
        );
        assert_eq!(
            state_of(&conf),
            Rs485State::On {
                rts_on_send: true,
                rts_delay_ms: (2, 1),
                rx_during_tx: false
            }
        );
        assert_eq!(state_of(&SerialRs485::default()), Rs485State::Off);
    }

    #[test]
    fn a_pty_has_neither_low_latency_nor_rs485_mode() {
        let (master, path) = crate::transport::test_pty();
        let end = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY)
            .open(path)
            .unwrap();
        let slave = end.as_raw_fd();
        assert_eq!(ask_low_latency(slave), LowLatency::Unsupported);
        assert_eq!(rs485_state(slave).unwrap(), Rs485State::Unsupported);
        assert!(!rs485_settable(slave));
        let rs485 = Rs485::new(Duration::ZERO, Duration::ZERO).unwrap();
        let e = set_rs485(slave, &rs485).unwrap_err();
        assert!(e.contains("no kernel RS485 mode"), "{e}");
        drop(end);
        // SAFETY: our own fd, closed once.
        unsafe { libc::close(master) };
    }

    #[test]
    fn holders_are_found_by_their_fd_links() {
        let root = std::env::temp_dir().join(format!("benchbus-proc-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (pid, target, comm) in [
            ("321", "/dev/ttyUSB0", "minicom\n"),
            ("45", "/dev/ttyUSB1", "screen\n"),
            ("7", "/dev/ttyUSB0", ""),
        ] {
            let fd = root.join(pid).join("fd");
            std::fs::create_dir_all(&fd).unwrap();
            std::os::unix::fs::symlink(target, fd.join("3")).unwrap();
            std::fs::write(root.join(pid).join("comm"), comm).unwrap();
        }
        std::fs::create_dir_all(root.join("self")).unwrap();
        let found = holders(&root, &[Path::new("/dev/ttyUSB0")]);
        assert_eq!(
            found,
            [
                Holder {
                    pid: 7,
                    command: None
                },
                Holder {
                    pid: 321,
                    command: Some("minicom".into())
                }
            ]
        );
        assert_eq!(holders(&root.join("absent"), &[Path::new("/x")]), []);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
