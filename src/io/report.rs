//! How long work talks to its user: notes and warnings as one line each, and progress over a
//! known amount of work. The command line prints them (and draws progress bars on a
//! terminal); the Python module collects the lines and stays quiet; tests stay silent.

/// A sink for what a running job has to say. Every method does nothing by default.
pub trait Report: Sync {
    /// A decision taken for the user or a part left out (`note: ...`).
    fn note(&self, _line: &str) {}
    /// Something the user should check (`warning: ...`).
    fn warning(&self, _line: &str) {}
    /// A result line (printed on standard output by the command line).
    fn say(&self, _line: &str) {}
    /// Progress over `total` units of `unit` (rays, pixels): the returned counter is told
    /// each finished share; dropping it ends the display.
    fn progress(&self, _total: u64, _unit: &str) -> Box<dyn Counter + '_> {
        Box::new(Silent)
    }
}

/// A progress counter.
pub trait Counter: Sync {
    /// `n` more units are done.
    fn inc(&self, n: u64);
}

/// Says nothing and counts nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Report for Silent {}

impl Counter for Silent {
    fn inc(&self, _n: u64) {}
}

/// Keeps every note and warning, for callers that return them (the Python module).
#[derive(Debug, Default)]
pub struct Collect {
    /// The notes, in order.
    pub notes: std::sync::Mutex<Vec<String>>,
    /// The warnings, in order.
    pub warnings: std::sync::Mutex<Vec<String>>,
}

impl Report for Collect {
    fn note(&self, line: &str) {
        if let Ok(mut v) = self.notes.lock() {
            v.push(line.to_string());
        }
    }

    fn warning(&self, line: &str) {
        if let Ok(mut v) = self.warnings.lock() {
            v.push(line.to_string());
        }
    }
}
