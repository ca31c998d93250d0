//! The Python module for real: creates a virtual environment under `target/python-venv`
//! (installing Debian's python3-venv when the venv module is missing), installs maturin,
//! pytest and numpy into it, then `pip install ./python` (built in `target/python`, so a
//! second run only rebuilds what changed) and runs the module's pytest suite
//! (python/tests/test_propsim.py), which checks it against closed forms and the CLI.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const MANIFEST_DIR: &str = env!("CARGO_MANIFEST_DIR");

/// What the suite needs in the environment, besides the module itself.
const PYTHON_PACKAGES: [&str; 3] = ["maturin>=1.5,<2", "pytest", "numpy"];

fn on_path(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The Python interpreter: `PYTHON` if set, else python3.
fn python() -> String {
    std::env::var("PYTHON").unwrap_or_else(|_| "python3".into())
}

fn has_venv_module() -> bool {
    // `ensurepip` is the part Debian splits off into python3-venv.
    Command::new(python()).args(["-c", "import venv, ensurepip"]).output().is_ok_and(|o| o.status.success())
}

/// Installs Debian's python3-venv with apt-get unless the venv module works already.
fn ensure_venv_module() {
    if has_venv_module() {
        return;
    }
    assert!(
        on_path("apt-get"),
        "python3 has no venv module and apt-get is not available: install python3-venv"
    );
    let sudo = if Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() != "0")
    {
        "sudo "
    } else {
        ""
    };
    let script = format!(
        "{sudo}apt-get update -qq && DEBIAN_FRONTEND=noninteractive {sudo}apt-get install -y -qq --no-install-recommends python3-venv"
    );
    let out = Command::new("sh").args(["-c", &script]).output().expect("sh runs");
    assert!(
        out.status.success(),
        "installing python3-venv failed: {}",
        String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
    );
    assert!(has_venv_module(), "the venv module is still missing after installing python3-venv");
}

/// Runs `cmd`, asserting success and showing its output otherwise.
fn check(what: &str, cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    assert!(
        out.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The virtual environment with the suite's packages, created once and then reused.
fn venv(target: &Path) -> PathBuf {
    let venv = target.join("python-venv");
    let bin = venv.join("bin");
    if !bin.join("python").exists() {
        ensure_venv_module();
        check("python3 -m venv", Command::new(python()).args(["-m", "venv"]).arg(&venv));
    }
    let ready = Command::new(bin.join("python"))
        .args(["-c", "import maturin, pytest, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ready {
        check(
            "pip install maturin pytest numpy",
            Command::new(bin.join("pip"))
                .args(["install", "-q", "--disable-pip-version-check"])
                .args(PYTHON_PACKAGES),
        );
    }
    venv
}

#[test]
fn pip_install_python_then_its_pytest_suite_passes() {
    let root = Path::new(MANIFEST_DIR);
    let target = root.join("target");
    let venv = venv(&target);
    let bin = venv.join("bin");
    // maturin is found on PATH; the build honours CARGO_BUILD_JOBS and has its own target
    // directory, so it does not wait on the lock of the `cargo test` running this.
    let path = std::env::join_paths(
        std::iter::once(bin.clone())
            .chain(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())),
    )
    .expect("PATH joins");
    let started = std::time::Instant::now();
    check(
        "pip install ./python",
        Command::new(bin.join("pip"))
            .current_dir(root)
            .env("PATH", &path)
            .env("CARGO_TARGET_DIR", target.join("python"))
            .env_remove("CARGO_MAKEFLAGS")
            .args([
                "install",
                "-q",
                "--disable-pip-version-check",
                "--no-build-isolation",
                "--force-reinstall",
                "--no-deps",
                "./python",
            ]),
    );
    eprintln!("pip install ./python: {:.1} s", started.elapsed().as_secs_f64());
    let started = std::time::Instant::now();
    // Run from a scratch directory, so that `import propsim` is the installed package and
    // not the source tree's python/propsim.
    let scratch = tempfile::tempdir().expect("a temporary directory");
    let out = check(
        "pytest python/tests",
        Command::new(bin.join("python"))
            .current_dir(scratch.path())
            .env("PATH", &path)
            .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
            .arg(root.join("python/tests")),
    );
    eprintln!(
        "pytest: {:.1} s\n{}",
        started.elapsed().as_secs_f64(),
        String::from_utf8_lossy(&out.stdout).lines().last().unwrap_or("")
    );
}
