//! Line format to wire timing: character time, t1.5 and t3.5 (Modbus over Serial Line V1.02,
//! 2.5.1.1: above 19200 baud fixed values of 750 us and 1.750 ms are used).

use std::time::{Duration, Instant};

/// Parity of the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

impl Parity {
    /// The letter used in line formats like "8E1".
    pub fn letter(self) -> char {
        match self {
            Parity::None => 'N',
            Parity::Even => 'E',
            Parity::Odd => 'O',
        }
    }

    /// Parses "N", "E" or "O" (any case).
    pub fn from_letter(s: &str) -> Option<Parity> {
        match s.to_ascii_uppercase().as_str() {
            "N" => Some(Parity::None),
            "E" => Some(Parity::Even),
            "O" => Some(Parity::Odd),
            _ => None,
        }
    }
}

/// Baud rates above this use the fixed t1.5 / t3.5 of the serial line spec.
const FIXED_TIMING_ABOVE: u32 = 19_200;

/// A serial line format: baud rate, data bits, parity and stop bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineFormat {
    /// Bits per second.
    pub baudrate: u32,
    /// Data bits per character (Modbus RTU: 8).
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits, 1 or 2.
    pub stop_bits: u8,
}

impl LineFormat {
    /// A line format with 8 data bits.
    pub fn new(baudrate: u32, parity: Parity, stop_bits: u8) -> LineFormat {
        LineFormat {
            baudrate,
            data_bits: 8,
            parity,
            stop_bits,
        }
    }

    /// Bits on the wire per character: start + data + parity + stop.
    pub fn bits_per_char(&self) -> u32 {
        let parity = u32::from(self.parity != Parity::None);
        1 + u32::from(self.data_bits) + parity + u32::from(self.stop_bits)
    }

    /// Time one character takes on the wire.
    pub fn char_time(&self) -> Duration {
        self.chars(1.0)
    }

    /// Time `n` characters take on the wire.
    pub fn frame_time(&self, n: usize) -> Duration {
        self.chars(n as f64)
    }

    /// Longest gap allowed inside a frame.
    pub fn t1_5(&self) -> Duration {
        if self.baudrate > FIXED_TIMING_ABOVE {
            Duration::from_micros(750)
        } else {
            self.chars(1.5)
        }
    }

    /// Silence that separates frames.
    pub fn t3_5(&self) -> Duration {
        if self.baudrate > FIXED_TIMING_ABOVE {
            Duration::from_micros(1750)
        } else {
            self.chars(3.5)
        }
    }

    fn chars(&self, n: f64) -> Duration {
        let baud = f64::from(self.baudrate.max(1));
        Duration::from_secs_f64(n * f64::from(self.bits_per_char()) / baud)
    }
}

impl std::fmt::Display for LineFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {}{}{}",
            self.baudrate,
            self.data_bits,
            self.parity.letter(),
            self.stop_bits
        )
    }
}

/// Keeps the line silent for t3.5 before each send, on the monotonic clock.
#[derive(Debug, Clone, Copy)]
pub struct SilenceGuard {
    quiet_since: Instant,
}

impl Default for SilenceGuard {
    fn default() -> Self {
        SilenceGuard::new()
    }
}

impl SilenceGuard {
    /// A guard whose line has been quiet since now.
    pub fn new() -> SilenceGuard {
        SilenceGuard {
            quiet_since: Instant::now(),
        }
    }

    /// Records that the line carries traffic until `until` (the end of a frame).
    pub fn busy_until(&mut self, until: Instant) {
        self.quiet_since = self.quiet_since.max(until);
    }

    /// The earliest instant a frame may start after `silence` of quiet line.
    pub fn ready_at(&self, silence: Duration) -> Instant {
        self.quiet_since + silence
    }

    /// Sleeps until the line has been quiet for `silence`; returns at once if it has.
    pub fn wait(&self, silence: Duration) {
        let ready = self.ready_at(silence);
        let now = Instant::now();
        if ready > now {
            std::thread::sleep(ready - now);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(d: Duration) -> f64 {
        d.as_secs_f64() * 1e6
    }

    #[test]
    fn char_time_counts_start_parity_and_stop_bits() {
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert_eq!(n81.bits_per_char(), 10);
        assert!((us(n81.char_time()) - 520.833).abs() < 0.01);
        let e81 = LineFormat::new(115_200, Parity::Even, 1);
        assert_eq!(e81.bits_per_char(), 11);
        assert!((us(e81.char_time()) - 95.486).abs() < 0.01);
        let n82 = LineFormat::new(9600, Parity::None, 2);
        assert_eq!(n82.bits_per_char(), 11);
    }

    #[test]
    fn t35_is_three_and_a_half_chars_up_to_19200_then_fixed() {
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert!((us(n81.t3_5()) - 1822.9).abs() < 0.1);
        assert!((us(n81.t1_5()) - 781.25).abs() < 0.01);
        let slow = LineFormat::new(9600, Parity::None, 1);
        assert!((us(slow.t3_5()) - 3645.8).abs() < 0.1);
        let fast = LineFormat::new(38_400, Parity::None, 1);
        assert_eq!(fast.t3_5(), Duration::from_micros(1750));
        assert_eq!(fast.t1_5(), Duration::from_micros(750));
    }

    #[test]
    fn wire_limit_of_single_register_reads() {
        // 8 request + 7 reply characters and one t3.5 per transaction.
        let per_tx = |f: LineFormat| f.frame_time(15) + f.t3_5();
        let n81 = LineFormat::new(19_200, Parity::None, 1);
        assert!((1.0 / per_tx(n81).as_secs_f64() - 103.8).abs() < 0.05);
        let e81 = LineFormat::new(115_200, Parity::Even, 1);
        assert!((1.0 / per_tx(e81).as_secs_f64() - 314.2).abs() < 0.05);
    }

    #[test]
    fn guard_waits_out_the_silence() {
        let mut g = SilenceGuard::new();
        let end = Instant::now() + Duration::from_millis(5);
        g.busy_until(end);
        g.busy_until(Instant::now()); // an earlier instant never shortens the wait
        g.wait(Duration::from_millis(2));
        assert!(Instant::now() >= end + Duration::from_millis(2));
    }

    #[test]
    fn display_is_the_usual_notation() {
        assert_eq!(
            LineFormat::new(115_200, Parity::Even, 1).to_string(),
            "115200 8E1"
        );
    }
}
