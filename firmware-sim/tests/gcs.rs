//! A real ground station against the SITL: `tools/gcs/gcs_check.py`
//! (pymavlink) runs `firmware-sim sitl route --speedup 50` (this test
//! build's binary) and checks missions, parameters, pause and continue,
//! bad missions and link loss (docs/mavlink.md, "The SITL").
//!
//! Its Python: `WMR_GCS_PYTHON` if set (`cargo xtask ci` makes the
//! virtual environment first), else a virtual environment made here
//! under `target/gcs-venv-test` with the pinned
//! `tools/gcs/requirements.txt` (needs `python3` with `venv` and PyPI).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace_root() -> PathBuf {
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

/// The ground station's Python (module documentation).
fn python() -> PathBuf {
    if let Some(python) = std::env::var_os("WMR_GCS_PYTHON") {
        return PathBuf::from(python);
    }
    let root = workspace_root();
    let dir = root.join("target").join("gcs-venv-test");
    let python = dir.join("bin").join("python");
    if !python.exists() {
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
    }
    python
}

#[test]
fn pymavlink_ground_station_against_the_sitl() {
    let script = workspace_root()
        .join("tools")
        .join("gcs")
        .join("gcs_check.py");
    let out = Command::new(python())
        .arg(&script)
        .args([
            "--firmware-sim",
            env!("CARGO_BIN_EXE_firmware-sim"),
            "--speedup",
            "50",
        ])
        .output()
        .expect("start the ground station");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "the ground station's checks failed (above)"
    );
    // The script's own count: every check ran and passed.
    let summary = stdout
        .lines()
        .rev()
        .find(|l| l.ends_with(" failed"))
        .expect("a summary");
    assert!(summary.ends_with(", 0 failed"), "{summary}");
    let passed: u32 = summary.split(' ').next().unwrap().parse().unwrap();
    assert!(passed >= 29, "only {passed} checks ran");
}
