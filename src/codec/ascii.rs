//! Modbus ASCII framing: `:` + the hex digits of `unit | PDU | LRC` + CR LF.
//!
//! Modbus over Serial Line V1.02, 2.5.2 (ASCII transmission mode: each byte sent as two
//! hex characters, upper case; a frame at most 513 characters; a `:` in mid-frame starts a
//! new frame, the one begun is dropped) and 6.2.1 (LRC: the two's complement of the 8-bit
//! sum of unit and PDU bytes). The LRC is one byte, sent as two hex characters.
//!
//! The unit | PDU inside a frame is the same as in RTU, so the PDU layer's rules (how long a
//! reply is, how it decodes: [`super::reply`]) read it as they read RTU's, with no CRC;
//! this module puts the hex text around it:
//!
//! - [`encode`] / [`encode_request`]: a whole frame to send;
//! - [`seen`] and [`complete`]: where the first frame in received characters begins and
//!   ends (the rules above, with no state: what a reader that keeps every character needs),
//!   and its `unit | PDU` once it has ended;
//! - [`reply_needed`], [`decode_reply`], [`unit_of`]: a reply read from such a buffer, the
//!   way [`super::Framing::reply_needed`] and [`super::Framing::decode_reply`] read RTU;
//! - [`Receiver`]: an incremental receiver that is fed characters and hands out each
//!   frame's `unit | PDU` (or why it was rejected), counting the characters outside frames.

pub use super::error::AsciiError;
use super::error::FrameError;
use super::pdu::Request;
use super::reply::{self, Needed, Reply, Trailer};
use std::time::Duration;

/// The character that begins a frame.
pub const START: u8 = b':';
/// The two characters that end a frame.
pub const END: [u8; 2] = *b"\r\n";
/// Longest frame, in characters: `:`, 255 bytes as hex (unit, 253 bytes of PDU, LRC), CR LF
/// (serial line spec 2.5.2.1).
pub const MAX_FRAME: usize = 513;
/// Longest `unit | PDU` a frame carries: the PDU layer's, [`reply::MAX_UNIT_PDU`].
pub const MAX_UNIT_PDU: usize = (MAX_FRAME - 1 - END.len()) / 2 - 1;
/// Shortest `unit | PDU` a frame carries: unit and function code.
const MIN_UNIT_PDU: usize = 2;
const _: () = assert!(MAX_UNIT_PDU == reply::MAX_UNIT_PDU);

/// The longest gap between two characters of an ASCII frame (serial line spec 2.5.2.1
/// allows up to one second). Unlike RTU, where a gap of t1.5 ends a frame, an ASCII frame
/// ends only at its CR LF; a reader may give up on a frame begun when no character came for
/// this long (see [`Receiver::abandon`]).
pub const INTER_CHAR_TIMEOUT: Duration = Duration::from_secs(1);

/// Data bits of the line in ASCII mode (serial line spec 2.5.2: 7; the default line format
/// is 7E1, even parity, and a line without parity has 2 stop bits, 7N2: 7N1 is not
/// allowed). See [`crate::timing::LineFormat::ascii`].
pub const DATA_BITS: u8 = 7;

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// The LRC of `bytes` (unit and PDU): the two's complement of their sum modulo 256 (serial
/// line spec 6.2.1).
pub fn lrc(bytes: &[u8]) -> u8 {
    bytes
        .iter()
        .fold(0u8, |sum, &b| sum.wrapping_add(b))
        .wrapping_neg()
}

/// The whole ASCII frame of `unit_pdu` (unit, then PDU): `:`, upper-case hex of the bytes
/// and of their LRC, CR LF. Any length is framed; a receiver takes at most
/// [`MAX_UNIT_PDU`] bytes (a [`Request`] never has more).
pub fn encode(unit_pdu: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(1 + 2 * (unit_pdu.len() + 1) + END.len());
    out.push(START);
    for &b in unit_pdu.iter().chain(&[lrc(unit_pdu)]) {
        out.push(HEX[usize::from(b >> 4)]);
        out.push(HEX[usize::from(b & 0x0F)]);
    }
    out.extend_from_slice(&END);
    out
}

