//! Device profiles: a device described in a TOML file, with the same [`Register`] the
//! built-in families' tables use, plus what a file must say that a family's code knows
//! (the table, the value's type and layout, enum members, the line settings and the
//! device's request limits). [`Profile::parse`] checks everything before any port is
//! opened; every mistake is a [`ProfileError`] naming the file, the line and the key.

use super::instrument::MAX_DECIMALS;
use super::value::{Kind, Layout};
use super::{Access, Register, Table};
use crate::codec::Echo;
use pieces::Pieces;
use std::collections::{BTreeMap, HashSet};
use std::ops::Range;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

mod pieces;

/// The rules of the language a profile's device is used from, beyond a name's form (an
/// ASCII identifier): which names its registers and enum members may not take. The Python
/// bindings pass Python's (its keywords, the members of its device class, what its `enum`
/// refuses: `benchbus._names`); read from Rust, a profile has none ([`AnyNames`]).
pub trait Names {
    /// Why a register may not be called `name`, or None.
    fn register(&self, _name: &str) -> Option<String> {
        None
    }

    /// Why `member` may not be a member of the enum of the register `register`, or None.
    fn member(&self, _register: &str, _member: &str) -> Option<String> {
        None
    }
}

/// No rules beyond a name's form.
#[derive(Debug, Clone, Copy, Default)]
pub struct AnyNames;

impl Names for AnyNames {}

/// A mistake in a profile file: where it is and what is wrong, shown as `FILE:LINE: key:
/// message` (`FILE: message` for a file that cannot be read, which has no line).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{path}{}: {}{message}",
    if *.line == 0 { String::new() } else { format!(":{}", .line) },
    if .key.is_empty() { String::new() } else { format!("{}: ", .key) })]
pub struct ProfileError {
    /// The file, as it was given.
    pub path: String,
    /// The line (from 1) of the offending key or value; 0 for a file that cannot be read.
    pub line: usize,
    /// The key, dotted from the top of the file (`line.parity`, `register[2].type`); empty
    /// for a file that is not valid TOML.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

/// The kind of value a profile register holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueType {
    /// A number over one, two or four registers.
    Number(Kind),
    /// A coil or discrete input, or one bit of a register (`bit`), or a whole register
    /// read as zero / non-zero (`bit` None).
    Bool {
        /// The bit (0..15) of a holding or input register.
        bit: Option<u8>,
    },
    /// Text over `length` registers, two characters each.
    Text {
        /// How many registers.
        length: u16,
    },
}

impl ValueType {
    /// Its name in a profile: "u16".."f64", "bool" or "string".
    pub fn name(self) -> &'static str {
        match self {
            ValueType::Number(kind) => kind.name(),
            ValueType::Bool { .. } => "bool",
            ValueType::Text { .. } => "string",
        }
    }

    /// How many registers (or bits, in a table of bits) a value covers.
    pub fn width(self) -> u32 {
        match self {
            ValueType::Number(kind) => kind.registers() as u32,
            ValueType::Bool { .. } => 1,
            ValueType::Text { length } => u32::from(length),
        }
    }
}

/// A value given in a profile (`default`).
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileValue {
    /// An integer (or an enum member's number).
    Int(i128),
    /// A float.
    Float(f64),
    /// A bool.
    Bool(bool),
    /// Text (or an enum member's name).
    Text(String),
}

/// One register of a profile: the shared [`Register`] (name, address, scale, signedness,
/// unit, access, range) and what the file adds.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileRegister {
    /// Name, address, scale, signedness, unit, access and the engineering range.
    pub register: Register<String>,
    /// The table it lives in.
    pub table: Table,
    /// What it holds.
    pub value: ValueType,
    /// How a multi-register value lies over its registers.
    pub layout: Layout,
    /// Engineering value = raw x scale + offset.
    pub offset: f64,
    /// Enum members (number, name), in the file's order; empty for none.
    pub members: Vec<(i128, String)>,
    /// The simulator's initial value, if given.
    pub default: Option<ProfileValue>,
    /// Free text.
    pub description: String,
    /// The line (from 1) of its `[[register]]` header; 0 for a register not read from a
    /// file (a built-in family's, [`Profile::family`]).
    pub line: usize,
    /// The models of `[device] models` that have it (`models`; empty: every model).
    pub models: Vec<String>,
    /// The write range on a model where it differs from [`Register::range`] (`ranges`).
    pub ranges: Vec<(String, (f64, f64))>,
    /// A field of a register's bits, `(first, last)` (`bits`): an unsigned number of
    /// `last - first + 1` bits (a status word's mode or source), None for the whole word.
    pub bits: Option<(u8, u8)>,
    /// The register whose value is the number of decimal places of this one (`decimals`:
    /// a controller's decimal point): engineering value = raw / 10^that, its range in the
    /// raw digits; None for a fixed scale.
    pub decimals: Option<String>,
}

/// How the device's own line is set up (each None: the caller's default).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LineSettings {
    /// Bits per second.
    pub baudrate: Option<u32>,
    /// 'N', 'E' or 'O'.
    pub parity: Option<char>,
    /// 1 or 2.
    pub stopbits: Option<u8>,
    /// Reply timeout, seconds.
    pub timeout: Option<f64>,
    /// "rtu" or "ascii".
    pub framing: Option<String>,
    /// 7 or 8.
    pub bytesize: Option<u8>,
}

/// What the device accepts in one request (each None: no limit beyond Modbus's).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Limits {
    /// Registers (or bits in a table of bits) one read may ask for.
    pub max_read: Option<u16>,
    /// Registers (or bits) one write may carry.
    pub max_write: Option<u16>,
    /// Seconds between two writes to the device.
    pub min_write_interval: Option<f64>,
    /// Whether neighbouring registers may be read in one request.
    pub block_reads: Option<bool>,
    /// Whether one request may also read the addresses between two registers that the
    /// profile does not list (a device that answers them, as the J2's empty "NC" ones).
    pub read_gaps: Option<bool>,
    /// What the device's reply to a write carries (`write_echo`): the Modbus echo
    /// ("strict"), or for a 0x06 write a register count of 1 in place of the value
    /// ("count", as PBL drives answer).
    pub write_echo: Option<Echo>,
    /// Whether every write of registers is function 0x10, also of one register
    /// (`write_multiple`: a device that does not take 0x06, as Eastron's meters).
    pub write_multiple: Option<bool>,
}

/// What a profile says of the device it describes (`[device] maker`, `model`, `kind`,
/// `source`): free text but `kind`, a lower-case word (`energy-meter`) that groups the
/// shipped profiles; empty where the file is silent.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct About {
    /// Who makes it.
    pub maker: String,
    /// The model or series the file covers.
    pub model: String,
    /// What sort of device it is: lower-case letters, digits and `-`.
    pub kind: String,
    /// The document the registers were written from (title, version, sections).
    pub source: String,
}

/// A device described by a profile file.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// The device's name (`[device] name`).
    pub name: String,
    /// Free text.
    pub description: String,
    /// Its maker, model, kind and source.
    pub about: About,
    /// `[line]`.
    pub line: LineSettings,
    /// `[limits]`.
    pub limits: Limits,
    /// The models the file describes (`[device] models`), the first the one its rows are
    /// written for; empty for a file of one model.
    pub models: Vec<String>,
    /// Every `[[register]]`, in the file's order.
    pub registers: Vec<ProfileRegister>,
}

type Fail = Box<ProfileError>;
type Parsed<T> = std::result::Result<T, Fail>;

/// Where each line of a file starts, to turn a byte offset into its line by a binary search
/// (counting the newlines before every key instead made loading quadratic in the file's
/// size).
struct Lines {
    starts: Vec<usize>,
}

impl Lines {
    fn new(text: &str) -> Lines {
        let newlines = text.bytes().enumerate().filter(|(_, b)| *b == b'\n');
        let starts = std::iter::once(0)
            .chain(newlines.map(|(at, _)| at + 1))
            .collect();
        Lines { starts }
    }

    /// The line (from 1) of the byte at `offset`.
    fn line(&self, offset: usize) -> usize {
        self.starts.partition_point(|start| *start <= offset)
    }
}

/// Where the parser is: the file's name and lines, to turn spans into lines.
struct Source<'a> {
    path: &'a str,
    lines: &'a Lines,
    /// The rules of names beyond their form.
    names: &'a dyn Names,
    /// Where the text parsed lies in the file: (offset in the text, offset in the file) of
    /// each of its pieces, ascending (`[(0, 0)]` for the whole file).
    at: &'a [(usize, usize)],
}

impl Source<'_> {
    /// The line (from 1) of the byte at `offset` of the text parsed.
    fn line(&self, offset: usize) -> usize {
        let piece = self.at.partition_point(|(from, _)| *from <= offset);
        let in_file = match piece.checked_sub(1).and_then(|p| self.at.get(p)) {
            Some((from, to)) => to + (offset - from),
            None => offset,
        };
        self.lines.line(in_file)
    }

    fn fail(&self, span: Range<usize>, key: &str, message: impl Into<String>) -> Fail {
        Box::new(ProfileError {
            path: self.path.to_string(),
            line: self.line(span.start),
            key: key.to_string(),
            message: message.into(),
        })
    }
}

/// One table of the file, with its dotted name for messages.
struct Section<'s, 'a, 'i> {
    src: &'s Source<'a>,
    table: &'s DeTable<'i>,
    prefix: String,
    span: Range<usize>,
}

impl<'s, 'a, 'i> Section<'s, 'a, 'i> {
    fn key(&self, key: &str) -> String {
        format!("{}.{key}", self.prefix)
    }

    fn fail(&self, key: &str, span: Range<usize>, message: impl Into<String>) -> Fail {
        self.src.fail(span, &self.key(key), message)
    }

