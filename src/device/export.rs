//! Profiles written out: [`Profile::to_toml`] gives the text [`Profile::parse`] reads back
//! as the same profile, and [`Profile::family`] describes a built-in family as a profile:
//! the family's file ([`family`]), or for "drive-c20" the drive file's C20 model. What a
//! file cannot say (the J2's rules, the drive's write enable and its Fgg.nn parameters)
//! stays code, said in the file's own comments ([`family_note`] puts them at the top of
//! the C20's export).

use super::drive::{self, Family};
use super::profile::{
    access_name, echo_name, field_range, full_range, table_name, Limits, LineSettings, Profile,
    ProfileRegister, ProfileValue, ValueType,
};
use super::value::{Kind, Layout};
use super::{family, Table};
use std::fmt::Write as _;

/// The keys of the built-in families [`Profile::family`] knows: "drive" (BLD2 / BLD3H,
/// manual 000), "drive-c20" (ZBLD.C20, manual 001: other ranges, fewer registers), "pbl"
/// and "j2".
pub const FAMILIES: [&str; 4] = ["drive", "drive-c20", "pbl", "j2"];

/// A string as TOML writes it: quoted, with `"`, `\` and control characters escaped.
fn quote(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A number as TOML writes it, read back as the same f64: a whole number as an integer,
/// anything else as the shortest float that parses back to it.
fn number(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        float(v)
    }
}

/// A float as TOML writes it, always with a fraction or an exponent ("2.0", "1e-7").
fn float(v: f64) -> String {
    format!("{v:?}")
}

fn value(v: &ProfileValue) -> String {
    match v {
        ProfileValue::Int(n) => n.to_string(),
        ProfileValue::Float(f) => float(*f),
        ProfileValue::Bool(b) => b.to_string(),
        ProfileValue::Text(t) => quote(t),
    }
}

impl Profile {
    /// The profile as a TOML file: [`Profile::parse`] reads it back as the same profile
    /// (the registers' lines aside). Keys at their defaults are left out.
    pub fn to_toml(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "[device]\nname = {}", quote(&self.name));
        if !self.description.is_empty() {
            let _ = writeln!(out, "description = {}", quote(&self.description));
        }
        if !self.models.is_empty() {
            let _ = writeln!(out, "models = {}", strings(&self.models));
        }
        let a = &self.about;
        for (key, text) in [
            ("maker", &a.maker),
            ("model", &a.model),
            ("kind", &a.kind),
            ("source", &a.source),
        ] {
            if !text.is_empty() {
                let _ = writeln!(out, "{key} = {}", quote(text));
            }
        }
        line_section(&mut out, &self.line);
        limits_section(&mut out, &self.limits);
        for r in &self.registers {
            register(&mut out, r);
        }
        out
    }

    /// The built-in family `key` (one of [`FAMILIES`]) as a profile: its file (the drive's
    /// with both models), or for "drive-c20" the C20's rows of the drive's file. None for
    /// another key.
    pub fn family(key: &str) -> Option<Profile> {
        match key {
            "drive-c20" => drive::table(Family::C20).ok().cloned(),
            _ => family::profile(key).ok().cloned(),
        }
    }
}

/// What the built-in family `key` does in code that its exported profile cannot say, as
/// lines for the top of the file: for "drive-c20", made from the drive's file, the top of
/// that file; None for another key (a family's file says it in its own comments).
pub fn family_note(key: &str) -> Option<String> {
    if key != "drive-c20" {
        return None;
    }
    let note = family::note("drive")?;
    Some(format!(
        "The C20's rows of the drive family's file (families/drive.toml).\n{note}"
    ))
}

fn line_section(out: &mut String, l: &LineSettings) {
    let keys = [
        ("baudrate", l.baudrate.map(|b| b.to_string())),
        ("parity", l.parity.map(|p| quote(&p.to_string()))),
        ("stopbits", l.stopbits.map(|s| s.to_string())),
        ("timeout", l.timeout.map(number)),
        ("framing", l.framing.as_deref().map(quote)),
        ("bytesize", l.bytesize.map(|b| b.to_string())),
    ];
    section(out, "[line]", keys);
}

fn limits_section(out: &mut String, l: &Limits) {
    let keys = [
        ("max_read", l.max_read.map(|n| n.to_string())),
        ("max_write", l.max_write.map(|n| n.to_string())),
        ("min_write_interval", l.min_write_interval.map(number)),
        ("block_reads", l.block_reads.map(|b| b.to_string())),
        ("read_gaps", l.read_gaps.map(|b| b.to_string())),
        ("write_echo", l.write_echo.map(|e| quote(echo_name(e)))),
        ("write_multiple", l.write_multiple.map(|b| b.to_string())),
    ];
    section(out, "[limits]", keys);
}

