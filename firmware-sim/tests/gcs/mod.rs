//! What the ground-station tests (`sitl.rs`, `hil_mavlink.rs`) share: the
//! in-process ground station ([`station::Gcs`]), and the pymavlink check
//! (`tools/gcs/gcs_check.py`) run on this test build's `firmware-sim`, and
//! its Python.
//!
//! The Python: `WMR_GCS_PYTHON` if set (`cargo xtask ci` makes the
//! virtual environment first), else a virtual environment made here under
//! `target/gcs-venv-test` with the pinned `tools/gcs/requirements.txt`
//! (needs `python3` with `venv` and PyPI).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

pub mod station;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn run(program: &Path, args: &[&str]) {
    let status = Command::new(program)
        .args(args)
        .status()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", program.display()));
    assert!(
        status.success(),
        "{} {} failed",
        program.display(),
        args.join(" ")
    );
}

/// The ground station's Python (module documentation). Made once per
/// test process (the tests of one binary run in threads and would each
/// find a half-made environment); an environment counts as made only
/// once its requirements are installed (the file `installed` in it), so
/// an interrupted install is redone.
pub fn python() -> PathBuf {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON.get_or_init(make_python).clone()
}

fn make_python() -> PathBuf {
    if let Some(python) = std::env::var_os("WMR_GCS_PYTHON") {
        return PathBuf::from(python);
    }
    let root = workspace_root();
    let dir = root.join("target").join("gcs-venv-test");
    let python = dir.join("bin").join("python");
    let installed = dir.join("installed");
    if !installed.exists() {
        run(
            Path::new("python3"),
            &["-m", "venv", "--clear", dir.to_str().unwrap()],
        );
        let requirements = root.join("tools").join("gcs").join("requirements.txt");
        run(
            &python,
            &[
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
                "-r",
                requirements.to_str().unwrap(),
            ],
        );
        std::fs::write(&installed, b"").expect("mark the environment made");
    }
    python
}

/// Runs `tools/gcs/gcs_check.py` with `args` against this test build's
/// `firmware-sim`; asserts it passed with no check failed and returns the
/// checks passed and skipped (its last line: "N passed, N failed, N
/// skipped").
pub fn gcs_check(args: &[&str]) -> (u32, u32) {
    let script = workspace_root()
        .join("tools")
        .join("gcs")
        .join("gcs_check.py");
    let out = Command::new(python())
        .arg(&script)
        .args(["--firmware-sim", env!("CARGO_BIN_EXE_firmware-sim")])
        .args(args)
        .output()
        .expect("start the ground station");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "the ground station's checks failed (above)"
    );
    let summary = stdout
        .lines()
        .rev()
        .find(|l| l.ends_with(" skipped"))
        .expect("a summary");
    let counts: Vec<u32> = summary
        .split(", ")
        .map(|part| part.split(' ').next().unwrap().parse().unwrap())
        .collect();
    let [passed, failed, skipped] = counts[..] else {
        panic!("not a summary: {summary}")
    };
    assert_eq!(failed, 0, "{summary}");
    (passed, skipped)
}