    /// Refuses a key not in `allowed`.
    fn known(&self, allowed: &[&str]) -> Parsed<()> {
        for (key, _) in self.table.iter() {
            let name: &str = key.get_ref();
            if !allowed.contains(&name) {
                return Err(self.fail(
                    name,
                    key.span(),
                    format!("unknown key (known: {})", allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }

    fn get(&self, key: &str) -> Option<&'s Spanned<DeValue<'i>>> {
        self.table.get(key)
    }

    fn span_of(&self, key: &str) -> Range<usize> {
        self.get(key).map_or(self.span.clone(), Spanned::span)
    }

    fn string(&self, key: &str) -> Parsed<Option<&'s str>> {
        match self.get(key).map(|v| (v.get_ref(), v.span())) {
            None => Ok(None),
            Some((DeValue::String(s), _)) => Ok(Some(s.as_ref())),
            Some((other, span)) => Err(self.fail(key, span, wrong("a string", other))),
        }
    }

    fn int(&self, key: &str) -> Parsed<Option<i128>> {
        match self.get(key).map(|v| (v.get_ref(), v.span())) {
            None => Ok(None),
            Some((DeValue::Integer(i), span)) => i128::from_str_radix(i.as_str(), i.radix())
                .map(Some)
                .map_err(|_| self.fail(key, span, "integer out of range")),
            Some((other, span)) => Err(self.fail(key, span, wrong("an integer", other))),
        }
    }

    fn number(&self, key: &str) -> Parsed<Option<f64>> {
        let value = match self.get(key).map(|v| (v.get_ref(), v.span())) {
            None => return Ok(None),
            Some((DeValue::Integer(_), _)) => self.int(key)?.map(|i| i as f64),
            Some((float @ DeValue::Float(_), _)) => to_number(float),
            Some((other, span)) => return Err(self.fail(key, span, wrong("a number", other))),
        };
        match value {
            Some(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(self.fail(key, self.span_of(key), "must be a finite number")),
        }
    }

    fn boolean(&self, key: &str) -> Parsed<Option<bool>> {
        match self.get(key).map(|v| (v.get_ref(), v.span())) {
            None => Ok(None),
            Some((DeValue::Boolean(b), _)) => Ok(Some(*b)),
            Some((other, span)) => Err(self.fail(key, span, wrong("true or false", other))),
        }
    }

    /// A non-empty array of distinct non-empty strings (empty when the key is absent).
    fn strings(&self, key: &str) -> Parsed<Vec<String>> {
        let (items, span) = match self.get(key).map(|v| (v.get_ref(), v.span())) {
            None => return Ok(Vec::new()),
            Some((DeValue::Array(items), span)) => (items, span),
            Some((other, span)) => {
                return Err(self.fail(key, span, wrong("an array of strings", other)))
            }
        };
        let mut out: Vec<String> = Vec::with_capacity(items.len());
        for item in items {
            match item.get_ref() {
                DeValue::String(text) if !text.trim().is_empty() => {
                    if out.iter().any(|o| o == text.as_ref()) {
                        return Err(self.fail(key, item.span(), format!("{text:?} is repeated")));
                    }
                    out.push(text.to_string());
                }
                DeValue::String(_) => {
                    return Err(self.fail(key, item.span(), "must not hold an empty name"))
                }
                other => return Err(self.fail(key, item.span(), wrong("a string", other))),
            }
        }
        if out.is_empty() {
            return Err(self.fail(key, span, "must name at least one"));
        }
        Ok(out)
    }

    /// An integer in `lo..=hi`.
    fn int_in(&self, key: &str, lo: i128, hi: i128) -> Parsed<Option<i128>> {
        match self.int(key)? {
            Some(v) if !(lo..=hi).contains(&v) => Err(self.fail(
                key,
                self.span_of(key),
                format!("must be {lo} to {hi}, got {v}"),
            )),
            v => Ok(v),
        }
    }

    /// One of `choices`.
    fn choice(&self, key: &str, choices: &[&str]) -> Parsed<Option<&'s str>> {
        match self.string(key)? {
            Some(s) if !choices.contains(&s) => Err(self.fail(
                key,
                self.span_of(key),
                format!("must be one of {}, got {s:?}", quoted(choices)),
            )),
            s => Ok(s),
        }
    }
}

/// A TOML integer or float as an f64; None for another value, or one that does not parse.
fn to_number(value: &DeValue<'_>) -> Option<f64> {
    match value {
        DeValue::Integer(i) => i128::from_str_radix(i.as_str(), i.radix())
            .ok()
            .map(|i| i as f64),
        DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
        _ => None,
    }
}

/// Whether `value` lies within `(lo, hi)`, what a register's type holds, give or take the
/// float rounding of its scale and offset.
fn holds((lo, hi): (f64, f64), value: f64) -> bool {
    let slack = |v: f64| 1e-9 * v.abs().max(1.0);
    value >= lo - slack(lo) && value <= hi + slack(hi)
}

fn wrong(expected: &str, got: &DeValue<'_>) -> String {
    let kind = match got {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a float",
        DeValue::Boolean(_) => "a bool",
        DeValue::Datetime(_) => "a date",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    };
    format!("must be {expected}, got {kind}")
}

fn quoted(choices: &[&str]) -> String {
    choices
        .iter()
        .map(|c| format!("{c:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether `name` is an identifier: ASCII letters, digits and `_`, not starting with a digit.
pub fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The engineering values a number kind holds at `scale` and `offset`, low to high: the
/// range of a register whose profile gives no `min` / `max`.
pub(crate) fn full_range(kind: Kind, scale: f64, offset: f64) -> (f64, f64) {
    let (raw_lo, raw_hi) = raw_range(kind);
    let (a, b) = (
        super::scaled(raw_lo, scale) + offset,
        super::scaled(raw_hi, scale) + offset,
    );
    (a.min(b), a.max(b))
}

/// The raw values a number kind holds.
fn raw_range(kind: Kind) -> (f64, f64) {
    match kind {
        Kind::U16 => (0.0, 65535.0),
        Kind::I16 => (-32768.0, 32767.0),
        Kind::U32 => (0.0, 4_294_967_295.0),
        Kind::I32 => (-2_147_483_648.0, 2_147_483_647.0),
        Kind::U64 => (0.0, u64::MAX as f64),
        Kind::I64 => (i64::MIN as f64, i64::MAX as f64),
        Kind::F32 => (-f64::from(f32::MAX), f64::from(f32::MAX)),
        Kind::F64 => (f64::MIN, f64::MAX),
    }
}

/// The integers an integer kind holds, or None for a float kind.
fn int_range(kind: Kind) -> Option<(i128, i128)> {
    match kind {
        Kind::U16 => Some((0, 0xFFFF)),
        Kind::I16 => Some((-0x8000, 0x7FFF)),
        Kind::U32 => Some((0, 0xFFFF_FFFF)),
        Kind::I32 => Some((i128::from(i32::MIN), i128::from(i32::MAX))),
        Kind::U64 => Some((0, i128::from(u64::MAX))),
        Kind::I64 => Some((i128::from(i64::MIN), i128::from(i64::MAX))),
        Kind::F32 | Kind::F64 => None,
    }
}

/// The values of `[limits] write_echo`, each with the rule it names.
pub const ECHOES: [(&str, Echo); 2] = [
    ("strict", Echo::Strict),
    ("count", Echo::CountForSingleWrite),
];

/// The name `[limits] write_echo` gives `echo`.
pub fn echo_name(echo: Echo) -> &'static str {
    ECHOES
        .iter()
        .find(|(_, e)| *e == echo)
        .map_or("strict", |(name, _)| name)
}

const TOP_KEYS: &[&str] = &["device", "line", "limits", "register"];
const DEVICE_KEYS: &[&str] = &[
    "name",
    "description",
    "models",
    "maker",
    "model",
    "kind",
    "source",
];
const LINE_KEYS: &[&str] = &[
    "baudrate", "parity", "stopbits", "timeout", "framing", "bytesize",
];
const LIMIT_KEYS: &[&str] = &[
    "max_read",
    "max_write",
    "min_write_interval",
    "block_reads",
    "read_gaps",
    "write_echo",
    "write_multiple",
];
const REGISTER_KEYS: &[&str] = &[
    "name",
    "address",
    "table",
    "type",
    "order",
    "scale",
    "offset",
    "unit",
    "access",
    "min",
    "max",
    "description",
    "enum",
    "default",
    "bit",
    "bits",
    "length",
    "models",
    "ranges",
    "decimals",
];

impl Profile {
    /// Reads and checks the profile file at `path`, its names by no rules but their form
    /// (see [`Profile::load_with`]).
    ///
    /// # Errors
    /// A [`ProfileError`] for a file that cannot be read (line 0) or any mistake in it.
    pub fn load(path: &std::path::Path) -> Result<Profile, Box<ProfileError>> {
        Profile::load_with(path, &AnyNames)
    }

    /// Reads and checks the profile file at `path`, its names by the rules `names`.
    ///
    /// # Errors
    /// A [`ProfileError`] for a file that cannot be read (line 0) or any mistake in it.
    pub fn load_with(
        path: &std::path::Path,
        names: &dyn Names,
    ) -> Result<Profile, Box<ProfileError>> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            Box::new(ProfileError {
                path: shown.clone(),
                line: 0,
                key: String::new(),
                message: format!("cannot read the file: {e}"),
            })
        })?;
        Profile::parse_with(&shown, &text, names)
    }

    /// Checks the profile `text`, read from `path` (used only in errors), its names by no
    /// rules but their form.
    ///
    /// # Errors
    /// A [`ProfileError`] for the first mistake in it.
    pub fn parse(path: &str, text: &str) -> Result<Profile, Box<ProfileError>> {
        Profile::parse_with(path, text, &AnyNames)
    }

    /// Checks the profile `text`, read from `path` (used only in errors), its names by the
    /// rules `names` (the Python bindings pass Python's).
    ///
    /// # Errors
    /// A [`ProfileError`] for the first mistake in it.
    pub fn parse_with(
        path: &str,
        text: &str,
        names: &dyn Names,
    ) -> Result<Profile, Box<ProfileError>> {
        let lines = Lines::new(text);
        // The registers a run at a time where the file allows it: the whole file's TOML
        // tree takes about 45 bytes for each byte of the file. A file with a mistake is read
        // whole, so that its mistake is the one reading it whole finds first.
        match Profile::parse_in_runs(path, text, &lines, names) {
            Some(profile) => Ok(profile),
            None => Profile::parse_whole(path, text, &lines, names),
        }
    }

    /// The profile `text` read as one TOML document.
    fn parse_whole(path: &str, text: &str, lines: &Lines, names: &dyn Names) -> Parsed<Profile> {
        let src = Source {
            path,
            lines,
            names,
            at: &[(0, 0)],
        };
        let root = DeTable::parse(text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            src.fail(span, "", e.message().trim().to_string())
        })?;
        let top = Section {
            src: &src,
            table: root.get_ref(),
            prefix: String::new(),
            span: root.span(),
        };
        Profile::checked(path, &top, || {
            let mut registers = RegisterSet::default();
            match top.get("register").map(|v| (v.get_ref(), v.span())) {
                None => {}
                Some((DeValue::Array(items), _)) => registers.add(&top, items)?,
                Some((other, span)) => {
                    return Err(src.fail(
                        span,
                        "register",
                        wrong("an array of tables ([[register]])", other),
                    ))
                }
            }
            Ok(registers.out)
        })
    }

    /// The profile `text` read as [`Pieces`]: the tables other than the registers as one
    /// TOML document, then the registers a run of tables at a time, each run's tree dropped
    /// before the next is read. None for a file with a mistake, or whose pieces do not hold
    /// what they should (the cut is made without parsing): the caller then reads it whole.
    fn parse_in_runs(path: &str, text: &str, lines: &Lines, names: &dyn Names) -> Option<Profile> {
        let pieces = Pieces::new(text);
        if pieces.len() != text.len() {
            return None;
        }
        let src = Source {
            path,
            lines,
            names,
            at: &pieces.rest_at,
        };
        let root = DeTable::parse(&pieces.rest).ok()?;
        let top = Section {
            src: &src,
            table: root.get_ref(),
            prefix: String::new(),
            span: root.span(),
        };
        if top.get("register").is_some() {
            return None;
        }
        Profile::checked(path, &top, || {
            let mut registers = RegisterSet::default();
            for (start, run) in &pieces.runs {
                let at = [(0, *start)];
                let run_src = Source {
                    path,
                    lines,
                    names,
                    at: &at,
                };
                let cut_wrong = || run_src.fail(0..0, "register", "the cut was wrong");
                let run_root = DeTable::parse(run).map_err(|_| cut_wrong())?;
                // A run holds registers only, else the cut was wrong.
                let mut entries = run_root.get_ref().iter();
                let (Some((key, value)), None) = (entries.next(), entries.next()) else {
                    return Err(cut_wrong());
                };
                let (DeValue::Array(items), "register") = (value.get_ref(), key.get_ref().as_ref())
                else {
                    return Err(cut_wrong());
                };
                let run_top = Section {
                    src: &run_src,
                    table: run_root.get_ref(),
                    prefix: String::new(),
                    span: run_root.span(),
                };
                registers.add(&run_top, items)?;
            }
            Ok(registers.out)
        })
        .ok()
    }

    /// The profile of the file whose top table is `top`: its sections checked, then its
    /// `registers` read, then their widths.
    fn checked(
        path: &str,
        top: &Section<'_, '_, '_>,
        registers: impl FnOnce() -> Parsed<Vec<ProfileRegister>>,
    ) -> Parsed<Profile> {
        let src = top.src;
        for (key, _) in top.table.iter() {
            if !TOP_KEYS.contains(&key.get_ref().as_ref()) {
                return Err(src.fail(
                    key.span(),
                    key.get_ref(),
                    format!("unknown section (known: {})", TOP_KEYS.join(", ")),
                ));
            }
        }
        let device = sub(top, "device")?
            .ok_or_else(|| src.fail(0..0, "device", "missing [device] with its name"))?;
        device.known(DEVICE_KEYS)?;
        let name = device
            .string("name")?
            .ok_or_else(|| device.fail("name", device.span.clone(), "missing (required)"))?;
        if name.trim().is_empty() {
            return Err(device.fail("name", device.span_of("name"), "must not be empty"));
        }
        let description = device.string("description")?.unwrap_or("").to_string();
        let models = device.strings("models")?;
        let about = about(&device)?;
        let line = match sub(top, "line")? {
            Some(s) => line_settings(&s)?,
            None => LineSettings::default(),
        };
        let limits = match sub(top, "limits")? {
            Some(s) => limits(&s)?,
            None => Limits::default(),
        };
        let profile = Profile {
            name: name.to_string(),
            description,
            about,
            line,
            limits,
            models,
            registers: registers()?,
        };
        profile.check_widths(path)?;
        profile.check_models(path)?;
        profile.check_decimals(path)?;
        Ok(profile)
    }

    /// Refuses a register's `models` or `ranges` naming a model `[device] models` does not.
    fn check_models(&self, path: &str) -> Parsed<()> {
        for (index, r) in self.registers.iter().enumerate() {
            let named = r.models.iter().map(|m| ("models", m));
            let ranged = r.ranges.iter().map(|(m, _)| ("ranges", m));
            for (key, model) in named.chain(ranged) {
                if !self.models.contains(model) {
                    let known = if self.models.is_empty() {
                        "the file names none in [device] models".to_string()
                    } else {
                        format!("[device] models are {}", self.models.join(", "))
                    };
                    return Err(Box::new(ProfileError {
                        path: path.to_string(),
                        line: r.line,
                        key: format!("register[{index}].{key}"),
                        message: format!("no model {model:?}: {known}"),
                    }));
                }
            }
        }
        Ok(())
    }

    /// Refuses a `decimals` naming no register of the profile, itself, a write-only one,
    /// one that is not an unscaled integer, one with decimals of its own, or one whose
    /// range reaches past 0..9 places.
    fn check_decimals(&self, path: &str) -> Parsed<()> {
        for (index, r) in self.registers.iter().enumerate() {
            let Some(name) = &r.decimals else { continue };
            let given = self.index(name).and_then(|at| self.registers.get(at));
            let refusal = match given {
                None => Some(format!("no register {name:?} in the file")),
                Some(g) if g.register.name == r.register.name => {
                    Some("a register's decimals are another register's value".to_string())
                }
                Some(g) if g.register.access == Access::Write => {
                    Some(format!("{name} is write-only: its value cannot be read"))
                }
                Some(g) if !g.is_count() || g.decimals.is_some() => Some(format!(
                    "{name} must be an unscaled integer without decimals of its own"
                )),
                Some(g) if !g.places_only() => Some(format!(
                    "{name} may hold {}..{} (on some model): give it min and max within \
                     0..{MAX_DECIMALS} places (or an enum of them)",
                    g.register.range.0, g.register.range.1
                )),
                Some(g)
                    if !g.models.is_empty()
                        && (r.models.is_empty()
                            || r.models.iter().any(|m| !g.models.contains(m))) =>
                {
                    Some(format!(
                        "{name} is not on every model {} is on",
                        r.register.name
                    ))
                }
                Some(_) => None,
            };
            if let Some(message) = refusal {
                return Err(Box::new(ProfileError {
                    path: path.to_string(),
                    line: r.line,
                    key: format!("register[{index}].decimals"),
                    message,
                }));
            }
        }
        Ok(())
    }

    /// The profile of model `model` of `[device] models`, named after it: its registers
    /// only, each with its range on that model, and no models of its own. None for a model
    /// the file does not name.
    pub fn for_model(&self, model: &str) -> Option<Profile> {
        if !self.models.iter().any(|m| m == model) {
            return None;
        }
        let registers = self
            .registers
            .iter()
            .filter(|r| r.models.is_empty() || r.models.iter().any(|m| m == model))
            .map(|r| {
                let mut r = r.clone();
                if let Some((_, range)) = r.ranges.iter().find(|(m, _)| m == model) {
                    r.register.range = *range;
                }
                r.models.clear();
                r.ranges.clear();
                r
            })
            .collect();
        Some(Profile {
            name: model.to_string(),
            description: self.description.clone(),
            about: About {
                model: model.to_string(),
                ..self.about.clone()
            },
            line: self.line.clone(),
            limits: self.limits.clone(),
            models: Vec::new(),
            registers,
        })
    }

    /// Refuses a register that one request cannot read or write whole: a value split over
    /// two requests could tear.
    fn check_widths(&self, path: &str) -> Parsed<()> {
        for (index, r) in self.registers.iter().enumerate() {
            let width = r.value.width();
            let (limit, what) = if r.register.access != Access::Write
                && width > u32::from(self.read_limit(r.table))
            {
                (self.read_limit(r.table), "read")
            } else if r.register.access != Access::Read
                && width > u32::from(self.write_limit(r.table))
            {
                (self.write_limit(r.table), "write")
            } else {
                continue;
            };
            let key = match r.value {
                ValueType::Text { .. } => "length",
                _ => "type",
            };
            return Err(Box::new(ProfileError {
                path: path.to_string(),
                line: r.line,
                key: format!("register[{index}].{key}"),
                message: format!(
                    "a {} of {width} registers does not fit one {what} of at most {limit}",
                    r.value.name()
                ),
            }));
        }
        Ok(())
    }
}

/// The table `key` of `parent`, if there.
fn sub<'s, 'a, 'i>(parent: &Section<'s, 'a, 'i>, key: &str) -> Parsed<Option<Section<'s, 'a, 'i>>> {
    match parent.get(key).map(|v| (v.get_ref(), v.span())) {
        None => Ok(None),
        Some((DeValue::Table(t), span)) => Ok(Some(Section {
            src: parent.src,
            table: t,
            prefix: key.to_string(),
            span,
        })),
        Some((other, span)) => Err(parent.src.fail(span, key, wrong("a table", other))),
    }
}

