//! What benchbus asks of a serial port's driver when it opens it, beyond the line format,
//! and what it found: on Linux the driver's low-latency mode (always asked, where the driver
//! and permissions allow) and the kernel's RS485 mode (when the Bus is opened with
//! [`Rs485`]). Other systems have neither: low latency is [`LowLatency::NotChecked`] there,
//! and RS485 mode is refused before the port opens ([`check_rs485_platform`]).

use std::time::Duration;

/// What a port that has no kernel RS485 mode says when a Bus asks for it.
pub const NO_RS485_MODE: &str = "this port has no kernel RS485 mode (a USB RS485 adapter \
                                 switches direction by itself: leave rs485 off)";

/// The longest RTS delay the kernel accepts (`RS485_MAX_RTS_DELAY`, 100 ms; it clamps more).
pub const MAX_RTS_DELAY: Duration = Duration::from_millis(100);

/// The kernel RS485 mode a Bus asks for: RTS drives the transceiver's driver enable, high
/// while sending, with these delays before the first and after the last bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rs485 {
    before: Duration,
    after: Duration,
}

impl Rs485 {
    /// RS485 mode with RTS delays `before` the first start bit and `after` the last stop
    /// bit, each 0 to [`MAX_RTS_DELAY`] (the kernel takes whole milliseconds: they are
    /// rounded to the nearest).
    ///
    /// # Errors
    /// A message if a delay is above [`MAX_RTS_DELAY`].
    pub fn new(before: Duration, after: Duration) -> Result<Rs485, String> {
        for (name, d) in [("before", before), ("after", after)] {
            if d > MAX_RTS_DELAY {
                return Err(format!(
                    "rts_delay {name} sending must be 0 to {} seconds (the kernel's limit), \
                     got {}",
                    MAX_RTS_DELAY.as_secs_f64(),
                    d.as_secs_f64()
                ));
            }
        }
        Ok(Rs485 { before, after })
    }

    /// The delays (before, after sending).
    pub fn rts_delay(&self) -> (Duration, Duration) {
        (self.before, self.after)
    }

    /// The delays in whole milliseconds, as the kernel takes them.
    pub fn rts_delay_ms(&self) -> (u32, u32) {
        let ms = |d: Duration| (d.as_micros() as u32 + 500) / 1000;
        (ms(self.before), ms(self.after))
    }
}

/// Whether the driver's low-latency mode is on for an open port.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LowLatency {
    /// On: the driver hands each received byte on at once (an FTDI adapter's latency timer
    /// is 1 ms while it is on).
    On,
    /// The port has no such mode (a pseudo-terminal; a driver without it).
    Unsupported,
    /// The driver refused the change (the system's words).
    Refused(String),
    /// Not asked on this system (only Linux has it).
    NotChecked,
}

/// The kernel RS485 mode of a port, as the driver reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Rs485State {
    /// On.
    On {
        /// RTS high while sending (else low).
        rts_on_send: bool,
        /// The RTS delays before and after sending, in milliseconds.
        rts_delay_ms: (u32, u32),
        /// The receiver stays on while sending (the request comes back as a local echo).
        rx_during_tx: bool,
    },
    /// The port has the mode, and it is off.
    Off,
    /// The port has no kernel RS485 mode (a pseudo-terminal, a USB adapter).
    Unsupported,
    /// Not read on this system (only Linux has it).
    NotChecked,
}

/// What the open of a serial port asked of its driver, and got.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tuned {
    /// The driver's low-latency mode.
    pub low_latency: LowLatency,
    /// The kernel RS485 mode: as benchbus set it if asked to, else as the port had it.
    pub rs485: Rs485State,
}

/// Refuses RS485 mode where benchbus cannot set it (anywhere but Linux), before a port is
/// opened.
///
/// # Errors
/// A message saying so, for a ValueError.
pub fn check_rs485_platform(rs485: Option<&Rs485>) -> Result<(), String> {
    if rs485.is_some() && !cfg!(target_os = "linux") {
        return Err(format!(
            "rs485=True sets the Linux kernel's RS485 mode, which {} does not have (a USB \
             RS485 adapter switches direction by itself: leave rs485 off)",
            std::env::consts::OS
        ));
    }
    Ok(())
}

/// Asks the driver of the just-opened `port` for low latency, reads or (if `rs485` is
/// given) sets its kernel RS485 mode, and says what it got.
///
/// # Errors
/// A message for the user if RS485 mode was asked for and cannot be set; the caller closes
/// the port.
#[cfg(unix)]
pub(crate) fn on_open(
    port: &impl std::os::unix::io::AsRawFd,
    rs485: Option<&Rs485>,
) -> Result<Tuned, String> {
    #[cfg(target_os = "linux")]
    {
        let fd = port.as_raw_fd();
        let rs485 = match rs485 {
            Some(r) => super::linux::set_rs485(fd, r)?,
            None => super::linux::rs485_state(fd).unwrap_or(Rs485State::NotChecked),
        };
        Ok(Tuned {
            low_latency: super::linux::ask_low_latency(fd),
            rs485,
        })
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = port;
        not_checked(rs485)
    }
}

/// As the unix [`on_open`]: nothing to ask of the driver here.
///
/// # Errors
/// A message if RS485 mode was asked for.
#[cfg(not(unix))]
pub(crate) fn on_open<P>(port: &P, rs485: Option<&Rs485>) -> Result<Tuned, String> {
    let _ = port;
    not_checked(rs485)
}

#[cfg(not(target_os = "linux"))]
fn not_checked(rs485: Option<&Rs485>) -> Result<Tuned, String> {
    check_rs485_platform(rs485)?;
    Ok(Tuned {
        low_latency: LowLatency::NotChecked,
        rs485: Rs485State::NotChecked,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rts_delays_are_whole_milliseconds_within_the_kernel_limit() {
        let r = Rs485::new(Duration::from_secs_f64(0.003), Duration::from_micros(499)).unwrap();
        assert_eq!(r.rts_delay_ms(), (3, 0));
        let r = Rs485::new(MAX_RTS_DELAY, Duration::from_micros(1_500)).unwrap();
        assert_eq!(r.rts_delay_ms(), (100, 2));
        let e = Rs485::new(Duration::ZERO, Duration::from_millis(101)).unwrap_err();
        assert!(e.contains("after sending must be 0 to 0.1 seconds"), "{e}");
    }

    #[test]
    fn rs485_is_refused_before_opening_only_where_benchbus_cannot_set_it() {
        assert_eq!(check_rs485_platform(None), Ok(()));
        let asked = check_rs485_platform(Some(&Rs485::default()));
        assert_eq!(asked.is_ok(), cfg!(target_os = "linux"), "{asked:?}");
    }
}