/// The ASCII frame of `request` to `unit` (0: broadcast), as it goes to the wire.
pub fn encode_request(unit: u8, request: &Request) -> Vec<u8> {
    encode(&request.unit_pdu(unit))
}

/// The value of a hex digit, either case.
fn nibble(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'A'..=b'F' => Some(c - b'A' + 10),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    }
}

/// The bytes of the leading hex digit pairs of `digits` (a trailing odd digit is left out),
/// up to the first character that is not a hex digit.
fn leading_bytes(digits: &[u8]) -> Vec<u8> {
    digits
        .chunks_exact(2)
        .map_while(|pair| Some((nibble(pair[0])? << 4) | nibble(pair[1])?))
        .collect()
}

/// The `unit | PDU` of one whole ASCII `frame` (`:` ... CR LF, nothing before or after),
/// its hex digits in either case.
///
/// Checks, in order: the length (at most 513), the `:` and the CR LF, every character
/// between them a hex digit, an even number of them, at least 3 bytes (unit, function,
/// LRC), the LRC.
///
/// # Errors
/// [`AsciiError`] saying what is wrong.
pub fn decode(frame: &[u8]) -> Result<Vec<u8>, AsciiError> {
    if frame.len() > MAX_FRAME {
        return Err(AsciiError::TooLong(frame.len()));
    }
    let digits = match frame {
        [START, digits @ .., b'\r', b'\n'] => digits,
        _ => return Err(AsciiError::Incomplete(frame.len())),
    };
    if let Some(at) = digits.iter().position(|&c| nibble(c).is_none()) {
        return Err(AsciiError::BadChar {
            at: at + 1,
            byte: digits[at],
        });
    }
    if digits.len() % 2 != 0 {
        return Err(AsciiError::OddLength(digits.len()));
    }
    let mut bytes = leading_bytes(digits);
    if bytes.len() < MIN_UNIT_PDU + 1 {
        return Err(AsciiError::TooShort(bytes.len()));
    }
    let received = bytes.pop().unwrap_or_default();
    let computed = lrc(&bytes);
    if computed != received {
        return Err(AsciiError::Lrc { computed, received });
    }
    Ok(bytes)
}

/// Where the first frame in received characters is (see [`seen`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    /// No `:`: every character is noise.
    Nothing,
    /// A frame begins at `start` (its `:`) and has not ended yet.
    Begun {
        /// Index of its `:`.
        start: usize,
    },
    /// A frame from `start` (its `:`) up to `end` (exclusive: just past its LF).
    Ended {
        /// Index of its `:`.
        start: usize,
        /// Index just past its LF.
        end: usize,
    },
    /// The frame from `start` reached 513 characters without its CR LF: it is no frame.
    TooLong {
        /// Index of its `:`.
        start: usize,
    },
}

/// Where the first frame in `buf`, characters as received, begins and ends: at the first
/// `:` (what comes before is noise), restarted at each further `:` before its end, ended by
/// the first CR LF after it, and [`Seen::TooLong`] once 513 characters hold no end.
pub fn seen(buf: &[u8]) -> Seen {
    let Some(mut start) = buf.iter().position(|&c| c == START) else {
        return Seen::Nothing;
    };
    for (i, pair) in buf.windows(2).enumerate().skip(start) {
        let next = i + 1;
        match pair {
            [_, START] => {
                start = next;
                continue;
            }
            [b'\r', b'\n'] => {
                return Seen::Ended {
                    start,
                    end: next + 1,
                }
            }
            _ => {}
        }
        if next + 1 - start >= MAX_FRAME {
            return Seen::TooLong { start };
        }
    }
    Seen::Begun { start }
}

/// Whether `buf`, characters as received, holds a whole frame: once the first frame has
/// ended ([`seen`]), the index just past its LF and its `unit | PDU` ([`decode`]), or why it
/// was rejected; once it is too long, the index past its 513th character and
/// [`AsciiError::TooLong`]. None while no frame has ended.
pub fn complete(buf: &[u8]) -> Option<(usize, Result<Vec<u8>, AsciiError>)> {
    match seen(buf) {
        Seen::Ended { start, end } => Some((end, decode(&buf[start..end]))),
        Seen::TooLong { start } => Some((start + MAX_FRAME, Err(AsciiError::TooLong(MAX_FRAME)))),
        Seen::Nothing | Seen::Begun { .. } => None,
    }
}