/// `[device]`'s `maker`, `model`, `kind` and `source`; a `kind` of other than lower-case
/// letters, digits and `-` is refused (it names a group of profiles).
fn about(s: &Section<'_, '_, '_>) -> Parsed<About> {
    let text = |key| -> Parsed<String> { Ok(s.string(key)?.unwrap_or("").to_string()) };
    let kind = text("kind")?;
    // Words of lower-case letters and digits joined by single hyphens, the first a letter.
    let word = |w: &str| {
        !w.is_empty()
            && w.chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit())
    };
    let starts = kind.chars().next().is_some_and(|c| c.is_ascii_lowercase());
    if s.get("kind").is_some() && !(starts && kind.split('-').all(word)) {
        return Err(s.fail(
            "kind",
            s.span_of("kind"),
            format!(
                "{kind:?} is not a kind: words of lower-case letters and digits joined by \
                 '-', the first a letter (\"energy-meter\")"
            ),
        ));
    }
    Ok(About {
        maker: text("maker")?,
        model: text("model")?,
        kind,
        source: text("source")?,
    })
}

fn line_settings(s: &Section<'_, '_, '_>) -> Parsed<LineSettings> {
    s.known(LINE_KEYS)?;
    let timeout = s.number("timeout")?;
    if let Some(t) = timeout {
        if t <= 0.0 {
            return Err(s.fail("timeout", s.span_of("timeout"), "must be above 0 s"));
        }
    }
    Ok(LineSettings {
        baudrate: s.int_in("baudrate", 1, 4_000_000)?.map(|b| b as u32),
        parity: s
            .choice("parity", &["N", "E", "O"])?
            .and_then(|p| p.chars().next()),
        stopbits: s.int_in("stopbits", 1, 2)?.map(|b| b as u8),
        timeout,
        framing: s.choice("framing", &["rtu", "ascii"])?.map(str::to_string),
        bytesize: s.int_in("bytesize", 7, 8)?.map(|b| b as u8),
    })
}

