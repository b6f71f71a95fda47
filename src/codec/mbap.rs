//! The Modbus TCP application data unit: `MBAP header | PDU`, and a sans-IO session that
//! carries the Bus's requests and replies over it.
//!
//! MODBUS Messaging on TCP/IP Implementation Guide V1.0b, 3.1.3 (MBAP header: transaction
//! id, protocol id 0, length = the bytes that follow it, unit id; 7 bytes).
//!
//! The Bus builds requests as `unit | PDU` plus the framing's trailer
//! ([`super::Framing`]): over Modbus TCP there is no trailer, TCP checks the bytes. A
//! [`Session`] is what sits between those and the bytes of a Modbus TCP connection: a
//! request gets an MBAP header (the next transaction id) in front; received bytes are cut
//! into whole MBAP frames, only the reply to the awaited transaction is kept, and it is
//! handed back from its length field on, `length | unit | PDU` (the transaction and protocol
//! ids are the session's business). The Bus reads that by its length ([`reply_needed`]), so
//! a frame is always taken whole, and [`decode_reply`] checks that the length counts exactly
//! the reply the request calls for. Like the rest of the codec it touches no port and no
//! clock.

use super::error::FrameError;
use super::pdu::Request;
use super::reply::{self, Needed, Reply, Trailer, MAX_UNIT_PDU};
use std::collections::VecDeque;
use std::ops::RangeInclusive;

/// The transaction id of the first request on a Modbus TCP connection; each request after
/// it takes the next (wrapping after 65535).
pub const FIRST_TRANSACTION_ID: u16 = 1;

/// MBAP header bytes before the length field's count starts: transaction id, protocol id,
/// length.
pub const PREFIX: usize = 6;

/// The MBAP length field's sane range: unit id + function code at least, unit id + the
/// longest PDU (253 bytes) at most.
pub const LENGTH: RangeInclusive<usize> = 2..=MAX_UNIT_PDU;

/// The Modbus protocol id (any other is another protocol on the same port).
pub const MODBUS_PROTOCOL: u16 = 0;

/// Exception 0x06, server device busy (MODBUS Application Protocol V1.1b3, 7).
pub const SERVER_DEVICE_BUSY: u8 = 0x06;

/// What the benchbus gateway means by [`SERVER_DEVICE_BUSY`]: it answers a client's first
/// request with it when every client slot is taken, then closes the connection.
pub const GATEWAY_FULL: &str = "a benchbus gateway answers this when all its client slots \
     are taken; try again later or raise --max-clients";

/// The meaning of exception `code` received over Modbus TCP, given what the device's family
/// makes of it (`meaning`): a 0x06 may come from the device, or from a benchbus gateway
/// with no client slot free, so its meaning names both ([`GATEWAY_FULL`]).
pub fn exception_meaning(code: u8, meaning: &str) -> String {
    if code == SERVER_DEVICE_BUSY {
        format!("{meaning} ({GATEWAY_FULL})")
    } else {
        meaning.to_string()
    }
}

/// The MBAP frame of transaction `tid` carrying `adu` (unit id + PDU, of a length in
/// [`LENGTH`]): transaction id, protocol id 0, length, then `adu`.
pub fn encode(tid: u16, adu: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(PREFIX + adu.len());
    out.extend_from_slice(&tid.to_be_bytes());
    out.extend_from_slice(&MODBUS_PROTOCOL.to_be_bytes());
    out.extend_from_slice(&(adu.len() as u16).to_be_bytes());
    out.extend_from_slice(adu);
    out
}

/// Bytes of the length field, which begins a reply as the Bus reads it (`length | unit |
/// PDU`).
pub const LENGTH_FIELD: usize = 2;

/// How many more bytes a reply needs, given the bytes `buf` of it received so far, as a
/// [`Session`] hands them out: `length | unit | PDU`. The length field alone tells:
/// [`Needed::More`] until it and the bytes it counts have come, then [`Needed::Complete`];
/// [`Needed::Unknown`] for a length outside [`LENGTH`] (which a session never hands out).
pub fn reply_needed(buf: &[u8]) -> Needed {
    let Some((field, _)) = buf.split_first_chunk::<LENGTH_FIELD>() else {
        return Needed::More(LENGTH_FIELD - buf.len());
    };
    let length = usize::from(u16::from_be_bytes(*field));
    if !LENGTH.contains(&length) {
        return Needed::Unknown;
    }
    let total = LENGTH_FIELD + length;
    match total.checked_sub(buf.len()) {
        Some(more) if more > 0 => Needed::More(more),
        _ => Needed::Complete(total),
    }
}