/// The section `header` with each key that has a value, as TOML; nothing if none has.
fn section<const N: usize>(out: &mut String, header: &str, keys: [(&str, Option<String>); N]) {
    let mut keys = keys
        .into_iter()
        .filter_map(|(key, value)| Some((key, value?)));
    if let Some((key, value)) = keys.next() {
        let _ = writeln!(out, "\n{header}\n{key} = {value}");
        for (key, value) in keys {
            let _ = writeln!(out, "{key} = {value}");
        }
    }
}

fn register(out: &mut String, r: &ProfileRegister) {
    let reg = &r.register;
    let _ = writeln!(out, "\n[[register]]\nname = {}", quote(&reg.name));
    let _ = writeln!(out, "address = 0x{:04X}  # {}", reg.address, reg.address);
    if r.table != Table::Holding {
        let _ = writeln!(out, "table = {}", quote(table_name(r.table)));
    }
    let default_type = if r.table.holds_bits() {
        ValueType::Bool { bit: None }
    } else {
        ValueType::Number(Kind::U16)
    };
    let bool_type = matches!(r.value, ValueType::Bool { .. });
    if r.value != default_type && !(bool_type && r.table.holds_bits()) {
        let _ = writeln!(out, "type = {}", quote(r.value.name()));
    }
    match r.value {
        ValueType::Bool { bit: Some(b) } => {
            let _ = writeln!(out, "bit = {b}");
        }
        ValueType::Text { length } => {
            let _ = writeln!(out, "length = {length}");
        }
        _ => {}
    }
    if let Some((first, last)) = r.bits {
        let _ = writeln!(out, "bits = [{first}, {last}]");
    }
    if r.layout != Layout::Abcd {
        let _ = writeln!(out, "order = {}", quote(r.layout.name()));
    }
    if reg.scale != 1.0 {
        let _ = writeln!(out, "scale = {}", number(reg.scale));
    }
    if r.offset != 0.0 {
        let _ = writeln!(out, "offset = {}", number(r.offset));
    }
    if let Some(name) = &r.decimals {
        let _ = writeln!(out, "decimals = {}", quote(name));
    }
    if !reg.unit.is_empty() {
        let _ = writeln!(out, "unit = {}", quote(&reg.unit));
    }
    // Written where it is not the table's default: "r" for input registers and discrete
    // inputs, "rw" for the rest.
    let access = access_name(reg.access);
    let default = if matches!(r.table, Table::Input | Table::Discrete) {
        "r"
    } else {
        "rw"
    };
    if access != default {
        let _ = writeln!(out, "access = {}", quote(access));
    }
    if let ValueType::Number(kind) = r.value {
        let (lo, hi) = match r.bits {
            Some((first, last)) => field_range(first, last, reg.scale, r.offset),
            None => full_range(kind, reg.scale, r.offset),
        };
        if reg.range.0 != lo {
            let _ = writeln!(out, "min = {}", number(reg.range.0));
        }
        if reg.range.1 != hi {
            let _ = writeln!(out, "max = {}", number(reg.range.1));
        }
    }
    if !r.members.is_empty() {
        let members: Vec<String> = r
            .members
            .iter()
            .map(|(n, m)| format!("{n} = {}", quote(m)))
            .collect();
        let _ = writeln!(out, "enum = {{ {} }}", members.join(", "));
    }
    if let Some(d) = &r.default {
        let _ = writeln!(out, "default = {}", value(d));
    }
    if !r.models.is_empty() {
        let _ = writeln!(out, "models = {}", strings(&r.models));
    }
    if !r.ranges.is_empty() {
        let ranges: Vec<String> = r
            .ranges
            .iter()
            .map(|(m, (lo, hi))| format!("{} = [{}, {}]", key(m), number(*lo), number(*hi)))
            .collect();
        let _ = writeln!(out, "ranges = {{ {} }}", ranges.join(", "));
    }
    if !r.description.is_empty() {
        let _ = writeln!(out, "description = {}", quote(&r.description));
    }
}

/// Strings as a TOML array.
fn strings(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|i| quote(i)).collect();
    format!("[{}]", quoted.join(", "))
}