fn limits(s: &Section<'_, '_, '_>) -> Parsed<Limits> {
    s.known(LIMIT_KEYS)?;
    let interval = s.number("min_write_interval")?;
    if let Some(t) = interval {
        if t < 0.0 {
            return Err(s.fail(
                "min_write_interval",
                s.span_of("min_write_interval"),
                "must be 0 s or more",
            ));
        }
    }
    let block_reads = s.boolean("block_reads")?;
    let read_gaps = s.boolean("read_gaps")?;
    if read_gaps == Some(true) && block_reads == Some(false) {
        return Err(s.fail(
            "read_gaps",
            s.span_of("read_gaps"),
            "needs block reads: with block_reads = false every register is read apart",
        ));
    }
    let write_multiple = s.boolean("write_multiple")?;
    let echo = s.choice("write_echo", &ECHOES.map(|(name, _)| name))?;
    if write_multiple == Some(true) && echo == Some("count") {
        return Err(s.fail(
            "write_echo",
            s.span_of("write_echo"),
            "\"count\" is the reply to a 0x06 write, which write_multiple = true never sends",
        ));
    }
    // 2000 bits is the most one read of coils may ask for; 1968 one write of coils.
    Ok(Limits {
        max_read: s.int_in("max_read", 1, 2000)?.map(|v| v as u16),
        max_write: s.int_in("max_write", 1, 1968)?.map(|v| v as u16),
        min_write_interval: interval,
        block_reads,
        read_gaps,
        write_echo: echo.and_then(|name| {
            ECHOES
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, echo)| *echo)
        }),
        write_multiple,
    })
}

/// The registers read so far, and what a register read next must not repeat.
#[derive(Default)]
struct RegisterSet {
    out: Vec<ProfileRegister>,
    names: HashSet<String>,
    /// The addresses taken, each (table, address, bit or [`WHOLE`]) with the index in the
    /// file of the register that takes it.
    taken: BTreeMap<(u8, u32, u8), usize>,
}

/// In [`RegisterSet::taken`], for a register taken whole (not one of its bits).
const WHOLE: u8 = 16;

/// Whether a register is one whole word read as a number: the word its bits may be
/// declared beside (`bit`, `bits`), a status word and its flags and fields.
fn is_word(r: &ProfileRegister) -> bool {
    r.bits.is_none() && matches!(r.value, ValueType::Number(Kind::U16 | Kind::I16))
}

impl RegisterSet {
    /// Checks the `[[register]]` tables `items` of the document `top`, and adds them.
    fn add(&mut self, top: &Section<'_, '_, '_>, items: &[Spanned<DeValue<'_>>]) -> Parsed<()> {
        self.out.reserve(items.len());
        for item in items {
            let index = self.out.len();
            let prefix = format!("register[{index}]");
            let DeValue::Table(table) = item.get_ref() else {
                return Err(top.src.fail(item.span(), &prefix, "must be a table"));
            };
            let s = Section {
                src: top.src,
                table,
                prefix,
                span: item.span(),
            };
            let reg = register(&s)?;
            if !self.names.insert(reg.register.name.clone()) {
                return Err(s.fail(
                    "name",
                    s.span_of("name"),
                    format!("duplicate name {:?}", reg.register.name),
                ));
            }
            let table_id = reg.table as u8;
            // The bits it takes of its register (a bool's bit, a field's), or None: whole.
            let bits = reg.part_of_word().map(|(first, last)| first..=last);
            let first = u32::from(reg.register.address);
            for address in first..first + reg.value.width() {
                // Bits share their register with other bits, and with the one-word number
                // that is the whole of it (a status word beside its fields), nothing else.
                let at = |b: u8| (table_id, address, b);
                let whole = self.taken.get(&at(WHOLE)).copied();
                let other = match &bits {
                    None if is_word(&reg) => whole,
                    None => self.taken.range(at(0)..=at(WHOLE)).map(|(_, i)| *i).min(),
                    Some(own) => own
                        .clone()
                        .find_map(|b| self.taken.get(&at(b)).copied())
                        .or_else(|| whole.filter(|i| self.out.get(*i).is_none_or(|w| !is_word(w)))),
                };
                if let Some(other) = other {
                    let other_name = self.out.get(other).map_or("", |r| r.register.name.as_str());
                    return Err(s.fail(
                        "address",
                        s.span_of("address"),
                        format!("{address:#06x} overlaps {other_name:?}"),
                    ));
                }
                match &bits {
                    Some(own) => own.clone().for_each(|b| {
                        self.taken.insert(at(b), index);
                    }),
                    None => {
                        self.taken.insert(at(WHOLE), index);
                    }
                }
            }
            self.out.push(reg);
        }
        Ok(())
    }
}

fn register(s: &Section<'_, '_, '_>) -> Parsed<ProfileRegister> {
    s.known(REGISTER_KEYS)?;
    let line = s.src.line(s.span.start);
    let name = s
        .string("name")?
        .ok_or_else(|| s.fail("name", s.span.clone(), "missing (required)"))?;
    if !is_identifier(name) {
        return Err(s.fail(
            "name",
            s.span_of("name"),
            format!("{name:?} is not a Python identifier"),
        ));
    }
    if let Some(refusal) = s.src.names.register(name) {
        return Err(s.fail("name", s.span_of("name"), refusal));
    }
    let address =
        s.int_in("address", 0, 0xFFFF)?
            .ok_or_else(|| s.fail("address", s.span.clone(), "missing (required)"))? as u16;
    let table = match s.choice("table", &["holding", "input", "coil", "discrete"])? {
        None | Some("holding") => Table::Holding,
        Some("input") => Table::Input,
        Some("coil") => Table::Coils,
        _ => Table::Discrete,
    };
    let value = value_type(s, table)?;
    let width = value.width();
    if u32::from(address) + width - 1 > 0xFFFF {
        return Err(s.fail(
            "address",
            s.span_of("address"),
            format!("a {} from {address:#06x} runs past 0xFFFF", value.name()),
        ));
    }
    let kind = match value {
        ValueType::Number(kind) => Some(kind),
        _ => None,
    };
    let layout = match s.string("order")? {
        None => Layout::Abcd,
        Some(_) if matches!(value, ValueType::Bool { .. }) => {
            return Err(s.fail("order", s.span_of("order"), "a bool has no byte order"))
        }
        Some(o) => Layout::from_name(o).ok_or_else(|| {
            s.fail(
                "order",
                s.span_of("order"),
                format!("must be one of \"ABCD\", \"CDAB\", \"BADC\", \"DCBA\", got {o:?}"),
            )
        })?,
    };
    for key in ["scale", "offset", "min", "max", "enum"] {
        if kind.is_none() && s.get(key).is_some() {
            return Err(s.fail(
                key,
                s.span_of(key),
                format!("a {} register takes no {key}", value.name()),
            ));
        }
    }
    let scale = s.number("scale")?.unwrap_or(1.0);
    if scale == 0.0 {
        return Err(s.fail("scale", s.span_of("scale"), "must not be 0"));
    }
    let offset = s.number("offset")?.unwrap_or(0.0);
    let read_only = matches!(table, Table::Input | Table::Discrete);
    let access = match s.choice("access", &["r", "rw", "rw-stopped", "w"])? {
        None if read_only => Access::Read,
        None => Access::ReadWrite,
        Some("r") => Access::Read,
        Some(_) if read_only => {
            return Err(s.fail(
                "access",
                s.span_of("access"),
                format!("{} is read-only", table_name(table)),
            ))
        }
        Some("rw") => Access::ReadWrite,
        Some("rw-stopped") => Access::WriteWhenStopped,
        _ => Access::Write,
    };
    let range = match kind {
        Some(kind) => range(s, kind, scale, offset)?,
        None => (0.0, 0.0),
    };
    let members = match kind {
        Some(kind) => members(s, kind, name)?,
        None => Vec::new(),
    };
    if !members.is_empty() && (scale != 1.0 || offset != 0.0) {
        return Err(s.fail(
            "enum",
            s.span_of("enum"),
            "an enum register takes no scale or offset",
        ));
    }
    let ranges = match kind {
        Some(kind) => model_ranges(s, kind, scale, offset)?,
        None if s.get("ranges").is_some() => {
            return Err(s.fail(
                "ranges",
                s.span_of("ranges"),
                format!("a {} register takes no ranges", value.name()),
            ))
        }
        None => Vec::new(),
    };
    let bits = bits(s, table, value)?;
    let range = match bits {
        Some(field) => checked_field_range(s, field, (scale, offset), range, &ranges, &members)?,
        None => range,
    };
    let default = default(s, value, (range, scale, offset), &members)?;
    let decimals = decimals(s, kind, (scale, offset), &members, bits)?;
    Ok(ProfileRegister {
        register: Register {
            name: name.to_string(),
            address,
            scale,
            signed: matches!(kind, Some(Kind::I16 | Kind::I32 | Kind::I64)),
            unit: s.string("unit")?.unwrap_or("").to_string(),
            access,
            range,
        },
        table,
        value,
        layout,
        offset,
        members,
        default,
        description: s.string("description")?.unwrap_or("").to_string(),
        line,
        models: s.strings("models")?,
        ranges,
        bits,
        decimals,
    })
}

/// `decimals`: the name of the register giving this one's decimal places; refused beside a
/// scale, an offset, an enum or bits, or on another than a whole integer (the register it
/// names is checked once every register is read, [`Profile::check_decimals`]).
fn decimals(
    s: &Section<'_, '_, '_>,
    kind: Option<Kind>,
    (scale, offset): (f64, f64),
    members: &[(i128, String)],
    bits: Option<(u8, u8)>,
) -> Parsed<Option<String>> {
    let Some(name) = s.string("decimals")? else {
        return Ok(None);
    };
    let refusal = if kind.is_none_or(|k| k.is_float()) {
        Some("an integer register's (u16, i16, u32, i32, u64, i64)")
    } else if scale != 1.0 || offset != 0.0 {
        Some("a register's without scale or offset: the decimals are its scale")
    } else if !members.is_empty() || bits.is_some() {
        Some("a whole number's, not an enum's nor a field of bits'")
    } else {
        None
    };
    match refusal {
        Some(what) => Err(s.fail(
            "decimals",
            s.span_of("decimals"),
            format!("decimal places are {what}"),
        )),
        None => Ok(Some(name.to_string())),
    }
}

/// The largest number bits `first..=last` hold (all of them set), before the shift.
pub(crate) fn field_top(first: u8, last: u8) -> u16 {
    let width = u32::from(last.saturating_sub(first)) + 1;
    u16::MAX.checked_shr(16 - width.min(16)).unwrap_or(u16::MAX)
}

/// The engineering values bits `first..=last` hold, `(low, high)`.
pub(crate) fn field_range(first: u8, last: u8, scale: f64, offset: f64) -> (f64, f64) {
    let top = super::scaled(f64::from(field_top(first, last)), scale) + offset;
    (offset.min(top), offset.max(top))
}