/// Decodes a complete reply `frame` (`length | unit | PDU`, as [`reply_needed`] measured it)
/// to `request` sent to `unit`: its `unit | PDU` is checked by the PDU layer (unit,
/// function, byte count, length, in [`reply::decode`]'s order), and its length must count
/// exactly the bytes that reply has. A raw request's reply of no known length
/// ([`Request::Raw`] without `reply_length`) is all the length counts.
///
/// # Errors
/// [`FrameError`] saying what is wrong: [`FrameError::Length`] for a length that counts more
/// bytes than the reply has (the extra bytes are never taken for part of it) or fewer.
pub fn decode_reply(unit: u8, request: &Request, frame: &[u8]) -> Result<Reply, FrameError> {
    let Some((field, unit_pdu)) = frame.split_first_chunk::<LENGTH_FIELD>() else {
        return Err(FrameError::TooShort(frame.len()));
    };
    let length = usize::from(u16::from_be_bytes(*field));
    if unit_pdu.len() != length {
        return Err(FrameError::Length(format!(
            "MBAP length {length}, but {} bytes follow it",
            unit_pdu.len()
        )));
    }
    match reply::needed(request, unit_pdu, Trailer::NONE) {
        // The reply ends before the bytes the length counts do: what is wrong within it is
        // told first (another unit, a byte count...), else the length.
        Needed::Complete(whole) if whole < length => {
            reply::decode(
                unit,
                request,
                unit_pdu.get(..whole).unwrap_or(unit_pdu),
                Trailer::NONE,
            )?;
            let extra = length - whole;
            Err(FrameError::Length(format!(
                "MBAP length {length} counts {extra} byte{} more than the reply to function \
                 {:#04x} has (unit + PDU: {whole} bytes)",
                if extra == 1 { "" } else { "s" },
                request.function()
            )))
        }
        // The same length, one too short (the decoder says what is missing), or a reply of
        // no known length: its checks tell.
        _ => reply::decode(unit, request, unit_pdu, Trailer::NONE),
    }
}

/// A whole MBAP frame taken apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Transaction id.
    pub tid: u16,
    /// Protocol id (0 for Modbus).
    pub protocol: u16,
    /// Unit id + PDU (the length field's count).
    pub adu: &'a [u8],
}

/// How long the MBAP frame at the start of `buf` is, once its header's length field has
/// arrived: `Ok(None)` before that.
///
/// # Errors
/// The length field's value, if it is outside [`LENGTH`]: the stream is out of step (or not
/// Modbus TCP at all), and there is no telling where the next frame starts.
pub fn frame_len(buf: &[u8]) -> Result<Option<usize>, usize> {
    let length = match buf {
        [_, _, _, _, hi, lo, ..] => usize::from(u16::from_be_bytes([*hi, *lo])),
        _ => return Ok(None),
    };
    if LENGTH.contains(&length) {
        Ok(Some(PREFIX + length))
    } else {
        Err(length)
    }
}

/// `frame`, one whole MBAP frame (as [`frame_len`] measured it), taken apart; None for
/// fewer bytes than a header.
pub fn decode(frame: &[u8]) -> Option<Frame<'_>> {
    let [t0, t1, p0, p1, _, _, adu @ ..] = frame else {
        return None;
    };
    Some(Frame {
        tid: u16::from_be_bytes([*t0, *t1]),
        protocol: u16::from_be_bytes([*p0, *p1]),
        adu,
    })
}

/// A frame a [`Session`] dropped, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Dropped {
    /// A frame of another protocol than Modbus.
    Protocol {
        /// Its protocol id.
        protocol: u16,
        /// The whole frame.
        frame: Vec<u8>,
    },
    /// A reply to a transaction other than the awaited one (a late reply), or one that came
    /// when no reply was awaited.
    Late {
        /// Its transaction id.
        tid: u16,
        /// The transaction awaited, if any.
        awaited: Option<u16>,
        /// The whole frame.
        frame: Vec<u8>,
    },
}

