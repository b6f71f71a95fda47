//! Why the codec rejects a frame, and how it shows one: the leaf the rest of the codec, and
//! the crate's own error type, build on.
//!
//! [`FrameError`] is every reason a reply is refused: the PDU layer's ([`super::reply`]:
//! another unit, another function, a length or an echo the request does not call for), the
//! framings' (an RTU frame's CRC, a Modbus ASCII frame's characters and LRC, which
//! [`AsciiError`] tells), and the Bus's (a garbled local echo, a reply too soon).

/// Why a reply frame was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Fewer bytes than the shortest reply.
    #[error("reply too short ({0} bytes)")]
    TooShort(usize),
    /// The CRC does not match the frame's contents.
    #[error("CRC mismatch: computed {computed:#06x}, received {received:#06x}")]
    Crc {
        /// CRC computed over the frame.
        computed: u16,
        /// CRC carried by the frame.
        received: u16,
    },
    /// The reply came from another unit.
    #[error("reply from unit {received}, expected {expected}")]
    WrongUnit {
        /// Unit asked.
        expected: u8,
        /// Unit in the reply.
        received: u8,
    },
    /// The reply carries another function code.
    #[error("reply function {received:#04x}, expected {expected:#04x}")]
    WrongFunction {
        /// Function asked.
        expected: u8,
        /// Function in the reply.
        received: u8,
    },
    /// The reply's byte count or length does not fit the request.
    #[error("reply length wrong: {0}")]
    Length(String),
    /// The byte count of a read reply from the addressed unit disagrees with the count the
    /// request asked for (known from the reply's third byte, before the rest arrives).
    #[error("reply byte count {received}, but the request asked for {expected} bytes")]
    ByteCount {
        /// Data bytes the request's count calls for.
        expected: usize,
        /// Byte count the reply carries.
        received: u8,
    },
    /// A write reply does not echo the request.
    #[error("write not echoed: sent {sent}, reply carries {received}")]
    Echo {
        /// What the request carried (address, value or count).
        sent: String,
        /// What the reply carried.
        received: String,
    },
    /// The adapter's local echo of the request (a Bus opened with `echo`) is wrong from
    /// byte `at` on, or broke off there: another talker on the line (a collision), or
    /// noise.
    #[error(
        "local echo of the request is wrong from byte {at} of {len} (a collision on the \
         line, or noise)"
    )]
    LocalEcho {
        /// Index of the first byte missing or different.
        at: usize,
        /// Length of the request.
        len: usize,
    },
    /// What came back begins with the request itself: the adapter echoes what it sends, and
    /// the Bus was not told so.
    #[error(
        "the reply begins with the request itself: an adapter that echoes what it sends? \
         then open the Bus with echo=True"
    )]
    UnexpectedEcho,
    /// A frame of the addressed unit came sooner after the request than the unit answers
    /// (a copy of an earlier reply, or an earlier request's answer come late), was dropped,
    /// and no other followed within the attempt.
    #[error(
        "a reply came {after:?} after the request began, sooner than this unit answers \
         ({usual:?} lately): a copy of an earlier reply or an earlier request's answer, not \
         taken, and no other reply followed"
    )]
    TooSoon {
        /// When the frame began on the wire at the latest (reckoned from the bytes of its
        /// first read), from the start of the request.
        after: std::time::Duration,
        /// The unit's least time lately, from the start of a request to its reply.
        usual: std::time::Duration,
    },
    /// A Modbus ASCII frame is malformed: a character, its length or its LRC.
    #[error(transparent)]
    Ascii(#[from] AsciiError),
}

/// Why an ASCII frame was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AsciiError {
    /// A character between `:` and CR LF that is not a hex digit.
    #[error("character {byte:#04x} at {at} of an ASCII frame is not a hex digit")]
    BadChar {
        /// Its index in the frame (the `:` is 0).
        at: usize,
        /// The character.
        byte: u8,
    },
    /// An odd number of hex digits: the last byte is cut in half.
    #[error("ASCII frame with an odd number of hex digits ({0})")]
    OddLength(usize),
    /// The LRC does not match the frame's contents.
    #[error("LRC mismatch: computed {computed:#04x}, received {received:#04x}")]
    Lrc {
        /// LRC computed over unit and PDU.
        computed: u8,
        /// LRC carried by the frame.
        received: u8,
    },
    /// A frame of this many characters without its end, over the longest (513).
    #[error("ASCII frame of {0} characters without its end (513 at most)")]
    TooLong(usize),
    /// Fewer bytes than a unit, a function code and the LRC.
    #[error("ASCII frame too short: {0} bytes with the LRC, 3 at least")]
    TooShort(usize),
    /// No whole frame (`:` to CR LF) in these characters.
    #[error("no complete ASCII frame (':' to CR LF) in {0} characters")]
    Incomplete(usize),
}

/// Bytes as space-separated uppercase hex, the way the manuals print frames.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02X}"));
    }
    s
}

/// The bytes of hex text as [`hex`] writes it (a frame of a manual, in a test).
#[cfg(test)]
pub(crate) fn unhex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}