/// A register's `bits`: `[first, last]`, a field of a holding or input register's bits
/// (0..15), read as an unsigned number (type u16).
fn bits(s: &Section<'_, '_, '_>, table: Table, value: ValueType) -> Parsed<Option<(u8, u8)>> {
    let Some(spanned) = s.get("bits") else {
        return Ok(None);
    };
    let span = spanned.span();
    let pair = match spanned.get_ref() {
        DeValue::Array(items) if items.len() == 2 => {
            let int = |v: &Spanned<DeValue<'_>>| match v.get_ref() {
                DeValue::Integer(i) => i128::from_str_radix(i.as_str(), i.radix()).ok(),
                _ => None,
            };
            int(&items[0]).zip(int(&items[1]))
        }
        _ => None,
    };
    let Some((first, last)) = pair else {
        return Err(s.fail(
            "bits",
            span,
            wrong("[first, last]: two bit numbers", spanned.get_ref()),
        ));
    };
    if !(0..=15).contains(&first) || !(0..=15).contains(&last) || first > last {
        return Err(s.fail(
            "bits",
            span,
            format!("must be [first, last], 0 <= first <= last <= 15, got [{first}, {last}]"),
        ));
    }
    if table.holds_bits() || value != ValueType::Number(Kind::U16) {
        return Err(s.fail(
            "bits",
            span,
            "only a u16 on a holding or input register takes bits (a single bit: a bool's bit)",
        ));
    }
    if s.get("order").is_some() {
        return Err(s.fail(
            "order",
            s.span_of("order"),
            "a field of bits has no byte order: its bits are the word's",
        ));
    }
    Ok(Some((first as u8, last as u8)))
}

/// The range of a field of bits (`bits`): `min` / `max` (and `ranges`, and the enum's
/// numbers) within what its bits hold; without them, all it holds.
fn checked_field_range(
    s: &Section<'_, '_, '_>,
    (first, last): (u8, u8),
    (scale, offset): (f64, f64),
    range: (f64, f64),
    ranges: &[(String, (f64, f64))],
    members: &[(i128, String)],
) -> Parsed<(f64, f64)> {
    let top = field_top(first, last);
    let holds_field = field_range(first, last, scale, offset);
    let outside = |key: &str, v: f64| {
        s.fail(
            key,
            s.span_of(key),
            format!(
                "{v} is outside what bits {first}..{last} hold ({} to {})",
                holds_field.0, holds_field.1
            ),
        )
    };
    for (key, given) in [("min", range.0), ("max", range.1)] {
        if s.get(key).is_some() && !holds(holds_field, given) {
            return Err(outside(key, given));
        }
    }
    for (_, (lo, hi)) in ranges {
        for v in [lo, hi] {
            if !holds(holds_field, *v) {
                return Err(outside("ranges", *v));
            }
        }
    }
    if let Some((number, _)) = members.iter().find(|(n, _)| *n > i128::from(top)) {
        return Err(s.fail(
            &format!("enum.{number}"),
            s.span_of("enum"),
            format!("{number} does not fit bits {first}..{last} (0 to {top})"),
        ));
    }
    let min = if s.get("min").is_some() {
        range.0
    } else {
        holds_field.0
    };
    let max = if s.get("max").is_some() {
        range.1
    } else {
        holds_field.1
    };
    Ok((min, max))
}

/// A register's `ranges`: `{ MODEL = [min, max] }`, each within what its type holds.
fn model_ranges(
    s: &Section<'_, '_, '_>,
    kind: Kind,
    scale: f64,
    offset: f64,
) -> Parsed<Vec<(String, (f64, f64))>> {
    let span = s.span_of("ranges");
    let table = match s.get("ranges").map(Spanned::get_ref) {
        None => return Ok(Vec::new()),
        Some(DeValue::Table(t)) if !t.is_empty() => t,
        Some(other) => {
            return Err(s.fail(
                "ranges",
                span,
                wrong("a table { MODEL = [min, max] }", other),
            ))
        }
    };
    let (lo, hi) = full_range(kind, scale, offset);
    let mut out = Vec::with_capacity(table.len());
    for (model, value) in table.iter() {
        let model: &str = model.get_ref();
        // Every item a finite number, or the pair is refused.
        let bounds: Option<Vec<f64>> = match value.get_ref() {
            DeValue::Array(items) => items
                .iter()
                .map(|v| to_number(v.get_ref()).filter(|n| n.is_finite()))
                .collect(),
            _ => None,
        };
        let Some(&[min, max]) = bounds.as_deref() else {
            return Err(s.fail(
                "ranges",
                value.span(),
                format!("{model}: must be [min, max], two numbers"),
            ));
        };
        if min > max || !holds((lo, hi), min) || !holds((lo, hi), max) {
            return Err(s.fail(
                "ranges",
                value.span(),
                format!(
                    "{model}: [{min}, {max}] must be min <= max within what a {} holds \
                     ({lo} to {hi})",
                    kind.name()
                ),
            ));
        }
        out.push((model.to_string(), (min, max)));
    }
    Ok(out)
}

/// The table's name in a profile.
/// How a profile names `access`: "r", "rw", "rw-stopped" (the manuals' W/R*) or "w".
pub(crate) fn access_name(access: Access) -> &'static str {
    match access {
        Access::Read => "r",
        Access::Write => "w",
        Access::ReadWrite => "rw",
        Access::WriteWhenStopped => "rw-stopped",
    }
}

pub(crate) fn table_name(table: Table) -> &'static str {
    match table {
        Table::Holding => "holding",
        Table::Input => "input",
        Table::Coils => "coil",
        Table::Discrete => "discrete",
    }
}

fn value_type(s: &Section<'_, '_, '_>, table: Table) -> Parsed<ValueType> {
    let named = s.string("type")?;
    let value = match named {
        None if table.holds_bits() => ValueType::Bool { bit: None },
        None => ValueType::Number(Kind::U16),
        Some("bool") => ValueType::Bool { bit: None },
        Some("string") => ValueType::Text { length: 0 },
        Some(t) => match Kind::from_name(t).filter(|k| k.name() == t) {
            Some(kind) => ValueType::Number(kind),
            None => {
                return Err(s.fail(
                    "type",
                    s.span_of("type"),
                    format!(
                        "must be one of \"u16\", \"i16\", \"u32\", \"i32\", \"u64\", \"i64\", \
                         \"f32\", \"f64\", \"bool\", \"string\", got {t:?}"
                    ),
                ))
            }
        },
    };
    if table.holds_bits() && !matches!(value, ValueType::Bool { .. }) {
        return Err(s.fail(
            "type",
            s.span_of("type"),
            format!(
                "a {} table holds bits: its type is bool, not {}",
                table_name(table),
                value.name()
            ),
        ));
    }
    let bit = s.int_in("bit", 0, 15)?;
    if bit.is_some() && (table.holds_bits() || !matches!(value, ValueType::Bool { .. })) {
        return Err(s.fail(
            "bit",
            s.span_of("bit"),
            "only a bool on a holding or input register takes a bit",
        ));
    }
    let length = s.int_in("length", 1, 0xFFFF)?;
    match value {
        ValueType::Text { .. } => {
            let length = length.ok_or_else(|| {
                s.fail(
                    "length",
                    s.span.clone(),
                    "missing: a string takes a length (registers)",
                )
            })?;
            Ok(ValueType::Text {
                length: length as u16,
            })
        }
        _ if length.is_some() => Err(s.fail(
            "length",
            s.span_of("length"),
            "only a string takes a length",
        )),
        ValueType::Bool { .. } => Ok(ValueType::Bool {
            bit: bit.map(|b| b as u8),
        }),
        other => Ok(other),
    }
}

/// The engineering range: `min`/`max`, checked against what the type holds.
fn range(s: &Section<'_, '_, '_>, kind: Kind, scale: f64, offset: f64) -> Parsed<(f64, f64)> {
    let (lo, hi) = full_range(kind, scale, offset);
    let min = s.number("min")?;
    let max = s.number("max")?;
    for (key, value) in [("min", min), ("max", max)] {
        if let Some(v) = value {
            if !holds((lo, hi), v) {
                return Err(s.fail(
                    key,
                    s.span_of(key),
                    format!("{v} is outside what a {} holds ({lo} to {hi})", kind.name()),
                ));
            }
        }
    }
    let (min, max) = (min.unwrap_or(lo), max.unwrap_or(hi));
    if min > max {
        return Err(s.fail(
            "min",
            s.span_of("min"),
            format!("min {min} is above max {max}"),
        ));
    }
    Ok((min, max))
}

/// The enum of the register `register`.
fn members(s: &Section<'_, '_, '_>, kind: Kind, register: &str) -> Parsed<Vec<(i128, String)>> {
    let span = s.span_of("enum");
    let table = match s.get("enum").map(Spanned::get_ref) {
        None => return Ok(Vec::new()),
        Some(DeValue::Table(t)) => t,
        Some(other) => return Err(s.fail("enum", span, wrong("a table { 0 = \"name\" }", other))),
    };
    let Some((lo, hi)) = int_range(kind) else {
        return Err(s.fail(
            "enum",
            span,
            format!("a {} register takes no enum", kind.name()),
        ));
    };
    if table.is_empty() {
        return Err(s.fail("enum", span, "must name at least one member"));
    }
    let mut out: Vec<(i128, String)> = Vec::with_capacity(table.len());
    let mut numbers: HashSet<i128> = HashSet::with_capacity(table.len());
    let mut names: HashSet<&str> = HashSet::with_capacity(table.len());
    for (key, value) in table.iter() {
        let text: &str = key.get_ref();
        let key_name = format!("enum.{text}");
        let number = parse_int(text)
            .ok_or_else(|| s.fail(&key_name, key.span(), format!("{text:?} is not an integer")))?;
        if !(lo..=hi).contains(&number) {
            return Err(s.fail(
                &key_name,
                key.span(),
                format!("{number} does not fit a {} ({lo} to {hi})", kind.name()),
            ));
        }
        let DeValue::String(member) = value.get_ref() else {
            return Err(s.fail(&key_name, value.span(), wrong("a name", value.get_ref())));
        };
        if !is_identifier(member) {
            return Err(s.fail(
                &key_name,
                value.span(),
                format!("{member:?} is not a Python identifier"),
            ));
        }
        if let Some(refusal) = s.src.names.member(register, member) {
            return Err(s.fail(&key_name, value.span(), refusal));
        }
        let new_number = numbers.insert(number);
        if !names.insert(member.as_ref()) || !new_number {
            return Err(s.fail(
                &key_name,
                key.span(),
                format!("duplicate member {member:?} = {number}"),
            ));
        }
        out.push((number, member.to_string()));
    }
    out.sort_by_key(|(n, _)| *n);
    Ok(out)
}