/// Modbus TCP on one connection, as the Bus's RTU frames see it (see the module docs).
#[derive(Debug)]
pub struct Session {
    /// The transaction id of the next request.
    next_tid: u16,
    /// The transaction id of the request whose reply is awaited: the last one written, until
    /// it is answered (or the input is discarded before the next request).
    awaited: Option<u16>,
    /// Bytes received that do not yet make a whole MBAP frame.
    raw: Vec<u8>,
    /// The awaited reply's `length | unit | PDU`, as much of it as has not been read yet.
    ready: VecDeque<u8>,
    /// Bytes of frames dropped (late replies, other protocols) since last asked.
    dropped: u64,
}

impl Default for Session {
    fn default() -> Self {
        Session::new()
    }
}

impl Session {
    /// A new connection's session: [`FIRST_TRANSACTION_ID`] comes next, nothing is awaited.
    pub fn new() -> Session {
        Session {
            next_tid: FIRST_TRANSACTION_ID,
            awaited: None,
            raw: Vec::new(),
            ready: VecDeque::new(),
            dropped: 0,
        }
    }

    /// The MBAP frame for `unit | PDU` (`adu`); the next transaction id is used up and
    /// awaited. A broadcast (unit 0) goes like any request. None, and nothing used up, for an
    /// `adu` whose length is outside [`LENGTH`].
    pub fn request(&mut self, adu: &[u8]) -> Option<Vec<u8>> {
        if !LENGTH.contains(&adu.len()) {
            return None;
        }
        let tid = self.next_tid;
        self.next_tid = tid.wrapping_add(1);
        self.awaited = Some(tid);
        Some(encode(tid, adu))
    }

    /// The MBAP frame that carries `frame` as it crossed the connection: a request (`sent`),
    /// `unit | PDU`, under the next transaction id (None for a length outside [`LENGTH`]); a
    /// reply as the session handed it out, `length | unit | PDU`, under the last request's.
    pub fn shown(&self, frame: &[u8], sent: bool) -> Option<Vec<u8>> {
        if sent {
            return LENGTH
                .contains(&frame.len())
                .then(|| encode(self.next_tid, frame));
        }
        let mut out = Vec::with_capacity(PREFIX - LENGTH_FIELD + frame.len());
        out.extend_from_slice(&self.next_tid.wrapping_sub(1).to_be_bytes());
        out.extend_from_slice(&MODBUS_PROTOCOL.to_be_bytes());
        out.extend_from_slice(frame);
        Some(out)
    }

    /// Takes bytes received from the connection.
    pub fn receive(&mut self, bytes: &[u8]) {
        self.raw.extend_from_slice(bytes);
    }

    /// Cuts what was received into whole frames: the awaited reply's unit + PDU is kept for
    /// [`Session::read`]; anything else is dropped and returned, for the log.
    ///
    /// # Errors
    /// The out-of-range length of a header ([`frame_len`]): the stream is out of step, and
    /// what was buffered is dropped. The first bytes received are returned with it.
    pub fn take_frames(&mut self) -> Result<Vec<Dropped>, (usize, Vec<u8>)> {
        let mut dropped = Vec::new();
        while let Some(frame) = self.next_frame()? {
            dropped.extend(self.accept(&frame));
        }
        Ok(dropped)
    }

