//! Every write is checked: an output that cannot be written completely (a full device, a file
//! size limit standing in for a full disk, an unwritable directory, a directory in the way)
//! ends the command with a non-zero exit and one error line naming the file, and leaves no
//! partial or temporary file behind.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::check_one_line_error;

const CANYON: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/street_canyon/scene.toml");

const SHOEBOX: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/shoebox/scene.toml");

const RENDER: [&str; 8] = [
    "render",
    concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/shoebox/scene.toml"),
    "--width",
    "32",
    "--height",
    "32",
    "--spp",
    "1",
];

fn render_to(out: &Path) -> Vec<String> {
    RENDER.iter().map(|s| s.to_string()).chain(["-o".into(), out.display().to_string()]).collect()
}

fn run(args: &[String]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_propsim")).args(args).output().expect("the binary runs");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into())
}

fn assert_fails_naming(args: &[String], needles: &[&str]) {
    let (ok, err) = run(args);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    check_one_line_error(&args, ok, &err, needles);
}

/// Every file under `dir`, recursively.
fn files(dir: &Path) -> Vec<String> {
    let mut all = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                all.extend(files(&p));
            } else {
                all.push(p.display().to_string());
            }
        }
    }
    all
}

fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() == 0 }
}

#[test]
fn a_path_under_a_device_or_a_file_is_refused_before_the_work() {
    let out = Path::new("/dev/full/x.png");
    assert_fails_naming(&render_to(out), &["/dev/full/x.png", "not a directory"]);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("file");
    std::fs::write(&file, "").unwrap();
    let out = file.join("sub/x.png");
    assert_fails_naming(&render_to(&out), &[&out.display().to_string()]);
    let rf_out = file.join("rf");
    let args: Vec<String> =
        ["rf", CANYON, "--rays", "2000", "--out", rf_out.to_str().unwrap()].map(String::from).into();
    assert_fails_naming(&args, &[&rf_out.display().to_string()]);
    assert_eq!(files(dir.path()), vec![file.display().to_string()], "nothing else written");
}

#[test]
fn an_unwritable_directory_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    // Root ignores permissions: there, a parent that is a regular file stands in.
    let (locked, out) = if is_root() {
        let f = dir.path().join("locked");
        std::fs::write(&f, "").unwrap();
        (f.clone(), f.join("render.png"))
    } else {
        use std::os::unix::fs::PermissionsExt as _;
        let d = dir.path().join("locked");
        std::fs::create_dir(&d).unwrap();
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o555)).unwrap();
        (d.clone(), d.join("render.png"))
    };
    assert_fails_naming(&render_to(&out), &[&out.display().to_string()]);
    let ac = locked.join("acoustic");
    let args: Vec<String> =
        ["acoustic", SHOEBOX, "--rays", "2000", "--out", ac.to_str().unwrap()].map(String::from).into();
    assert_fails_naming(&args, &[&ac.display().to_string()]);
    assert!(!out.exists() && !ac.exists());
    if locked.is_dir() {
        assert!(files(&locked).is_empty());
    }
}

#[test]
fn a_directory_in_the_way_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    std::fs::create_dir(&out).unwrap();
    assert_fails_naming(&render_to(&out), &[&out.display().to_string(), "is a directory"]);
    let file = dir.path().join("rf_out");
    std::fs::write(&file, "keep").unwrap();
    let args: Vec<String> =
        ["rf", CANYON, "--rays", "2000", "--out", file.to_str().unwrap()].map(String::from).into();
    assert_fails_naming(&args, &[&file.display().to_string(), "not a directory"]);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
    assert!(files(dir.path()).len() == 1, "{:?}", files(dir.path()));
}

#[test]
fn a_full_device_behind_a_link_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("render.png");
    std::os::unix::fs::symlink("/dev/full", &link).unwrap();
    assert_fails_naming(&render_to(&link), &[&link.display().to_string(), "No space left on device"]);
    assert_eq!(files(dir.path()), vec![link.display().to_string()]);
    assert!(Path::new("/dev/full").exists(), "the device is left alone");
}

/// Runs `propsim ARGS` with a file size limit of `bytes` (writes beyond it fail with EFBIG, as
/// on a full disk, instead of raising SIGXFSZ).
fn run_with_size_limit(args: &[String], bytes: u64) -> (bool, String) {
    use std::os::unix::process::CommandExt as _;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_propsim"));
    cmd.args(args);
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(move || {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let lim = libc::rlimit { rlim_cur: bytes as libc::rlim_t, rlim_max: bytes as libc::rlim_t };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let out = cmd.output().expect("the binary runs");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into())
}

#[test]
fn a_write_cut_short_leaves_no_partial_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let args = render_to(&out);
    let (ok, err) = run_with_size_limit(&args, 100);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    check_one_line_error(&a, ok, &err, &[&format!("cannot write {}", out.display()), "too large"]);
    assert!(files(dir.path()).is_empty(), "{:?}", files(dir.path()));

    let ac = dir.path().join("acoustic");
    let args: Vec<String> =
        ["acoustic", SHOEBOX, "--rays", "2000", "--out", ac.to_str().unwrap()].map(String::from).into();
    let (ok, err) = run_with_size_limit(&args, 4096);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    check_one_line_error(&a, ok, &err, &["cannot write", &ac.display().to_string()]);
    let left = files(dir.path());
    assert!(left.iter().all(|f| !f.contains(".tmp-")), "temporary files left: {left:?}");
    for f in &left {
        assert!(std::fs::metadata(f).unwrap().len() <= 4096, "{f}");
    }
}

#[test]
fn standard_output_on_a_full_device_is_an_error() {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_propsim"))
        .args(["info", "builtin:shoebox", "--json"])
        .stdout(full)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    check_one_line_error(
        &["info", "--json"],
        out.status.success(),
        &err,
        &["standard output", "No space left"],
    );
}

/// Standard error on a full device: warnings and errors cannot be shown, but nothing panics,
/// a good run still succeeds and a bad one still fails (not with a panic's 101).
#[test]
fn standard_error_on_a_full_device_changes_no_exit_status() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        Command::new(env!("CARGO_BIN_EXE_propsim")).args(args).stderr(full).output().unwrap().status
    };
    let out = dir.path().join("a");
    // Few rays: the run warns about few detections on standard error.
    let ok = run(&["acoustic", "builtin:shoebox", "--rays", "300", "--out", out.to_str().unwrap()]);
    assert!(ok.success(), "{ok:?}");
    for bad in
        [&["info", "/no/such/room.obj"][..], &["acoustic", "builtin:shoebox", "--rays", "0"], &["nonsense"]]
    {
        let status = run(bad);
        assert!(
            !status.success() && status.code() != Some(101) && status.code().is_some(),
            "{bad:?}: {status:?}"
        );
    }
}

#[test]
fn a_closed_pipe_ends_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_propsim"))
        .args(["info", "builtin:bras_cr2", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked") && !err.contains("error"), "{err}");
}
