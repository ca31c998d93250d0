//! Checked standard output. `println!` panics when standard output cannot be written (a full
//! disk behind `> file`); [`print()`] records the first failure instead, stops writing, and
//! [`finish`] reports it once the command is done, so that the command ends with one error
//! line and a non-zero exit.

use std::fmt;
use std::io::{self, Write};
use std::sync::Mutex;

/// The first error met writing standard output.
static FAILED: Mutex<Option<io::Error>> = Mutex::new(None);

/// Writes `args` to standard output unless an earlier write failed; a failure is kept for
/// [`finish`].
pub fn print(args: fmt::Arguments) {
    let mut failed = FAILED.lock().unwrap_or_else(|e| e.into_inner());
    if failed.is_some() {
        return;
    }
    if let Err(e) = io::stdout().lock().write_fmt(args) {
        *failed = Some(e);
    }
}

/// Flushes standard output and returns the first error met writing it, if any.
pub fn finish() -> io::Result<()> {
    let mut failed = FAILED.lock().unwrap_or_else(|e| e.into_inner());
    if failed.is_none()
        && let Err(e) = io::stdout().lock().flush()
    {
        *failed = Some(e);
    }
    match failed.take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Checked `print!`.
#[macro_export]
macro_rules! out {
    ($($t:tt)*) => { $crate::io::stdout::print(format_args!($($t)*)) };
}

/// Checked `println!`.
#[macro_export]
macro_rules! outln {
    () => { $crate::io::stdout::print(format_args!("\n")) };
    ($($t:tt)*) => { $crate::io::stdout::print(format_args!("{}\n", format_args!($($t)*))) };
}

/// Writes `args` to standard error, ignoring a failure: `eprintln!` panics when standard error
/// cannot be written (`2>/dev/full`), and there is nowhere else to say anything.
pub fn print_err(args: fmt::Arguments) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// `eprintln!` that never panics.
#[macro_export]
macro_rules! errln {
    ($($t:tt)*) => { $crate::io::stdout::print_err(format_args!("{}\n", format_args!($($t)*))) };
}