/// An integer written as an enum key: decimal (with a sign) or 0x / 0o / 0b.
fn parse_int(text: &str) -> Option<i128> {
    let t = text.replace('_', "");
    let (negative, digits) = match t.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, t.strip_prefix('+').unwrap_or(&t)),
    };
    let (radix, digits) = match digits.get(..2) {
        Some("0x") | Some("0X") => (16, &digits[2..]),
        Some("0o") => (8, &digits[2..]),
        Some("0b") => (2, &digits[2..]),
        _ => (10, digits),
    };
    if digits.is_empty() || digits.starts_with(['+', '-']) {
        return None;
    }
    let v = i128::from_str_radix(digits, radix).ok()?;
    Some(if negative { -v } else { v })
}

fn default(
    s: &Section<'_, '_, '_>,
    value: ValueType,
    (range, scale, offset): ((f64, f64), f64, f64),
    members: &[(i128, String)],
) -> Parsed<Option<ProfileValue>> {
    let Some(given) = s.get("default") else {
        return Ok(None);
    };
    let span = given.span();
    let bad = |message: String| Err(s.fail("default", span.clone(), message));
    let got = given.get_ref();
    match (value, got) {
        (ValueType::Bool { .. }, DeValue::Boolean(b)) => Ok(Some(ProfileValue::Bool(*b))),
        (ValueType::Bool { .. }, other) => bad(wrong("true or false", other)),
        (ValueType::Text { length }, DeValue::String(t)) => {
            if !t.is_ascii() || t.len() > 2 * usize::from(length) {
                bad(format!(
                    "must be ASCII text of at most {} characters",
                    2 * usize::from(length)
                ))
            } else {
                Ok(Some(ProfileValue::Text(t.to_string())))
            }
        }
        (ValueType::Text { .. }, other) => bad(wrong("a string", other)),
        (ValueType::Number(_), DeValue::String(t)) if !members.is_empty() => {
            match members.iter().find(|(_, m)| m == t.as_ref()) {
                Some(_) => Ok(Some(ProfileValue::Text(t.to_string()))),
                None => bad(format!("{t:?} is not a member of the enum")),
            }
        }
        (ValueType::Number(kind), DeValue::Integer(_) | DeValue::Float(_)) => {
            let v = s.number("default")?.unwrap_or(0.0);
            if !members.is_empty() {
                let member = s.int("default").ok().flatten();
                return match member.filter(|n| members.iter().any(|(m, _)| m == n)) {
                    Some(n) => Ok(Some(ProfileValue::Int(n))),
                    None => bad(format!("{v} is not a member of the enum")),
                };
            }
            if v < range.0 || v > range.1 {
                return bad(format!("{v} is outside {} to {}", range.0, range.1));
            }
            let steps = (v - offset) / scale;
            if int_range(kind).is_some() && (steps - steps.round()).abs() > 1e-6 {
                return bad(format!("{v} is not a whole number of steps of {scale}"));
            }
            match (int_range(kind), s.int("default").ok().flatten()) {
                (Some(_), Some(n)) => Ok(Some(ProfileValue::Int(n))),
                _ => Ok(Some(ProfileValue::Float(v))),
            }
        }
        (ValueType::Number(_), other) => bad(wrong("a number", other)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"[device]
name = "XY-MD02"                 # shown in reprs, CLI, errors
description = "RS485 temperature and humidity sensor"

[line]
baudrate = 9600
parity = "N"

[limits]
max_read = 10
max_write = 1
min_write_interval = 0.0
block_reads = true

[[register]]
name = "temperature"
address = 0x0001
table = "input"
type = "i16"
order = "ABCD"
scale = 0.1
unit = "degC"
access = "r"
min = -40.0
max = 125.0
description = "air temperature"

[[register]]
name = "mode"
address = 0x0101
access = "rw"
enum = { 0 = "off", 1 = "heat", 2 = "cool" }
"#;

    #[test]
    fn the_example_parses() {
        let p = Profile::parse("xy.toml", EXAMPLE).unwrap();
        assert_eq!(p.name, "XY-MD02");
        assert_eq!(p.line.baudrate, Some(9600));
        assert_eq!(p.line.parity, Some('N'));
        assert_eq!(p.limits.max_read, Some(10));
        assert_eq!(p.limits.block_reads, Some(true));
        let t = &p.registers[0];
        assert_eq!(t.register.name, "temperature");
        assert_eq!(t.register.address, 1);
        assert_eq!(t.table, Table::Input);
        assert_eq!(t.value, ValueType::Number(Kind::I16));
        assert_eq!(t.register.access, Access::Read);
        assert_eq!(t.register.range, (-40.0, 125.0));
        assert!(t.register.signed);
        assert_eq!(t.line, 15);
        assert!((t.register.decode(0xFFCE) + 5.0).abs() < 1e-9);
        let m = &p.registers[1];
        assert_eq!(m.table, Table::Holding);
        assert_eq!(m.value, ValueType::Number(Kind::U16));
        assert_eq!(m.register.access, Access::ReadWrite);
        assert_eq!(
            m.members,
            vec![(0, "off".into()), (1, "heat".into()), (2, "cool".into())]
        );
    }

    #[test]
    fn a_table_row_and_its_profile_row_are_the_same_register() {
        let row = super::super::pbl::by_name("max_speed").unwrap();
        let text = "[device]\nname = \"pbl\"\n[[register]]\nname = \"max_speed\"\n\
                    address = 124\nunit = \"rpm\"\n";
        let p = Profile::parse("pbl.toml", text).unwrap();
        assert_eq!(&p.registers[0].register, row);
        assert_eq!(
            p.registers[0].register.encode(3000.0).ok(),
            row.encode(3000.0).ok()
        );
    }

    fn error(extra: &str) -> ProfileError {
        let text = format!("[device]\nname = \"d\"\n{extra}");
        *Profile::parse("d.toml", &text).unwrap_err()
    }

    /// `body` after two lines of [device]: the error's line and key.
    fn fails(body: &str, line: usize, key: &str) {
        let e = error(body);
        assert_eq!((e.line, e.key.as_str()), (line, key), "{e}");
        assert!(
            e.to_string()
                .starts_with(&format!("d.toml:{line}: {key}: ")),
            "{e}"
        );
    }

    const R: &str = "[[register]]\nname = \"a\"\naddress = 1\n"; // lines 3..5

    #[test]
    fn unknown_keys_at_every_level() {
        fails("colour = 1\n", 3, "device.colour");
        let e = *Profile::parse("d.toml", "colour = 1\n[device]\nname = \"d\"\n").unwrap_err();
        assert_eq!((e.line, e.key.as_str()), (1, "colour"));
        fails("[line]\nbaud = 1\n", 4, "line.baud");
        fails("[limits]\nmax = 1\n", 4, "limits.max");
        fails(&format!("{R}scal = 1\n"), 6, "register[0].scal");
        let e = *Profile::parse("d.toml", "[device]\nname = \"d\"\nnick = \"x\"\n").unwrap_err();
        assert_eq!((e.line, e.key.as_str()), (3, "device.nick"));
    }

    #[test]
    fn write_multiple_is_a_bool_and_never_goes_with_a_count_echo() {
        let text = "[device]\nname = \"d\"\n[limits]\nwrite_multiple = true\n";
        let p = Profile::parse("d.toml", text).unwrap();
        assert_eq!(p.limits.write_multiple, Some(true));
        assert_eq!(Profile::parse("e.toml", &p.to_toml()).unwrap(), p);
        fails("[limits]\nwrite_multiple = 1\n", 4, "limits.write_multiple");
        fails(
            "[limits]\nwrite_multiple = true\nwrite_echo = \"count\"\n",
            5,
            "limits.write_echo",
        );
        let strict = "[limits]\nwrite_multiple = true\nwrite_echo = \"strict\"\n";
        assert!(Profile::parse("d.toml", &format!("[device]\nname = \"d\"\n{strict}")).is_ok());
    }

    #[test]
    fn what_a_profile_says_of_its_device() {
        let text = "[device]\nname = \"d\"\nmaker = \"Acme\"\nmodel = \"X-1\"\n\
                    kind = \"energy-meter\"\nsource = \"map v2, 1.2\"\n";
        let p = Profile::parse("d.toml", text).unwrap();
        let about = About {
            maker: "Acme".into(),
            model: "X-1".into(),
            kind: "energy-meter".into(),
            source: "map v2, 1.2".into(),
        };
        assert_eq!(p.about, about);
        assert_eq!(Profile::parse("e.toml", &p.to_toml()).unwrap().about, about);
        let silent = Profile::parse("d.toml", "[device]\nname = \"d\"\n").unwrap();
        assert_eq!(silent.about, About::default());
        assert!(!silent.to_toml().contains("kind"));
        for bad in [
            "\"Energy meter\"",
            "\"\"",
            "\"meter_3\"",
            "3",
            "\"-\"",
            "\"a--b\"",
            "\"meter-\"",
            "\"3d-printer\"",
        ] {
            fails(&format!("kind = {bad}\n"), 3, "device.kind");
        }
        fails("maker = 1\n", 3, "device.maker");
    }

    #[test]
    fn missing_required_keys() {
        fails("[[register]]\naddress = 1\n", 3, "register[0].name");
        fails("[[register]]\nname = \"a\"\n", 3, "register[0].address");
        let e = *Profile::parse("d.toml", "[line]\nbaudrate = 9600\n").unwrap_err();
        assert_eq!(e.key, "device");
        let e = *Profile::parse("d.toml", "[device]\ndescription = \"x\"\n").unwrap_err();
        assert_eq!((e.line, e.key.as_str()), (1, "device.name"));
    }

    #[test]
    fn names() {
        fails(
            &format!("{R}[[register]]\nname = \"a\"\naddress = 2\n"),
            7,
            "register[1].name",
        );
        fails(
            "[[register]]\nname = \"2x\"\naddress = 1\n",
            4,
            "register[0].name",
        );
        // A name's form is all the core checks itself; the rules of the language a
        // profile is used from are passed in.
        let text = "[device]\nname = \"d\"\n[[register]]\nname = \"class\"\naddress = 1\n\
                    enum = { 0 = \"mro\" }\n";
        assert!(Profile::parse("d.toml", text).is_ok());
        let refused = *Profile::parse_with("d.toml", text, &Picky).unwrap_err();
        assert_eq!(
            (refused.line, refused.key.as_str()),
            (4, "register[0].name")
        );
        assert_eq!(refused.message, "class: not here");
        let member = text.replace("\"class\"", "\"klass\"");
        let refused = *Profile::parse_with("d.toml", &member, &Picky).unwrap_err();
        assert_eq!(
            (refused.line, refused.key.as_str()),
            (6, "register[0].enum.0")
        );
        assert_eq!(refused.message, "klass.mro: not here");
    }

    /// Rules that refuse the register `class` and the member `mro`.
    struct Picky;

    impl Names for Picky {
        fn register(&self, name: &str) -> Option<String> {
            (name == "class").then(|| format!("{name}: not here"))
        }

        fn member(&self, register: &str, member: &str) -> Option<String> {
            (member == "mro").then(|| format!("{register}.{member}: not here"))
        }
    }

    #[test]
    fn addresses() {
        fails(
            "[[register]]\nname = \"a\"\naddress = 0x10000\n",
            5,
            "register[0].address",
        );
        fails(
            "[[register]]\nname = \"a\"\naddress = -1\n",
            5,
            "register[0].address",
        );
        fails(
            "[[register]]\nname = \"a\"\naddress = 0xFFFF\ntype = \"u32\"\n",
            5,
            "register[0].address",
        );
        fails(
            "[[register]]\nname = \"a\"\naddress = 0xFFFE\ntype = \"string\"\nlength = 3\n",
            5,
            "register[0].address",
        );
        // A u32 at 1 covers 2.
        fails(
            "[[register]]\nname = \"a\"\naddress = 1\ntype = \"u32\"\n\
             [[register]]\nname = \"b\"\naddress = 2\n",
            9,
            "register[1].address",
        );
        // A string of 3 at 10 covers 12.
        fails(
            "[[register]]\nname = \"a\"\naddress = 10\ntype = \"string\"\nlength = 3\n\
             [[register]]\nname = \"b\"\naddress = 12\n",
            10,
            "register[1].address",
        );
        // The same bit twice, or a bit on a register a number uses.
        let bit = |n: &str, b: u8| {
            format!("[[register]]\nname = \"{n}\"\naddress = 5\ntype = \"bool\"\nbit = {b}\n")
        };
        fails(
            &format!("{}{}", bit("a", 1), bit("b", 1)),
            10,
            "register[1].address",
        );
        // A bit beside a number wider than the word, or beside a second whole word.
        let at5 = |text: String| text.replace("\"a\"\naddress = 1\n", "\"c\"\naddress = 5\n");
        fails(
            &at5(format!("{}{R}type = \"u32\"\n", bit("a", 1))),
            10,
            "register[1].address",
        );
        fails(
            &at5(format!("{R}type = \"u32\"\n{}", bit("b", 1))),
            9,
            "register[1].address",
        );
        let word = at5(R.to_string());
        fails(
            &format!("{word}{}{word}", bit("b", 1)).replacen("\"c\"", "\"d\"", 1),
            13,
            "register[2].address",
        );
        // A status word beside its bits, declared before or after them: read once.
        for text in [
            format!("{word}{}", bit("b", 1)),
            format!("{}{word}", bit("b", 1)),
        ] {
            let p = Profile::parse("d.toml", &format!("[device]\nname = \"d\"\n{text}")).unwrap();
            assert_eq!(p.plan(&[0, 1]).len(), 1);
        }
        // A field of bits overlaps a bit or a field it shares a bit with, not the word.
        let field = |n: &str, f: u8, l: u8| {
            format!("[[register]]\nname = \"{n}\"\naddress = 5\nbits = [{f}, {l}]\n")
        };
        fails(
            &format!("{}{}", field("a", 4, 6), bit("b", 6)),
            9,
            "register[1].address",
        );
        fails(
            &format!("{}{}", field("a", 4, 6), field("b", 0, 4)),
            9,
            "register[1].address",
        );
        let text = format!(
            "[device]\nname = \"d\"\n{word}{}{}{}",
            field("f", 4, 6),
            field("g", 0, 3),
            bit("b", 7)
        );
        let p = Profile::parse("d.toml", &text).unwrap();
        assert_eq!(p.registers[1].bits, Some((4, 6)));
        assert_eq!(p.plan(&[0, 1, 2, 3]).len(), 1);
        // Distinct bits share a register; other tables are apart.
        let text = format!("[device]\nname = \"d\"\n{}{}", bit("a", 1), bit("b", 2));
        assert!(Profile::parse("d.toml", &text).is_ok());
        let text = "[device]\nname = \"d\"\n[[register]]\nname = \"a\"\naddress = 1\n\
                    [[register]]\nname = \"b\"\naddress = 1\ntable = \"input\"\n";
        assert!(Profile::parse("d.toml", text).is_ok());
    }

    #[test]
    fn types_and_tables() {
        fails(&format!("{R}type = \"u8\"\n"), 6, "register[0].type");
        fails(
            &format!("{R}table = \"coil\"\ntype = \"u16\"\n"),
            7,
            "register[0].type",
        );
        fails(
            &format!("{R}table = \"discrete\"\ntype = \"f32\"\n"),
            7,
            "register[0].type",
        );
        fails(
            &format!("{R}table = \"holdings\"\n"),
            6,
            "register[0].table",
        );
        fails(
            &format!("{R}table = \"coil\"\nbit = 1\n"),
            7,
            "register[0].bit",
        );
        fails(
            &format!("{R}type = \"u16\"\nbit = 1\n"),
            7,
            "register[0].bit",
        );
        fails(
            &format!("{R}type = \"bool\"\nbit = 16\n"),
            7,
            "register[0].bit",
        );
        // bits: [first, last] within 0..15, on a u16 of a holding or input register.
        for bad in ["3", "[1]", "[2, 1]", "[0, 16]", "[\"a\", 2]"] {
            fails(&format!("{R}bits = {bad}\n"), 6, "register[0].bits");
        }
        for other in ["type = \"i16\"", "type = \"bool\"", "table = \"coil\""] {
            fails(
                &format!("{R}{other}\nbits = [0, 1]\n"),
                7,
                "register[0].bits",
            );
        }
        // Its range, enum and default within what the bits hold.
        fails(
            &format!("{R}bits = [0, 1]\nmax = 4\n"),
            7,
            "register[0].max",
        );
        fails(
            &format!("{R}bits = [0, 1]\nenum = {{ 4 = \"x\" }}\n"),
            7,
            "register[0].enum.4",
        );
        fails(
            &format!("{R}bits = [0, 1]\ndefault = 4\n"),
            7,
            "register[0].default",
        );
        let p = Profile::parse(
            "d.toml",
            &format!("[device]\nname = \"d\"\n{R}bits = [2, 4]\nscale = 0.5\n"),
        )
        .unwrap();
        assert_eq!(p.registers[0].register.range, (0.0, 3.5));
        fails(&format!("{R}type = \"string\"\n"), 3, "register[0].length");
        fails(&format!("{R}length = 2\n"), 6, "register[0].length");
        fails(
            &format!("{R}type = \"bool\"\nscale = 2\n"),
            7,
            "register[0].scale",
        );
        let text = format!("[device]\nname = \"d\"\n{R}table = \"coil\"\n");
        let p = Profile::parse("d.toml", &text).unwrap();
        assert_eq!(p.registers[0].value, ValueType::Bool { bit: None });
        assert_eq!(p.registers[0].register.access, Access::ReadWrite);
    }

    #[test]
    fn access_order_scale() {
        fails(
            &format!("{R}table = \"input\"\naccess = \"rw\"\n"),
            7,
            "register[0].access",
        );
        fails(
            &format!("{R}table = \"discrete\"\naccess = \"w\"\n"),
            7,
            "register[0].access",
        );
        fails(&format!("{R}access = \"x\"\n"), 6, "register[0].access");
        fails(
            &format!("{R}type = \"u32\"\norder = \"ACBD\"\n"),
            7,
            "register[0].order",
        );
        fails(&format!("{R}scale = 0\n"), 6, "register[0].scale");
        fails(&format!("{R}scale = 0.0\n"), 6, "register[0].scale");
        fails(&format!("{R}scale = \"x\"\n"), 6, "register[0].scale");
        fails(&format!("{R}offset = nan\n"), 6, "register[0].offset");
    }

    #[test]
    fn ranges() {
        fails(&format!("{R}min = 10\nmax = 5\n"), 6, "register[0].min");
        fails(&format!("{R}min = -1\n"), 6, "register[0].min");
        fails(&format!("{R}max = 65536\n"), 6, "register[0].max");
        fails(
            &format!("{R}type = \"i16\"\nscale = 0.1\nmax = 3276.8\n"),
            8,
            "register[0].max",
        );
        // Scaled, the range follows the scale.
        let text =
            format!("[device]\nname = \"d\"\n{R}type = \"i16\"\nscale = 0.1\nmax = 3276.7\n");
        assert!(Profile::parse("d.toml", &text).is_ok());
    }

    #[test]
    fn enums() {
        fails(
            &format!("{R}enum = {{ x = \"off\" }}\n"),
            6,
            "register[0].enum.x",
        );
        fails(
            &format!("{R}enum = {{ -1 = \"off\" }}\n"),
            6,
            "register[0].enum.-1",
        );
        fails(
            &format!("{R}type = \"i16\"\nenum = {{ 40000 = \"off\" }}\n"),
            7,
            "register[0].enum.40000",
        );
        fails(
            &format!("{R}enum = {{ 0 = \"2off\" }}\n"),
            6,
            "register[0].enum.0",
        );
        fails(
            &format!("{R}enum = {{ 0 = \"off\", 1 = \"off\" }}\n"),
            6,
            "register[0].enum.1",
        );
        // The same number written twice.
        fails(
            &format!("{R}enum = {{ 0 = \"off\", 0x0 = \"on\" }}\n"),
            6,
            "register[0].enum.0x0",
        );
        fails(&format!("{R}enum = {{ 0 = 1 }}\n"), 6, "register[0].enum.0");
        fails(
            &format!("{R}type = \"f32\"\nenum = {{ 0 = \"off\" }}\n"),
            7,
            "register[0].enum",
        );
        fails(
            &format!("{R}enum = {{ 0 = \"off\" }}\nscale = 0.5\n"),
            6,
            "register[0].enum",
        );
        let text = format!("[device]\nname = \"d\"\n{R}enum = {{ 0x10 = \"hi\", 0 = \"lo\" }}\n");
        let p = Profile::parse("d.toml", &text).unwrap();
        assert_eq!(
            p.registers[0].members,
            vec![(0, "lo".into()), (16, "hi".into())]
        );
    }

    #[test]
    fn defaults() {
        fails(&format!("{R}default = 70000\n"), 6, "register[0].default");
        fails(&format!("{R}default = true\n"), 6, "register[0].default");
        fails(
            &format!("{R}scale = 0.5\ndefault = 1.25\n"),
            7,
            "register[0].default",
        );
        let text = format!("[device]\nname = \"d\"\n{R}scale = 0.5\ndefault = 1.5\n");
        let p = Profile::parse("d.toml", &text).unwrap();
        assert_eq!(p.registers[0].default, Some(ProfileValue::Float(1.5)));
        fails(
            &format!("{R}type = \"bool\"\ndefault = 1\n"),
            7,
            "register[0].default",
        );
        fails(
            &format!("{R}type = \"string\"\nlength = 1\ndefault = \"abc\"\n"),
            8,
            "register[0].default",
        );
        fails(
            &format!("{R}enum = {{ 0 = \"off\" }}\ndefault = \"on\"\n"),
            7,
            "register[0].default",
        );
        fails(
            &format!("{R}enum = {{ 0 = \"off\" }}\ndefault = 3\n"),
            7,
            "register[0].default",
        );
        let text =
            format!("[device]\nname = \"d\"\n{R}enum = {{ 0 = \"off\" }}\ndefault = \"off\"\n");
        let p = Profile::parse("d.toml", &text).unwrap();
        assert_eq!(
            p.registers[0].default,
            Some(ProfileValue::Text("off".into()))
        );
    }

    /// A file of two models, `A` (its rows') and `B`.
    const MODELS: &str = "[device]\nname = \"d\"\nmodels = [\"A\", \"B\"]\n\
        [[register]]\nname = \"x\"\naddress = 1\naccess = \"rw-stopped\"\nmax = 5\n\
        ranges = { B = [1, 3] }\n\
        [[register]]\nname = \"y\"\naddress = 2\nmodels = [\"A\"]\n";

    #[test]
    fn models_ranges_and_rw_stopped() {
        let p = Profile::parse("m.toml", MODELS).unwrap();
        assert_eq!(p.models, ["A", "B"]);
        let x = &p.registers[0];
        assert_eq!(x.register.access, Access::WriteWhenStopped);
        assert_eq!(x.register.range, (0.0, 5.0));
        assert_eq!(x.ranges, vec![("B".to_string(), (1.0, 3.0))]);
        assert_eq!(p.registers[1].models, ["A"]);
        let b = p.for_model("B").unwrap();
        assert_eq!(b.registers.len(), 1);
        assert_eq!(b.registers[0].register.range, (1.0, 3.0));
        assert!(b.models.is_empty() && b.registers[0].ranges.is_empty());
        let a = p.for_model("A").unwrap();
        assert_eq!(a.registers.len(), 2);
        assert_eq!(a.registers[0].register.range, (0.0, 5.0));
        assert!(p.for_model("C").is_none());
        // Written back, it reads the same (rw-stopped, models and ranges too).
        let again = Profile::parse("m.toml", &p.to_toml()).unwrap();
        assert_eq!(again.models, p.models);
        for (x, y) in again.registers.iter().zip(&p.registers) {
            assert_eq!(
                (&x.register, &x.models, &x.ranges),
                (&y.register, &y.models, &y.ranges)
            );
        }
    }

    #[test]
    fn models_misuse() {
        let m = "models = [\"A\"]\n";
        fails(&format!("{R}models = [\"A\"]\n"), 3, "register[0].models");
        let e = error(&format!("{R}models = [\"A\"]\n"));
        assert!(e.message.contains("names none in [device] models"), "{e}");
        let text = format!("[device]\nname = \"d\"\n{m}{R}ranges = {{ B = [0, 1] }}\n");
        let e = *Profile::parse("d.toml", &text).unwrap_err();
        assert_eq!((e.line, e.key.as_str()), (4, "register[0].ranges"), "{e}");
        assert!(e.message.contains("no model \"B\""), "{e}");
        for (extra, key) in [
            ("ranges = { A = [3, 1] }\n", "ranges"),
            ("ranges = { A = [0, 70000] }\n", "ranges"),
            ("ranges = { A = 3 }\n", "ranges"),
            ("ranges = { A = [0, 1, \"x\"] }\n", "ranges"),
            ("ranges = [0, 1]\n", "ranges"),
            ("models = []\n", "models"),
            ("models = [\"A\", \"A\"]\n", "models"),
            ("models = \"A\"\n", "models"),
            ("access = \"stopped\"\n", "access"),
        ] {
            let text = format!("[device]\nname = \"d\"\n{m}{R}{extra}");
            let e = *Profile::parse("d.toml", &text).unwrap_err();
            assert_eq!(e.key, format!("register[0].{key}"), "{extra}: {e}");
        }
        let text =
            format!("[device]\nname = \"d\"\n{m}{R}type = \"bool\"\nranges = {{ A = [0, 1] }}\n");
        let e = *Profile::parse("d.toml", &text).unwrap_err();
        assert!(e.message.contains("takes no ranges"), "{e}");
        fails("models = [1]\n", 3, "device.models");
    }

    #[test]
    fn line_and_limits() {
        fails("[line]\nparity = \"X\"\n", 4, "line.parity");
        fails("[line]\nstopbits = 3\n", 4, "line.stopbits");
        fails("[line]\nbytesize = 9\n", 4, "line.bytesize");
        fails("[line]\nbaudrate = 0\n", 4, "line.baudrate");
        fails("[line]\ntimeout = 0\n", 4, "line.timeout");
        fails("[line]\nframing = \"tcp\"\n", 4, "line.framing");
        fails("[limits]\nmax_read = 0\n", 4, "limits.max_read");
        fails(
            "[limits]\nblock_reads = false\nread_gaps = true\n",
            5,
            "limits.read_gaps",
        );
        fails("[limits]\nmax_write = 2000\n", 4, "limits.max_write");
        fails(
            "[limits]\nmin_write_interval = -1\n",
            4,
            "limits.min_write_interval",
        );
        fails("[limits]\nblock_reads = 1\n", 4, "limits.block_reads");
    }

    #[test]
    fn a_value_one_request_cannot_carry_is_refused() {
        // Lines: [limits] 3, max_read 4, max_write 5, [[register]] 6.
        let limits = "[limits]\nmax_read = 2\nmax_write = 1\n[[register]]\nname = \"a\"\n";
        fails(
            &format!("{limits}address = 0\ntype = \"u64\"\naccess = \"r\"\n"),
            6,
            "register[0].type",
        );
        fails(
            &format!("{limits}address = 0\ntype = \"string\"\nlength = 3\naccess = \"r\"\n"),
            6,
            "register[0].length",
        );
        // Read whole (2), but not written whole (1).
        fails(
            &format!("{limits}address = 0\ntype = \"u32\"\n"),
            6,
            "register[0].type",
        );
        // A register table's own limit applies even where max_read allows more bits.
        fails(
            "[[register]]\nname = \"a\"\naddress = 0\ntype = \"string\"\nlength = 124\n",
            3,
            "register[0].length",
        );
    }

    /// `text` read a run of registers at a time, and read whole.
    fn both_ways(text: &str) -> (Option<Profile>, Parsed<Profile>) {
        let lines = Lines::new(text);
        (
            Profile::parse_in_runs("d.toml", text, &lines, &AnyNames),
            Profile::parse_whole("d.toml", text, &lines, &AnyNames),
        )
    }

    #[test]
    fn read_in_runs_a_profile_is_the_one_read_whole() {
        let register = |n: usize| {
            format!(
                "\n[[register]] # {n}\nname = \"r{n}\"\naddress = {n}\n\
                 description = \"\"\"\n[[register]]\"\"\"\n[register.enum]\n0 = \"off\"\n"
            )
        };
        let many: String = (0..3000).map(register).collect();
        let texts = [
            EXAMPLE.to_string(),
            format!("[device]\nname = \"d\"\n{many}"),
            // Sections after the registers, and keys before any section.
            format!("[limits]\nmax_read = 9\n{many}[device]\nname = \"d\"\n"),
        ];
        for text in &texts {
            let (runs, whole) = both_ways(text);
            let whole = whole.map_err(|e| e.to_string());
            assert!(whole.is_ok(), "{whole:?}");
            assert_eq!(runs.ok_or_else(|| "read whole".to_string()), whole);
        }
        // Eight lines a register, after two of [limits]: its header on its second.
        let (runs, _) = both_ways(&texts[2]);
        let last = runs.as_ref().and_then(|p| p.registers.last());
        assert_eq!(last.map(|r| r.line), Some(3 + 8 * 2999 + 1));
        assert_eq!(runs.map(|p| p.limits.max_read), Some(Some(9)));
    }

    #[test]
    fn a_file_the_runs_cannot_hold_is_read_whole() {
        let text = "[device]\nname = \"d\"\n";
        let register = "[[register]]\nname = \"a\"\naddress = 1\n";
        for other in [
            // A part of the register above after another section.
            format!("{register}[line]\nbaudrate = 9600\n[register.enum]\n0 = \"off\"\n"),
            // The registers as an array of inline tables, or a quoted key.
            "register = [{ name = \"a\", address = 1 }]\n".to_string(),
            "[[\"register\"]]\nname = \"a\"\naddress = 1\n".to_string(),
            // What looks like a header, inside a register's array over several lines.
            format!("{register}x = [\n[[register]]\n]\n"),
        ] {
            let text = format!("{text}{other}");
            let (runs, whole) = both_ways(&text);
            assert!(runs.is_none(), "{text}");
            assert_eq!(
                Profile::parse("d.toml", &text).map_err(|e| e.to_string()),
                whole.map_err(|e| e.to_string())
            );
        }
        // A file with a mistake is read whole: its first mistake, wherever it is, is the one
        // reported (here the [device] without a name before the repeated register).
        let repeated = format!("[device]\n{register}{register}");
        let late_typo = format!("{text}{register}[[register]]\nname = \n");
        let bad_rest = format!("{text}{register}[limits]\nmax_read = 0\n");
        for bad in [&repeated, &late_typo, &bad_rest] {
            let (runs, whole) = both_ways(bad);
            assert!(runs.is_none(), "{bad}");
            assert_eq!(Profile::parse("d.toml", bad).err(), whole.err());
        }
        let first = Profile::parse("d.toml", &repeated).map_err(|e| e.key);
        assert_eq!(first.err().as_deref(), Some("device.name"));
    }

    #[test]
    fn an_offset_is_on_the_line_it_is_in() {
        let lines = Lines::new("ab\n\ncd\n");
        let found: Vec<usize> = (0..=8).map(|at| lines.line(at)).collect();
        // a b \n | \n | c d \n | the end
        assert_eq!(found, vec![1, 1, 1, 2, 3, 3, 3, 4, 4]);
        assert_eq!(Lines::new("").line(0), 1);
    }

    #[test]
    fn bad_toml_names_its_line() {
        let e = error("[[register]]\nname = \n");
        assert_eq!((e.line, e.key.as_str()), (4, ""));
        assert!(e.to_string().starts_with("d.toml:4: "), "{e}");
    }
}
