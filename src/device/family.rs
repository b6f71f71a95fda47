//! The built-in families' register maps: the profile files the Python package ships
//! (`python/benchbus/families/<key>.toml`), built into the core and read once by the one
//! profile parser. A family's module keeps only its manual's rules beside the file.

use super::profile::{Profile, ProfileRegister};
use crate::error::{Error, Result};
use std::sync::OnceLock;

/// The families whose register map is a file, and its text.
const FILES: [(&str, &str); 3] = [
    (
        "drive",
        include_str!("../../python/benchbus/families/drive.toml"),
    ),
    (
        "pbl",
        include_str!("../../python/benchbus/families/pbl.toml"),
    ),
    ("j2", include_str!("../../python/benchbus/families/j2.toml")),
];

/// The text of the file of family `key`, or None for a family without one.
pub fn text(key: &str) -> Option<&'static str> {
    FILES.iter().find(|(k, _)| *k == key).map(|(_, text)| *text)
}

/// The comment lines at the top of family `key`'s file, without their `# `.
pub fn note(key: &str) -> Option<String> {
    let lines = text(key)?.lines().map_while(|l| l.strip_prefix('#'));
    let lines: Vec<&str> = lines.map(|l| l.strip_prefix(' ').unwrap_or(l)).collect();
    Some(lines.join("\n"))
}

/// The profile of family `key`, read from its file the first time it is asked for.
///
/// # Errors
/// [`Error::Internal`] for a key without a file, or a file the parser refuses (a bug the
/// tests catch: the files are part of the build).
pub fn profile(key: &str) -> Result<&'static Profile> {
    static READ: [OnceLock<std::result::Result<Profile, String>>; FILES.len()] =
        [const { OnceLock::new() }; FILES.len()];
    let at = FILES
        .iter()
        .position(|(k, _)| *k == key)
        .ok_or_else(|| Error::Internal(format!("no family file {key:?}")))?;
    let (_, text) = FILES[at];
    READ[at]
        .get_or_init(|| Profile::parse(&format!("<{key}>"), text).map_err(|e| e.to_string()))
        .as_ref()
        .map_err(|e| Error::Internal(format!("the {key} family file: {e}")))
}

/// The registers of family `key`, in its file's order.
///
/// # Errors
/// As [`profile`].
pub fn registers(key: &str) -> Result<&'static [ProfileRegister]> {
    Ok(&profile(key)?.registers)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::profile::ValueType;
    use crate::device::Access;

    #[test]
    fn every_file_reads() {
        for (key, _) in FILES {
            let p = profile(key).unwrap();
            assert!(!p.registers.is_empty(), "{key}");
            assert!(p.line.baudrate.is_some(), "{key}: its line is the file's");
            // A family's set writes whole words: its flags and fields are read-only.
            for r in &p.registers {
                // Families read through their own tables, which know no decimal places.
                assert!(r.decimals.is_none(), "{}", r.register.name);
                let part = r.bits.is_some() || matches!(r.value, ValueType::Bool { .. });
                assert!(
                    !part || r.register.access == Access::Read,
                    "{}",
                    r.register.name
                );
            }
        }
        assert!(text("nope").is_none() && note("nope").is_none());
        let note = note("drive").unwrap();
        assert!(note.starts_with("The drive family") && !note.contains("\n#"));
        assert!(matches!(profile("nope"), Err(Error::Internal(_))));
    }
}