/// The unit address of the frame begun in `buf` (its first two hex digits after the `:`),
/// once they have come: for a request frame, the unit it goes to; for a reply begun, the
/// unit it comes from.
pub fn unit_of(buf: &[u8]) -> Option<u8> {
    let start = match seen(buf) {
        Seen::Begun { start } | Seen::Ended { start, .. } | Seen::TooLong { start } => start,
        Seen::Nothing => return None,
    };
    leading_bytes(buf.get(start + 1..start + 3)?)
        .first()
        .copied()
}

/// How many more characters a reply to `request` needs, given the characters `buf`
/// received so far (noise before the `:` included): [`Needed::Complete`] with the index
/// just past the LF once the frame has ended; else [`Needed::More`] by the reply's length
/// as far as its `unit | PDU` tells it ([`reply::needed`]), and at least its LRC and CR
/// LF; [`Needed::Unknown`] once it is too long to be a frame.
///
/// Reading exactly the characters asked never reads past the end of the frame, which ends
/// at its CR LF whatever its length: a reply the PDU-level rules cannot size (another
/// function, a byte count the request does not call for) is still read to its end, two
/// characters at a time at least.
pub fn reply_needed(request: &Request, buf: &[u8]) -> Needed {
    needed_by(buf, |unit_pdu| {
        reply::needed(request, unit_pdu, Trailer::NONE)
    })
}

/// [`reply_needed`] with the `unit | PDU` lengths given by `pdu_needed`.
fn needed_by(buf: &[u8], pdu_needed: impl Fn(&[u8]) -> Needed) -> Needed {
    // The hex digits so far, and how many characters are still to come before them.
    let (digits, colon) = match seen(buf) {
        Seen::Ended { end, .. } => return Needed::Complete(end),
        Seen::TooLong { .. } => return Needed::Unknown,
        Seen::Nothing => (&buf[..0], 1),
        Seen::Begun { start } => {
            let body = &buf[start + 1..];
            match body.iter().position(|&c| nibble(c).is_none()) {
                None => (body, 0),
                // A CR at the end: its LF follows.
                Some(at) if at + 1 == body.len() && body[at] == b'\r' => return Needed::More(1),
                // Not a hex digit: the frame is bad, and ends at its CR LF.
                Some(_) => return Needed::More(END.len()),
            }
        }
    };
    let bytes = leading_bytes(digits);
    // How many bytes of unit | PDU | LRC the frame holds, as far as the PDU tells.
    let total = match pdu_needed(&bytes) {
        Needed::More(n) => bytes.len() + n + 1,
        Needed::Complete(n) => n + 1,
        _ => 0,
    };
    let digits_left = (2 * total).saturating_sub(digits.len());
    Needed::More(colon + digits_left.max(digits.len() % 2) + END.len())
}

/// Decodes the reply to `request` from `unit` in `buf`, characters as received: the first
/// frame in it ([`seen`]; noise before its `:` is skipped), its framing checked
/// ([`decode`]), then its `unit | PDU` ([`reply::decode`]).
///
/// # Errors
/// The framing's [`AsciiError`] (no whole frame in `buf` is [`AsciiError::Incomplete`],
/// one too long [`AsciiError::TooLong`]), or the reply's [`FrameError`]: `E` takes both
/// (the Bus's error for a bad reply).
pub fn decode_reply<E>(unit: u8, request: &Request, buf: &[u8]) -> Result<Reply, E>
where
    E: From<AsciiError> + From<FrameError>,
{
    let Some((_, unit_pdu)) = complete(buf) else {
        return Err(AsciiError::Incomplete(buf.len()).into());
    };
    let unit_pdu = unit_pdu?;
    Ok(reply::decode(unit, request, &unit_pdu, Trailer::NONE)?)
}

