//! Checked, all-or-nothing output files.
//!
//! Every file propsim writes goes through [`write_atomically`]: the bytes go to a temporary
//! file beside the target, which is renamed over the target only once everything has been
//! written and flushed. A full disk, an unwritable directory or a target that is a directory
//! gives one error naming the target and the cause, and leaves neither a partial file nor the
//! temporary one behind.

use std::fs::{self, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes the temporary files of one process writing several outputs at once.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` with `write`, all or nothing. The error, if any, reads
/// `cannot write PATH: CAUSE` on one line.
///
/// A target that exists and is not a regular file (a device such as `/dev/stdout`, a FIFO)
/// is written in place, as there is nothing to rename over; a symbolic link is followed, so
/// that the file it points to is replaced and the link kept.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    write_inner(path, write).map_err(|e| anyhow::anyhow!("cannot write {}: {}", path.display(), one_line(&e)))
}

/// Writes `bytes` to `path`, all or nothing (see [`write_atomically`]).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    write_atomically(path, |w| Ok(w.write_all(bytes)?))
}

/// The causes of `e` on one line.
fn one_line(e: &anyhow::Error) -> String {
    format!("{e:#}").replace('\n', " ")
}

fn write_inner(path: &Path, write: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>) -> anyhow::Result<()> {
    if path.as_os_str().is_empty() {
        anyhow::bail!("empty file name");
    }
    let mut target = path.to_path_buf();
    if let Ok(meta) = fs::symlink_metadata(path) {
        if meta.file_type().is_symlink()
            && let Ok(real) = fs::canonicalize(path)
        {
            target = real;
        }
        match fs::metadata(&target) {
            Ok(m) if m.is_dir() => anyhow::bail!("is a directory"),
            Ok(m) if !m.is_file() => return write_in_place(&target, write),
            _ => {}
        }
    }
    let tmp = temp_name(&target)?;
    let file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
    let result = (|| -> anyhow::Result<()> {
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        // Some file systems report a failed write only when the file is closed.
        drop(file);
        fs::rename(&tmp, &target)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Checks, before a long computation, that `path` can be written: a file (`dir == false`)
/// whose name is not a directory, or a directory (`dir == true`), under a directory this
/// process can create files in. Missing directories on the way are fine (they are created
/// when writing) as long as the nearest existing one is a writable directory. Nothing is left
/// behind. The error reads `cannot write PATH: CAUSE`. A full disk shows only when writing.
pub fn check_writable(path: &Path, dir: bool) -> anyhow::Result<()> {
    let fail = |cause: String| anyhow::anyhow!("cannot write {}: {cause}", path.display());
    let existing = fs::metadata(path).ok();
    match &existing {
        Some(m) if !dir && m.is_dir() => return Err(fail("is a directory".into())),
        Some(m) if dir && !m.is_dir() => return Err(fail("not a directory".into())),
        Some(m) if !dir && !m.is_file() => return Ok(()), // a device or FIFO: written in place
        _ => {}
    }
    let mut probe_dir = if dir { path } else { path.parent().unwrap_or(Path::new("")) };
    loop {
        let d = if probe_dir.as_os_str().is_empty() { Path::new(".") } else { probe_dir };
        match fs::metadata(d) {
            Ok(m) if m.is_dir() => {
                let probe = d.join(format!(
                    ".propsim-probe-{}-{}",
                    std::process::id(),
                    COUNTER.fetch_add(1, Ordering::Relaxed)
                ));
                OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(&probe)
                    .map_err(|e| fail(e.to_string()))?;
                let _ = fs::remove_file(&probe);
                return Ok(());
            }
            Ok(_) => return Err(fail(format!("{} is not a directory", d.display()))),
            Err(e) if e.kind() == io::ErrorKind::NotFound => match probe_dir.parent() {
                Some(p) => probe_dir = p,
                None => return Err(fail(e.to_string())),
            },
            Err(e) => return Err(fail(e.to_string())),
        }
    }
}

/// A device or FIFO: written directly, flushed, errors checked.
fn write_in_place(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let file = OpenOptions::new().write(true).truncate(true).open(path)?;
    let mut w = BufWriter::new(file);
    write(&mut w)?;
    w.flush()?;
    Ok(())
}

/// `DIR/.NAME.tmp-PID-N` beside `path`.
fn temp_name(path: &Path) -> io::Result<PathBuf> {
    let name =
        path.file_name().ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp = std::ffi::OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".tmp-{}-{n}", std::process::id()));
    Ok(path.with_file_name(tmp))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_target_and_leaves_no_temporary_file() -> anyhow::Result<()> {
        let dir = tempfile::tempdir()?;
        let p = dir.path().join("a.txt");
        fs::write(&p, "old")?;
        write_bytes(&p, b"new")?;
        assert_eq!(fs::read_to_string(&p)?, "new");
        assert_eq!(fs::read_dir(dir.path())?.count(), 1);
        Ok(())
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_names_the_target() -> anyhow::Result<()> {
        let dir = tempfile::tempdir()?;
        let p = dir.path().join("a.txt");
        fs::write(&p, "old")?;
        let e = write_atomically(&p, |w| {
            w.write_all(b"partial")?;
            anyhow::bail!("disk on fire")
        })
        .unwrap_err();
        assert_eq!(e.to_string(), format!("cannot write {}: disk on fire", p.display()));
        assert_eq!(fs::read_to_string(&p)?, "old");
        assert_eq!(fs::read_dir(dir.path())?.count(), 1);
        Ok(())
    }

    #[test]
    fn refuses_a_directory_and_a_path_under_a_file() -> anyhow::Result<()> {
        let dir = tempfile::tempdir()?;
        let e = write_bytes(dir.path(), b"x").unwrap_err().to_string();
        assert!(e.starts_with("cannot write ") && e.ends_with("is a directory"), "{e}");
        let f = dir.path().join("f");
        fs::write(&f, "")?;
        let e = write_bytes(&f.join("x"), b"x").unwrap_err().to_string();
        assert!(e.starts_with(&format!("cannot write {}", f.join("x").display())), "{e}");
        assert_eq!(fs::read_dir(dir.path())?.count(), 1);
        Ok(())
    }

    #[test]
    fn a_full_device_is_an_error() {
        if Path::new("/dev/full").exists() {
            let e = write_bytes(Path::new("/dev/full"), &[0u8; 100_000]).unwrap_err().to_string();
            assert!(e.starts_with("cannot write /dev/full: "), "{e}");
        }
    }
}