/// A TOML key: bare where it can be, else quoted.
fn key(name: &str) -> String {
    let bare = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare {
        name.to_string()
    } else {
        quote(name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `p` with every register's line set to 0: what a round trip cannot keep.
    fn lineless(mut p: Profile) -> Profile {
        for r in &mut p.registers {
            r.line = 0;
        }
        p
    }

    /// Writes `p`, reads it back: the same profile, and the same text when written again.
    fn round_trip(p: &Profile) {
        let text = p.to_toml();
        let back = Profile::parse("out.toml", &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(lineless(back.clone()), lineless(p.clone()), "{text}");
        assert_eq!(back.to_toml(), text);
    }

    #[test]
    fn the_example_profiles_come_back_the_same() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/profiles");
        let mut seen = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                round_trip(&Profile::load(&path).unwrap());
                seen += 1;
            }
        }
        assert_eq!(seen, 3);
    }

    const EDGES: &str = r#"[device]
name = "Edge \"cases\" \\ é"
description = "line one\nline two\ttab \u0001"

[line]
baudrate = 115200
parity = "E"
stopbits = 2
timeout = 0.35
framing = "ascii"
bytesize = 7

[limits]
max_read = 2000
max_write = 4
min_write_interval = 0.15
block_reads = false

[[register]]
name = "temp"
address = 0
table = "input"
type = "i16"
scale = 0.1
offset = -40.5
unit = "°C"
min = -50.0
max = 100.0
default = 21.5

[[register]]
name = "big"
address = 0x10
type = "f64"
order = "DCBA"
scale = 1e-7
default = 3.0

[[register]]
name = "count"
address = 0x20
type = "u64"
order = "BADC"
access = "r"
default = 18446744073709551615

[[register]]
name = "level"
address = 0x30
type = "i32"
order = "CDAB"
min = -2147483648
max = 5
default = -7

[[register]]
name = "whole_float"
address = 0x32
default = 2.0

[[register]]
name = "mode"
address = 0x40
type = "i16"
enum = { -1 = "back", 0 = "off", 0x10 = "hi" }
default = "hi"

[[register]]
name = "step"
address = 0x41
enum = { 3 = "three" }
access = "w"
default = 3

[[register]]
name = "label"
address = 0x50
type = "string"
length = 4
default = "a\"b"
description = "with a quote"

[[register]]
name = "flag_a"
address = 0x60
type = "bool"
bit = 0
default = true

[[register]]
name = "flag_b"
address = 0x60
type = "bool"
bit = 15
access = "r"

[[register]]
name = "source"
address = 0x60
bits = [4, 6]
enum = { 0 = "off", 5 = "auto" }

[[register]]
name = "stage"
address = 0x60
bits = [8, 11]
scale = 0.5
max = 6
access = "r"

[[register]]
name = "whole"
address = 0x61
type = "bool"

[[register]]
name = "relay"
address = 0
table = "coil"
access = "w"

[[register]]
name = "door"
address = 0
table = "discrete"
default = false

[[register]]
name = "wide"
address = 2
table = "input"
type = "f32"
max = 1e30
default = -2.5e-8
"#;

    #[test]
    fn hand_made_edge_cases_come_back_the_same() {
        let p = Profile::parse("edges.toml", EDGES).unwrap();
        assert_eq!(p.registers.len(), 16);
        round_trip(&p);
        let empty = Profile::parse("e.toml", "[device]\nname = \"e\"\n").unwrap();
        round_trip(&empty);
        assert_eq!(empty.to_toml(), "[device]\nname = \"e\"\n");
    }

    #[test]
    fn every_family_comes_back_the_same() {
        for key in FAMILIES {
            let p = Profile::family(key).unwrap();
            assert!(!p.registers.is_empty());
            round_trip(&p);
            // A family without a file says in a note what stays code; a file in comments.
            assert!(
                family_note(key).is_some() != family::text(key).is_some(),
                "{key}"
            );
            assert!(
                family::text(key).is_none_or(|t| t.starts_with("# ")),
                "{key}"
            );
        }
        assert_eq!(Profile::family("atv31"), None);
        assert_eq!(family_note("atv31"), None);
    }

    #[test]
    fn the_c20_export_is_the_c20_rows_of_the_drive_file() {
        let c20 = Profile::family("drive-c20").unwrap();
        assert_eq!(c20, drive::table(Family::C20).unwrap().clone());
        assert!(c20.models.is_empty() && c20.registers.iter().all(|r| r.models.is_empty()));
        let note = family_note("drive-c20").unwrap();
        assert!(note.contains("C20's rows") && note.contains("Fgg.nn"));
        assert_eq!(family_note("drive"), None);
    }

    #[test]
    fn text_is_quoted_for_toml() {
        assert_eq!(quote("a\"b\\c\n\u{1}°"), "\"a\\\"b\\\\c\\n\\u0001°\"");
        assert_eq!(number(3.0), "3");
        assert_eq!(number(0.1), "0.1");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(float(2.0), "2.0");
    }
}
