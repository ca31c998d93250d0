//! What the command line shows while work runs: notes and warnings on standard error, results
//! on standard output, and progress bars with count and rate (`45,000/100,000 rays, 20k
//! rays/s`) on a terminal; silent bars when standard error is piped or redirected, and on
//! every MPI rank but 0.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressState, ProgressStyle};

use crate::io::report::{Counter, Report};

/// The command line's [`Report`]: `note:` and `warning:` lines, printed results, bars.
#[derive(Clone, Copy, Debug, Default)]
pub struct Terminal;

impl Report for Terminal {
    fn note(&self, line: &str) {
        tell!("note: {line}");
    }

    fn warning(&self, line: &str) {
        tell!("warning: {line}");
    }

    fn say(&self, line: &str) {
        say!("{line}");
    }

    fn progress(&self, total: u64, unit: &str) -> Box<dyn Counter + '_> {
        Box::new(Bar(bar(total, unit)))
    }
}

/// A bar that clears itself when dropped.
struct Bar(ProgressBar);

impl Counter for Bar {
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// `x` with an SI prefix and three significant digits at most: 950, 20.1k, 3.2M.
fn si(x: f64) -> String {
    let (v, p) = match x {
        x if x >= 1e9 => (x / 1e9, "G"),
        x if x >= 1e6 => (x / 1e6, "M"),
        x if x >= 1e3 => (x / 1e3, "k"),
        x => (x, ""),
    };
    let digits = if v >= 100.0 {
        0
    } else if v >= 10.0 {
        1
    } else {
        2
    };
    let s = format!("{v:.digits$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    format!("{s}{p}")
}

/// A bar over `total` units of `unit` with count, rate and ETA, or a hidden one when standard
/// error is not a terminal.
pub fn bar(total: u64, unit: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() || !super::speaks() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(total);
    let unit_name = unit.to_string();
    let template = format!("[{{bar:30}}] {{human_pos}}/{{human_len}} {unit}, {{rate}} {unit}/s, ETA {{eta}}");
    let style = ProgressStyle::with_template(&template)
        .map(|s| {
            s.progress_chars("=> ").with_key("rate", |state: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}", si(state.per_sec()));
            })
        })
        .unwrap_or_else(|_| ProgressStyle::default_bar());
    pb.set_style(style);
    pb.set_message(unit_name);
    pb
}

#[cfg(test)]
mod tests {
    use super::si;

    #[test]
    fn rates_read_like_a_person_writes_them() {
        assert_eq!(si(20_000.0), "20k");
        assert_eq!(si(20_140.0), "20.1k");
        assert_eq!(si(950.0), "950");
        assert_eq!(si(3_210_000.0), "3.21M");
        assert_eq!(si(0.5), "0.5");
    }
}
