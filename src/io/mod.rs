//! Writers: checked output files and standard output, PNG charts, WAV files, file names. No
//! physics here.

pub mod atomic;
pub mod memory;
pub mod plot;
pub mod stdout;
pub mod wav;

/// A file-name-safe version of a user-given name (letters, digits, `-`, `_`, `.` kept).
pub fn file_stem(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect();
    if s.is_empty() { "_".into() } else { s }
}