/// An incremental ASCII receiver: fed the characters of a line as they come, it hands out
/// the `unit | PDU` of each frame, or why the frame was rejected, and counts the characters
/// that belong to no frame (before a `:`, or in a frame cut off by a new `:` or given up).
///
/// It holds at most one frame's characters (513) between calls.
#[derive(Debug, Clone, Default)]
pub struct Receiver {
    /// Characters from the current frame's `:` on (or noise not yet looked at).
    pending: Vec<u8>,
    dropped: u64,
}

impl Receiver {
    /// A receiver waiting for a `:`.
    pub fn new() -> Receiver {
        Receiver::default()
    }

    /// Takes `chars` and returns, in order, each frame they end: its `unit | PDU`, or
    /// the [`AsciiError`] it was rejected for.
    pub fn feed(&mut self, chars: &[u8]) -> Vec<Result<Vec<u8>, AsciiError>> {
        self.pending.extend_from_slice(chars);
        let mut out = Vec::new();
        loop {
            match seen(&self.pending) {
                Seen::Nothing => {
                    self.drop_front(self.pending.len());
                    break;
                }
                Seen::Begun { start } => {
                    self.drop_front(start);
                    break;
                }
                Seen::Ended { start, end } => {
                    out.push(decode(&self.pending[start..end]));
                    self.drop_front(start);
                    self.pending.drain(..end - start);
                }
                Seen::TooLong { start } => {
                    out.push(Err(AsciiError::TooLong(MAX_FRAME)));
                    self.drop_front(start);
                    // What follows, up to the next `:`, is noise.
                    self.pending.drain(..MAX_FRAME.min(self.pending.len()));
                }
            }
        }
        out
    }

    /// Whether a frame has begun (its `:` came) and not ended: a caller that times the
    /// line calls [`Receiver::abandon`] when [`INTER_CHAR_TIMEOUT`] passes without a
    /// character meanwhile.
    pub fn in_frame(&self) -> bool {
        !self.pending.is_empty()
    }

    /// Gives up the frame begun, if any (its characters count as dropped), and waits for
    /// the next `:`.
    pub fn abandon(&mut self) {
        self.drop_front(self.pending.len());
    }

    /// Characters that belonged to no frame handed out, since the receiver was made.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    fn drop_front(&mut self, n: usize) {
        let n = n.min(self.pending.len());
        self.pending.drain(..n);
        self.dropped += n as u64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::pdu::Response;
    use crate::codec::rtu::BROADCAST;

    /// Read holding registers 0x006B..0x006D of unit 0x11 (the RTU example `11 03 00 6B 00
    /// 03`), in ASCII: 0x11 + 0x03 + 0x6B + 0x03 = 0x82, LRC 0x7E.
    const READ: &[u8] = b":1103006B00037E\r\n";
    /// Its reply, 0x022B, 0x0000, 0x0064: the sum 0xAB, LRC 0x55.
    const REPLY: &[u8] = b":110306022B0000006455\r\n";
    const READ_REQ: Request = Request::ReadHoldingRegisters {
        address: 0x6B,
        count: 3,
    };

    /// Both errors a reply may have, for [`decode_reply`].
    #[derive(Debug, PartialEq)]
    enum Bad {
        Ascii(AsciiError),
        Frame(FrameError),
    }
    impl From<AsciiError> for Bad {
        fn from(e: AsciiError) -> Bad {
            Bad::Ascii(e)
        }
    }
    impl From<FrameError> for Bad {
        fn from(e: FrameError) -> Bad {
            Bad::Frame(e)
        }
    }

