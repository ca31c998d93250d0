//! The memory a job may plan to use: `PROPSIM_MAX_MEMORY_MB` if set, else the machine's
//! available memory (`MemAvailable` in /proc/meminfo). Jobs check their estimate first.

/// Environment variable that caps the memory a job may plan to use, megabytes.
pub const MAX_MEMORY_ENV: &str = "PROPSIM_MAX_MEMORY_MB";

/// `MemAvailable` of a /proc/meminfo text, bytes.
pub fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// The memory budget in bytes and where it comes from; `None` when neither source is known.
pub fn budget() -> Option<(u64, String)> {
    if let Ok(v) = std::env::var(MAX_MEMORY_ENV) {
        let mb: f64 = v.trim().parse().ok().filter(|m: &f64| m.is_finite() && *m > 0.0)?;
        return Some(((mb * 1e6) as u64, format!("{MAX_MEMORY_ENV}={v}")));
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    Some((parse_mem_available(&text)?, "available (MemAvailable in /proc/meminfo)".into()))
}

/// Errors, before the work starts, when `what` needs about `bytes` and that exceeds the
/// budget ([`budget`]).
pub fn check_fits(what: &str, bytes: u64) -> anyhow::Result<()> {
    if let Some((limit, source)) = budget()
        && bytes > limit
    {
        anyhow::bail!(
            "{what} needs about {:.1} GB of memory, more than the {:.1} GB {source}",
            bytes as f64 / 1e9,
            limit as f64 / 1e9
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_mem_available() {
        let text = "MemTotal:       24683520 kB\nMemFree:        21238124 kB\nMemAvailable:   23999872 kB\n";
        assert_eq!(parse_mem_available(text), Some(23_999_872 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 1 kB\n"), None);
    }
}
