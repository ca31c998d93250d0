//! Writers: checked output files and standard output, PNG charts, WAV files, file names. No
//! physics here.

pub mod atomic;
pub mod memory;
pub mod npy;
pub mod plot;
pub mod report;
pub mod stdout;
pub mod wav;

/// A file-name-safe version of a user-given name (letters, digits, `-`, `_`, `.` kept).
pub fn file_stem(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect();
    if s.is_empty() { "_".into() } else { s }
}

/// A measured quantity for people to read: at most `digits` significant digits, trailing
/// zeros dropped, so a cell size that went through `f32` prints `0.1`, not
/// `0.10000000149011612`.
pub fn tidy(x: f64, digits: usize) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    let decimals = (digits as i32 - 1 - x.abs().log10().floor() as i32).clamp(0, 15) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

#[cfg(test)]
mod tests {
    use super::tidy;

    #[test]
    fn tidy_numbers_drop_float_noise_and_trailing_zeros() {
        assert_eq!(tidy(f64::from(0.1f32), 6), "0.1");
        assert_eq!(tidy(1.5, 6), "1.5");
        assert_eq!(tidy(2.0, 6), "2");
        assert_eq!(tidy(-93.966_001, 6), "-93.966");
        assert_eq!(tidy(123_456_789.0, 6), "123456789");
        assert_eq!(tidy(0.000_123_456_78, 3), "0.000123");
    }
}