    /// Copies the awaited reply's next bytes (`length | unit | PDU`) into `buf`: how many (0
    /// if none are ready).
    pub fn read(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.ready.len());
        for (slot, byte) in buf.iter_mut().zip(self.ready.drain(..n)) {
            *slot = byte;
        }
        n
    }

    /// Drops everything received before a request and returns it: the awaited reply's
    /// unread rest, then every whole frame waiting (`received`, just taken from the
    /// connection, first added). A frame's beginning stays: its rest is on its way, and
    /// without it the stream is out of step. Whatever answers an earlier request from now
    /// on is late.
    ///
    /// # Errors
    /// As [`Session::take_frames`].
    pub fn discard(&mut self, received: &[u8]) -> Result<Vec<u8>, (usize, Vec<u8>)> {
        let mut stale: Vec<u8> = self.ready.drain(..).collect();
        self.receive(received);
        while let Some(frame) = self.next_frame()? {
            stale.extend_from_slice(&frame);
        }
        self.awaited = None;
        Ok(stale)
    }

    /// How many bytes of frames were dropped (late replies, other protocols) since last
    /// asked.
    pub fn take_dropped(&mut self) -> u64 {
        std::mem::take(&mut self.dropped)
    }

    /// The next whole MBAP frame received, taken out; None while it is incomplete.
    fn next_frame(&mut self) -> Result<Option<Vec<u8>>, (usize, Vec<u8>)> {
        let total = match frame_len(&self.raw) {
            Ok(Some(total)) => total,
            Ok(None) => return Ok(None),
            Err(length) => {
                let seen = self.raw[..self.raw.len().min(16)].to_vec();
                self.raw.clear();
                self.ready.clear();
                return Err((length, seen));
            }
        };
        if self.raw.len() < total {
            return Ok(None);
        }
        let rest = self.raw.split_off(total);
        Ok(Some(std::mem::replace(&mut self.raw, rest)))
    }

    /// Takes a whole MBAP frame: the awaited reply goes to `ready` from its length field on
    /// (`length | unit | PDU`); anything else is dropped (and returned).
    fn accept(&mut self, frame: &[u8]) -> Option<Dropped> {
        let header = decode(frame)?;
        if header.protocol != MODBUS_PROTOCOL {
            self.dropped += frame.len() as u64;
            return Some(Dropped::Protocol {
                protocol: header.protocol,
                frame: frame.to_vec(),
            });
        }
        if self.awaited != Some(header.tid) {
            self.dropped += frame.len() as u64;
            return Some(Dropped::Late {
                tid: header.tid,
                awaited: self.awaited,
                frame: frame.to_vec(),
            });
        }
        self.awaited = None;
        self.ready
            .extend(frame.get(PREFIX - LENGTH_FIELD..).unwrap_or_default());
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Read holding registers of unit 1, 0x0000, 1 register: unit + PDU.
    const READ: [u8; 6] = [0x01, 0x03, 0x00, 0x00, 0x00, 0x01];

    /// The same request over Modbus TCP, transaction 1:
    /// tid 00 01 | protocol 00 00 | length 00 06 | unit 01 | PDU 03 00 00 00 01.
    const MBAP_READ: [u8; 12] = [
        0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, 0x01,
    ];

    /// Its reply (value 0x1234), transaction 1: length 5 = unit + 03 02 12 34.
    const MBAP_REPLY: [u8; 11] = [
        0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x01, 0x03, 0x02, 0x12, 0x34,
    ];

    /// A session that has sent `READ` (transaction 1) and awaits its reply.
    fn awaiting() -> Session {
        let mut s = Session::new();
        s.request(&READ).unwrap();
        s
    }

    fn read_all(s: &mut Session) -> Vec<u8> {
        let mut buf = [0u8; 300];
        let n = s.read(&mut buf);
        buf[..n].to_vec()
    }

    #[test]
    fn encode_is_golden() {
        assert_eq!(encode(1, &READ[..6]), MBAP_READ);
        assert_eq!(
            encode(0xBEEF, &[0x00, 0x06, 0x00, 0x01, 0x00, 0x02]),
            [0xBE, 0xEF, 0, 0, 0, 6, 0x00, 0x06, 0x00, 0x01, 0x00, 0x02]
        );
    }

    #[test]
    fn frame_len_reads_the_header_and_refuses_insane_lengths() {
        assert_eq!(frame_len(&MBAP_READ[..5]), Ok(None));
        assert_eq!(frame_len(&MBAP_READ[..6]), Ok(Some(12)));
        assert_eq!(frame_len(&MBAP_READ), Ok(Some(12)));
        assert_eq!(frame_len(&[0, 1, 0, 0, 0, 1]), Err(1));
        assert_eq!(frame_len(&[0, 1, 0, 0, 0, 255]), Err(255));
        assert_eq!(frame_len(&[0, 1, 0, 0, 0, 254]), Ok(Some(260)));
    }

    #[test]
    fn decode_takes_the_header_apart() {
        assert_eq!(
            decode(&MBAP_REPLY),
            Some(Frame {
                tid: 1,
                protocol: 0,
                adu: &MBAP_REPLY[6..],
            })
        );
        assert_eq!(decode(&MBAP_REPLY[..5]), None);
    }

    #[test]
    fn requests_get_a_header_and_count_transaction_ids_up() {
        let mut s = Session::new();
        assert_eq!(s.shown(&READ, true).as_deref(), Some(&MBAP_READ[..]));
        assert_eq!(s.request(&READ).as_deref(), Some(&MBAP_READ[..]));
        // As a reply (from its length field on), the shown frame takes the last request's id.
        assert_eq!(
            s.shown(&MBAP_REPLY[4..], false).as_deref(),
            Some(&MBAP_REPLY[..])
        );
        let second = s.request(&READ).unwrap();
        assert_eq!(&second[..2], &[0x00, 0x02]);
        // Unit + function code at least, unit + the longest PDU at most.
        assert_eq!(s.request(&[0x01]), None);
        assert_eq!(s.request(&[0x01; 255]), None);
        assert!(s.shown(&[0x01; 255], true).is_none());
        // Refused frames use no id up.
        assert_eq!(&s.request(&READ).unwrap()[..2], &[0x00, 0x03]);
    }

    #[test]
    fn transaction_ids_wrap() {
        let mut s = Session::new();
        s.next_tid = u16::MAX;
        assert_eq!(&s.request(&READ).unwrap()[..2], &[0xFF, 0xFF]);
        assert_eq!(&s.request(&READ).unwrap()[..2], &[0x00, 0x00]);
    }

    #[test]
    fn the_awaited_reply_comes_back_from_its_length_on_in_pieces() {
        let mut s = awaiting();
        s.receive(&MBAP_REPLY[..4]);
        assert_eq!(s.take_frames(), Ok(vec![]));
        assert_eq!(read_all(&mut s), Vec::<u8>::new());
        s.receive(&MBAP_REPLY[4..]);
        assert_eq!(s.take_frames(), Ok(vec![]));
        let mut two = [0u8; 2];
        assert_eq!(s.read(&mut two), 2);
        assert_eq!(two, [0x00, 0x05]);
        // length 00 05 | unit 01 | 03 02 12 34, and no CRC: TCP carries none.
        assert_eq!(read_all(&mut s), [0x01, 0x03, 0x02, 0x12, 0x34]);
        assert_eq!(s.take_dropped(), 0);
    }

    #[test]
    fn late_replies_and_other_protocols_are_dropped_and_counted() {
        let mut s = awaiting();
        s.request(&READ).unwrap();
        let mut foreign = MBAP_REPLY;
        foreign[1] = 2;
        foreign[3] = 7;
        let mut answer = MBAP_REPLY;
        answer[1] = 2;
        s.receive(&MBAP_REPLY);
        s.receive(&foreign);
        s.receive(&answer);
        s.receive(&answer);
        let dropped = s.take_frames().unwrap();
        assert_eq!(
            dropped,
            vec![
                Dropped::Late {
                    tid: 1,
                    awaited: Some(2),
                    frame: MBAP_REPLY.to_vec()
                },
                Dropped::Protocol {
                    protocol: 7,
                    frame: foreign.to_vec()
                },
                // Already answered: nothing is awaited any more.
                Dropped::Late {
                    tid: 2,
                    awaited: None,
                    frame: answer.to_vec()
                },
            ]
        );
        assert_eq!(s.take_dropped(), 33);
        assert_eq!(s.take_dropped(), 0);
        assert_eq!(read_all(&mut s), MBAP_REPLY[4..]);
    }

    #[test]
    fn out_of_step_stream_is_an_error_and_drops_the_buffer() {
        let mut s = awaiting();
        s.receive(&[0x01, 0x03, 0x02, 0x12, 0x34, 0xB5, 0x33]);
        assert_eq!(
            s.take_frames(),
            Err((0x34B5, vec![0x01, 0x03, 0x02, 0x12, 0x34, 0xB5, 0x33]))
        );
        assert_eq!(s.take_frames(), Ok(vec![]));
    }

    #[test]
    fn discard_returns_whole_frames_keeps_a_beginning_and_awaits_nothing() {
        let mut s = awaiting();
        s.receive(&MBAP_REPLY);
        s.take_frames().unwrap();
        let mut one = [0u8; 1];
        s.read(&mut one);
        let mut received = MBAP_REPLY.to_vec();
        received.extend_from_slice(&MBAP_REPLY[..3]);
        let stale = s.discard(&received).unwrap();
        let mut want = MBAP_REPLY[5..].to_vec();
        want.extend_from_slice(&MBAP_REPLY);
        assert_eq!(stale, want);
        // The beginning's rest completes a frame, which answers nothing awaited.
        s.receive(&MBAP_REPLY[3..]);
        assert!(matches!(
            s.take_frames().unwrap().as_slice(),
            [Dropped::Late { awaited: None, .. }]
        ));
    }

    const READ_ONE: Request = Request::ReadHoldingRegisters {
        address: 0,
        count: 1,
    };

    /// Golden: the reply to `READ` as a gateway that pads it sends it, transaction 1:
    /// tid 00 01 | protocol 00 00 | length 00 07 (two bytes more than the reply) |
    /// unit 01 | PDU 03 02 12 34 | extra 00 00.
    const MBAP_PADDED: [u8; 13] = [
        0x00, 0x01, 0x00, 0x00, 0x00, 0x07, 0x01, 0x03, 0x02, 0x12, 0x34, 0x00, 0x00,
    ];

    #[test]
    fn a_reply_is_read_by_its_length_field_and_taken_whole() {
        let mut s = awaiting();
        s.receive(&MBAP_PADDED);
        s.take_frames().unwrap();
        let mut got = Vec::new();
        // As the Bus reads: exactly what reply_needed asks for, until it is complete.
        while let Needed::More(n) = reply_needed(&got) {
            let mut chunk = vec![0u8; n];
            assert_eq!(s.read(&mut chunk), n);
            got.extend_from_slice(&chunk);
        }
        assert_eq!(reply_needed(&got), Needed::Complete(9));
        // Nothing of the frame is left over for the next request.
        assert_eq!(got, MBAP_PADDED[4..]);
        assert_eq!(read_all(&mut s), Vec::<u8>::new());
        assert_eq!(s.discard(&[]), Ok(vec![]));
        // And the errors show the frame as it crossed the network.
        assert_eq!(s.shown(&got, false).as_deref(), Some(&MBAP_PADDED[..]));
    }

    #[test]
    fn a_length_that_counts_more_or_fewer_bytes_than_the_reply_is_a_frame_error() {
        let exact = &MBAP_REPLY[4..];
        assert_eq!(
            decode_reply(1, &READ_ONE, exact),
            Ok(Reply::Normal(super::super::pdu::Response::Registers(vec![
                0x1234
            ])))
        );
        // Two bytes more: never a value, however good its first bytes.
        assert_eq!(
            decode_reply(1, &READ_ONE, &MBAP_PADDED[4..]),
            Err(FrameError::Length(
                "MBAP length 7 counts 2 bytes more than the reply to function 0x03 has \
                 (unit + PDU: 5 bytes)"
                    .into()
            ))
        );
        // An exception reply with a byte more.
        assert!(matches!(
            decode_reply(1, &READ_ONE, &[0x00, 0x04, 0x01, 0x83, 0x02, 0x00]),
            Err(FrameError::Length(m)) if m.contains("1 byte more")
        ));
        // What is wrong within the reply is told first: here the unit.
        let mut other_unit = MBAP_PADDED[4..].to_vec();
        other_unit[2] = 9;
        assert_eq!(
            decode_reply(1, &READ_ONE, &other_unit),
            Err(FrameError::WrongUnit {
                expected: 1,
                received: 9
            })
        );
        // A byte fewer than the byte count says: the length is short of the reply.
        assert!(matches!(
            decode_reply(1, &READ_ONE, &[0x00, 0x04, 0x01, 0x03, 0x02, 0x12]),
            Err(FrameError::Length(_))
        ));
        // A length field the bytes after it do not match.
        assert!(matches!(
            decode_reply(1, &READ_ONE, &MBAP_PADDED[4..11]),
            Err(FrameError::Length(m)) if m == "MBAP length 7, but 5 bytes follow it"
        ));
        assert_eq!(
            decode_reply(1, &READ_ONE, &[0x00]),
            Err(FrameError::TooShort(1))
        );
        // A raw request's reply of no known length is all the length counts.
        let raw = Request::Raw {
            function: 0x41,
            data: vec![],
            reply_length: None,
        };
        assert_eq!(
            decode_reply(1, &raw, &[0x00, 0x05, 0x01, 0x41, 0xAA, 0xBB, 0xCC]),
            Ok(Reply::Normal(super::super::pdu::Response::Raw(vec![
                0xAA, 0xBB, 0xCC
            ])))
        );
        let sized = Request::Raw {
            function: 0x41,
            data: vec![],
            reply_length: Some(2),
        };
        assert!(matches!(
            decode_reply(1, &sized, &[0x00, 0x05, 0x01, 0x41, 0xAA, 0xBB, 0xCC]),
            Err(FrameError::Length(m)) if m.contains("1 byte more")
        ));
    }

    #[test]
    fn reply_needed_goes_by_the_length_field_alone() {
        assert_eq!(reply_needed(&[]), Needed::More(2));
        assert_eq!(reply_needed(&[0x00]), Needed::More(1));
        assert_eq!(reply_needed(&[0x00, 0x07]), Needed::More(7));
        assert_eq!(reply_needed(&MBAP_PADDED[4..10]), Needed::More(3));
        assert_eq!(reply_needed(&MBAP_PADDED[4..]), Needed::Complete(9));
        assert_eq!(reply_needed(&[0x00, 0x01]), Needed::Unknown);
        assert_eq!(reply_needed(&[0x00, 0xFF]), Needed::Unknown);
        assert_eq!(reply_needed(&[0xFF, 0xFF, 0x01]), Needed::Unknown);
    }

    #[test]
    fn every_reply_shape_takes_its_exact_length_only() {
        use super::super::pdu::Request as R;
        // (request, its reply's unit + PDU): each shape the decoder knows.
        let cases: Vec<(R, Vec<u8>)> = vec![
            (READ_ONE, vec![1, 0x03, 0x02, 0x12, 0x34]),
            (
                R::WriteSingleRegister {
                    address: 1,
                    value: 2,
                },
                vec![1, 0x06, 0x00, 0x01, 0x00, 0x02],
            ),
            (
                R::WriteMultipleRegisters {
                    address: 1,
                    values: vec![7, 8],
                },
                vec![1, 0x10, 0x00, 0x01, 0x00, 0x02],
            ),
            (
                R::ReadCoils {
                    address: 0,
                    count: 9,
                },
                vec![1, 0x01, 0x02, 0xFF, 0x01],
            ),
            (
                R::MaskWriteRegister {
                    address: 4,
                    and_mask: 0xF2,
                    or_mask: 0x25,
                },
                vec![1, 0x16, 0x00, 0x04, 0x00, 0xF2, 0x00, 0x25],
            ),
            (R::ReadExceptionStatus, vec![1, 0x07, 0x6D]),
            (
                R::Diagnostics {
                    sub_function: 0,
                    data: vec![0xA5],
                },
                vec![1, 0x08, 0x00, 0x00, 0xA5],
            ),
            (R::ReportServerId, vec![1, 0x11, 0x02, 0x0A, 0xFF]),
            (
                R::ReadDeviceIdentification {
                    read_code: 1,
                    object_id: 0,
                },
                vec![
                    1, 0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x02, b'A', b'B',
                ],
            ),
            (READ_ONE, vec![1, 0x83, 0x02]),
        ];
        let framed = |unit_pdu: &[u8]| {
            let mut out = (unit_pdu.len() as u16).to_be_bytes().to_vec();
            out.extend_from_slice(unit_pdu);
            out
        };
        for (request, reply) in &cases {
            let exact = framed(reply);
            assert_eq!(reply_needed(&exact), Needed::Complete(exact.len()));
            assert!(decode_reply(1, request, &exact).is_ok(), "{request:?}");
            for extra in 1..=3 {
                let mut padded = reply.clone();
                padded.extend(std::iter::repeat_n(0, extra));
                assert!(
                    matches!(
                        decode_reply(1, request, &framed(&padded)),
                        Err(FrameError::Length(m)) if m.contains("more than the reply")
                    ),
                    "{request:?} + {extra}"
                );
            }
            for short in 1..reply.len() - 1 {
                assert!(
                    decode_reply(1, request, &framed(&reply[..short])).is_err(),
                    "{request:?} cut to {short}"
                );
            }
        }
    }

    #[test]
    fn over_modbus_tcp_a_busy_answer_also_says_what_the_gateway_means_by_it() {
        assert_eq!(
            exception_meaning(0x06, "server device busy"),
            "server device busy (a benchbus gateway answers this when all its client slots \
             are taken; try again later or raise --max-clients)"
        );
        assert_eq!(
            exception_meaning(0x02, "illegal data address"),
            "illegal data address"
        );
    }
}