    #[test]
    fn lrc_is_the_twos_complement_of_the_byte_sum() {
        assert_eq!(lrc(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]), 0x7E);
        assert_eq!(lrc(&[]), 0);
        assert_eq!(lrc(&[0x01]), 0xFF);
        // The sum wraps: 0xFF + 0x02 = 0x101 -> 0x01 -> 0xFF.
        assert_eq!(lrc(&[0xFF, 0x02]), 0xFF);
        assert_eq!(lrc(&[0x80, 0x80]), 0x00);
    }

    #[test]
    fn encode_is_colon_upper_case_hex_lrc_cr_lf() {
        assert_eq!(encode(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]), READ);
        assert_eq!(encode_request(0x11, &READ_REQ), READ);
        let write = Request::WriteSingleRegister {
            address: 0xABCD,
            value: 0xEF01,
        };
        // 0x11 + 0x06 + 0xAB + 0xCD + 0xEF + 0x01 = 0x27F -> 0x7F, LRC 0x81.
        assert_eq!(encode_request(0x11, &write), b":1106ABCDEF0181\r\n");
        assert_eq!(encode_request(BROADCAST, &write)[..5], *b":0006");
    }

    #[test]
    fn decode_takes_either_case_and_checks_the_lrc() {
        let unit_pdu = vec![0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64];
        assert_eq!(decode(REPLY), Ok(unit_pdu.clone()));
        assert_eq!(decode(b":110306022b0000006455\r\n"), Ok(unit_pdu));
        assert_eq!(
            decode(b":110306022B0000006456\r\n"),
            Err(AsciiError::Lrc {
                computed: 0x55,
                received: 0x56
            })
        );
    }

    #[test]
    fn decode_names_each_fault() {
        assert_eq!(
            decode(b":1103006G00037E\r\n"),
            Err(AsciiError::BadChar { at: 8, byte: b'G' })
        );
        assert_eq!(
            decode(b":1103 06B00037E\r\n"),
            Err(AsciiError::BadChar { at: 5, byte: b' ' })
        );
        // A CR inside, or a lone LF: not hex digits.
        assert_eq!(
            decode(b":11\r3006B00037E\r\n"),
            Err(AsciiError::BadChar { at: 3, byte: b'\r' })
        );
        assert_eq!(
            decode(b":1103006B00037\r\n"),
            Err(AsciiError::OddLength(13))
        );
        assert_eq!(decode(b":1183\r\n"), Err(AsciiError::TooShort(2)));
        assert_eq!(decode(b":\r\n"), Err(AsciiError::TooShort(0)));
        assert_eq!(
            decode(b"1103006B00037E\r\n"),
            Err(AsciiError::Incomplete(16))
        );
        assert_eq!(
            decode(b":1103006B00037E\r"),
            Err(AsciiError::Incomplete(16))
        );
        assert_eq!(
            decode(b":1103006B00037E\n"),
            Err(AsciiError::Incomplete(16))
        );
        assert_eq!(decode(b""), Err(AsciiError::Incomplete(0)));
        let long = encode(&[0u8; MAX_UNIT_PDU + 1]);
        assert_eq!(long.len(), MAX_FRAME + 2);
        assert_eq!(decode(&long), Err(AsciiError::TooLong(MAX_FRAME + 2)));
        assert_eq!(
            AsciiError::Lrc {
                computed: 0x7E,
                received: 0x7F
            }
            .to_string(),
            "LRC mismatch: computed 0x7e, received 0x7f"
        );
    }

    #[test]
    fn the_longest_frame_is_513_characters() {
        let most = [0xA5u8; MAX_UNIT_PDU];
        let frame = encode(&most);
        assert_eq!(frame.len(), MAX_FRAME);
        assert_eq!(decode(&frame), Ok(most.to_vec()));
        assert_eq!(
            seen(&frame),
            Seen::Ended {
                start: 0,
                end: MAX_FRAME
            }
        );
        // One character more without the end: no frame.
        let mut long = frame[..MAX_FRAME - 2].to_vec();
        long.extend_from_slice(b"00");
        assert_eq!(seen(&long[..MAX_FRAME - 1]), Seen::Begun { start: 0 });
        assert_eq!(seen(&long), Seen::TooLong { start: 0 });
    }

    #[test]
    fn seen_skips_noise_restarts_at_a_colon_and_ends_at_cr_lf() {
        assert_eq!(seen(b""), Seen::Nothing);
        assert_eq!(seen(b"\x00\xFF12\r\n"), Seen::Nothing);
        assert_eq!(seen(b"xx:1103"), Seen::Begun { start: 2 });
        assert_eq!(seen(b"xx:11\r"), Seen::Begun { start: 2 });
        assert_eq!(seen(b":11\n\r"), Seen::Begun { start: 0 });
        // A new `:` in mid-frame starts the frame again.
        assert_eq!(seen(b":1103:11"), Seen::Begun { start: 5 });
        let mut cut = b":1103".to_vec();
        cut.extend_from_slice(READ);
        cut.extend_from_slice(b":rest");
        assert_eq!(
            seen(&cut),
            Seen::Ended {
                start: 5,
                end: 5 + READ.len()
            }
        );
        // A `:` between CR and LF, too.
        assert_eq!(seen(b":11\r:22\r\n"), Seen::Ended { start: 4, end: 9 });
    }

    #[test]
    fn complete_once_the_first_frame_has_ended() {
        assert_eq!(complete(b""), None);
        assert_eq!(complete(b"xx:1103006B"), None);
        let mut two = b"x".to_vec();
        two.extend_from_slice(READ);
        two.extend_from_slice(REPLY);
        assert_eq!(complete(&two), Some((1 + READ.len(), decode(READ))));
        assert_eq!(
            complete(b"::1183\r\n"),
            Some((8, Err(AsciiError::TooShort(2))))
        );
        let mut long = b"~:".to_vec();
        long.extend(std::iter::repeat_n(b'0', MAX_FRAME));
        assert_eq!(
            complete(&long),
            Some((1 + MAX_FRAME, Err(AsciiError::TooLong(MAX_FRAME))))
        );
    }

    #[test]
    fn unit_of_the_frame_begun() {
        assert_eq!(unit_of(READ), Some(0x11));
        assert_eq!(unit_of(b"noise:f7"), Some(0xF7));
        assert_eq!(unit_of(b":1"), None);
        assert_eq!(unit_of(b":G1"), None);
        assert_eq!(unit_of(b"11"), None);
    }

    #[test]
    fn receiver_hands_out_frames_and_counts_noise() {
        let mut rx = Receiver::new();
        assert!(rx.feed(b"\x00junk").is_empty());
        assert_eq!(rx.dropped(), 5);
        assert!(!rx.in_frame());
        // One character at a time.
        for &c in &READ[..READ.len() - 1] {
            assert!(rx.feed(&[c]).is_empty());
            assert!(rx.in_frame());
        }
        assert_eq!(
            rx.feed(b"\n"),
            [Ok(vec![0x11, 0x03, 0x00, 0x6B, 0x00, 0x03])]
        );
        assert!(!rx.in_frame());
        // Two frames and a bad one in one go; a frame cut off by a new `:` is dropped.
        let mut all = b":0102".to_vec();
        all.extend_from_slice(READ);
        all.extend_from_slice(b"--");
        all.extend_from_slice(b":1103006B00037F\r\n");
        all.extend_from_slice(REPLY);
        all.extend_from_slice(b":01");
        let got = rx.feed(&all);
        assert_eq!(got.len(), 3);
        assert_eq!(got[0], decode(READ));
        assert_eq!(
            got[1],
            Err(AsciiError::Lrc {
                computed: 0x7E,
                received: 0x7F
            })
        );
        assert_eq!(got[2], decode(REPLY));
        assert_eq!(rx.dropped(), 5 + 5 + 2);
        assert!(rx.in_frame());
        // Given up after the inter-character timeout: counted as dropped.
        rx.abandon();
        assert!(!rx.in_frame());
        assert_eq!(rx.dropped(), 5 + 5 + 2 + 3);
    }

    #[test]
    fn receiver_rejects_a_frame_too_long_and_finds_the_next() {
        let mut rx = Receiver::new();
        let mut chars = vec![START];
        chars.extend(std::iter::repeat_n(b'0', 600));
        assert_eq!(rx.feed(&chars), [Err(AsciiError::TooLong(MAX_FRAME))]);
        // Nothing kept past the limit: the rest is noise until the next `:`.
        assert!(!rx.in_frame());
        assert_eq!(rx.dropped(), 601 - MAX_FRAME as u64);
        assert_eq!(rx.feed(REPLY), [decode(REPLY)]);
        assert_eq!(rx.dropped(), 601 - MAX_FRAME as u64);
    }

    #[test]
    fn reply_needed_reads_to_the_cr_lf_and_never_past_it() {
        let exception = encode(&[0x11, 0x83, 0x02]);
        assert_eq!(exception, b":1183026A\r\n");
        for frame in [REPLY, &exception[..]] {
            for i in 0..frame.len() {
                match reply_needed(&READ_REQ, &frame[..i]) {
                    Needed::More(n) => assert!(n > 0 && i + n <= frame.len(), "{i}: {n}"),
                    other => panic!("{i}: {other:?}"),
                }
            }
            assert_eq!(
                reply_needed(&READ_REQ, frame),
                Needed::Complete(frame.len())
            );
        }
        // Exactly: once the byte count is in, the rest is known.
        assert_eq!(reply_needed(&READ_REQ, &REPLY[..7]), Needed::More(16));
        assert_eq!(reply_needed(&READ_REQ, b""), Needed::More(11));
        assert_eq!(reply_needed(&READ_REQ, b"noise"), Needed::More(11));
        // Noise before the frame is part of the buffer the end is counted in.
        let mut noisy = b"~~".to_vec();
        noisy.extend_from_slice(REPLY);
        assert_eq!(
            reply_needed(&READ_REQ, &noisy),
            Needed::Complete(noisy.len())
        );
    }

    #[test]
    fn a_reply_the_pdu_cannot_size_is_read_to_its_end() {
        // Another function code: RTU would read until the line is quiet; ASCII has its end.
        let other = encode(&[0x11, 0x04, 0x02, 0x00, 0x01]);
        for i in 5..other.len() {
            let Needed::More(n) = reply_needed(&READ_REQ, &other[..i]) else {
                panic!("{i}");
            };
            assert!(i + n <= other.len(), "{i}: {n}");
        }
        assert_eq!(
            reply_needed(&READ_REQ, &other),
            Needed::Complete(other.len())
        );
        // A bad character: only the CR LF is still to come.
        assert_eq!(reply_needed(&READ_REQ, b":11 "), Needed::More(2));
        assert_eq!(reply_needed(&READ_REQ, b":1103\r"), Needed::More(1));
        // Longer than its PDU says: it ends at its CR LF.
        assert_eq!(
            reply_needed(&READ_REQ, b":110306022B000000645500"),
            Needed::More(2)
        );
        let mut long = vec![START];
        long.extend(std::iter::repeat_n(b'0', MAX_FRAME));
        assert_eq!(reply_needed(&READ_REQ, &long), Needed::Unknown);
    }

    #[test]
    fn decode_reply_checks_the_frame_then_the_pdu() {
        assert_eq!(
            decode_reply::<Bad>(0x11, &READ_REQ, REPLY),
            Ok(Reply::Normal(Response::Registers(vec![0x022B, 0, 0x64])))
        );
        let mut noisy = b"\x00".to_vec();
        noisy.extend_from_slice(REPLY);
        assert!(decode_reply::<Bad>(0x11, &READ_REQ, &noisy).is_ok());
        assert_eq!(
            decode_reply::<Bad>(0x11, &READ_REQ, b":1183026A\r\n"),
            Ok(Reply::Exception {
                function: 0x03,
                code: 0x02
            })
        );
        assert_eq!(
            decode_reply::<Bad>(0x12, &READ_REQ, REPLY),
            Err(Bad::Frame(FrameError::WrongUnit {
                expected: 0x12,
                received: 0x11
            }))
        );
        assert_eq!(
            decode_reply::<Bad>(0x11, &READ_REQ, b":110306022B0000006456\r\n"),
            Err(Bad::Ascii(AsciiError::Lrc {
                computed: 0x55,
                received: 0x56
            }))
        );
        assert_eq!(
            decode_reply::<Bad>(0x11, &READ_REQ, &REPLY[..10]),
            Err(Bad::Ascii(AsciiError::Incomplete(10)))
        );
    }
}
