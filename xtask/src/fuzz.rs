//! `cargo xtask fuzz [--seconds N]`: every fuzz target of `fuzz/` for a
//! short fixed time on its committed corpus, failing on any crash.
//!
//! The targets (`fuzz/fuzz_targets/`) are a cargo-fuzz project of their own,
//! outside the workspace: libFuzzer's instrumentation needs the nightly
//! toolchain. This task checks that nightly is installed (and fails, saying
//! how to get it, if not: it is not silently skipped), installs cargo-fuzz
//! with cargo when missing, refuses a stale `fuzz/Cargo.lock` (rather than
//! let cargo rewrite it), builds every target once and runs each in turn.
//!
//! Nothing tracked is written: builds go to `target/fuzz/`, and libFuzzer's
//! new corpus entries and crash artifacts to `target/fuzz-corpus/<target>/`
//! and `target/fuzz-artifacts/<target>/`; the committed corpus
//! `fuzz/corpus/<target>/` is only read (libFuzzer writes into the first
//! corpus directory it is given, which is the scratch one); the seed writer
//! `fuzz/examples/make_seeds.rs` writes to `target/fuzz-seeds/`, and its
//! seeds must equal the committed ones (a changed link message makes them
//! stale: regenerate with `cd fuzz && cargo run --example make_seeds`). Every committed
//! input runs first, so a crash that was fixed, with its input committed to
//! the corpus, cannot come back unnoticed. The long runs (millions of
//! executions) are done by hand: `fuzz/README.md`.

use std::path::Path;
use std::process::Command;

use crate::target::workspace_root;
use crate::{Result, output, run, step};

/// The fuzz targets, in the order they run.
pub const TARGETS: [&str; 6] = [
    "rfid_frames",
    "link_decode",
    "link_session",
    "pilot_step",
    "scenario_toml",
    "mavlink_rx",
];

/// Seconds each target runs in CI.
pub const CI_SECONDS: u64 = 15;

/// The toolchain cargo-fuzz builds with.
const NIGHTLY: &str = "nightly";

/// libFuzzer's sanitizer: none. The fuzzed code is safe Rust (`unsafe` is
/// denied in the workspace), so AddressSanitizer would mostly find nothing
/// and halve the executions per second; panics, overflow checks and debug
/// assertions (on in `fuzz/Cargo.toml`'s profile) are the findings.
const SANITIZER: &str = "none";

/// Runs every target for `seconds` each.
pub fn fuzz(seconds: u64) -> Result {
    let root = workspace_root();
    let target_dir = root.join("target").join("fuzz");
    let target_dir_arg = target_dir.to_string_lossy().into_owned();
    step("fuzz: prerequisites (nightly, cargo-fuzz)", prerequisites)?;
    let manifest = root.join("fuzz").join("Cargo.toml");
    let manifest_arg = manifest.to_string_lossy().into_owned();
    step("fuzz: rustfmt, lock file", || {
        run(
            "cargo",
            &["fmt", "--manifest-path", &manifest_arg, "--", "--check"],
            &[],
        )?;
        // `--locked` fails, without writing, when the lock file would change
        // (e.g. a dependency added to the core but not to fuzz/Cargo.lock).
        output(
            "cargo",
            &[
                "metadata",
                "--locked",
                "--format-version",
                "1",
                "--manifest-path",
                &manifest_arg,
            ],
        )
        .map(|_| ())
        .map_err(|e| {
            format!(
                "{e}: fuzz/Cargo.lock is out of date; update it with \
                 `cargo metadata --manifest-path fuzz/Cargo.toml --format-version 1 >/dev/null` \
                 and commit it"
            )
        })
    })?;
    step("fuzz: the committed seeds are make_seeds' own", || {
        committed_seeds_are_current(&root)
    })?;
    step("fuzz: build every target (nightly, libFuzzer)", || {
        cargo_fuzz(
            &root,
            &["build", "-s", SANITIZER, "--target-dir", &target_dir_arg],
        )
    })?;
    for name in TARGETS {
        step(&format!("fuzz {name} ({seconds} s)"), || {
            run_target(&root, &target_dir_arg, name, seconds)
        })?;
    }
    Ok(())
}

/// Runs the seed writer into `target/fuzz-seeds/` and compares each seed
/// it writes with the committed one.
fn committed_seeds_are_current(root: &Path) -> Result {
    let fuzz = root.join("fuzz");
    let fresh = root.join("target").join("fuzz-seeds");
    if fresh.exists() {
        std::fs::remove_dir_all(&fresh).map_err(|e| format!("{}: {e}", fresh.display()))?;
    }
    let target_dir = root.join("target").join("fuzz-seeds-build");
    let status = Command::new("cargo")
        .arg(format!("+{NIGHTLY}"))
        .args(["run", "-q", "--example", "make_seeds", "--target-dir"])
        .arg(&target_dir)
        .arg("--")
        .arg(&fresh)
        .current_dir(&fuzz)
        .status()
        .map_err(|e| format!("cargo run --example make_seeds: {e}"))?;
    if !status.success() {
        return Err(format!("cargo run --example make_seeds: {status}"));
    }
    let mut stale = Vec::new();
    let mut count = 0_usize;
    for target in std::fs::read_dir(&fresh).map_err(|e| format!("{}: {e}", fresh.display()))? {
        let target = target.map_err(|e| e.to_string())?.path();
        for seed in std::fs::read_dir(&target).map_err(|e| format!("{}: {e}", target.display()))? {
            let seed = seed.map_err(|e| e.to_string())?.path();
            let relative = seed.strip_prefix(&fresh).map_err(|e| e.to_string())?;
            let committed = fuzz.join("corpus").join(relative);
            let fresh_bytes =
                std::fs::read(&seed).map_err(|e| format!("{}: {e}", seed.display()))?;
            count += 1;
            if std::fs::read(&committed).ok() != Some(fresh_bytes) {
                stale.push(relative.display().to_string());
            }
        }
    }
    if stale.is_empty() {
        println!("    {count} seeds equal the committed ones");
        Ok(())
    } else {
        stale.sort();
        Err(format!(
            "fuzz/corpus is stale ({}); regenerate with `cd fuzz && cargo run --example \
             make_seeds` and commit",
            stale.join(", ")
        ))
    }
}

fn run_target(root: &Path, target_dir: &str, name: &str, seconds: u64) -> Result {
    let committed = root.join("fuzz").join("corpus").join(name);
    if !committed.is_dir() {
        return Err(format!("no committed corpus {}", committed.display()));
    }
    let scratch = root.join("target").join("fuzz-corpus").join(name);
    let artifacts = root.join("target").join("fuzz-artifacts").join(name);
    for dir in [&scratch, &artifacts] {
        if dir.exists() {
            std::fs::remove_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let scratch = scratch.to_string_lossy().into_owned();
    let committed = committed.to_string_lossy().into_owned();
    let max_total_time = format!("-max_total_time={seconds}");
    let artifact_prefix = format!("-artifact_prefix={}/", artifacts.to_string_lossy());
    cargo_fuzz(
        root,
        &[
            "run",
            "-s",
            SANITIZER,
            "--target-dir",
            target_dir,
            name,
            &scratch,
            &committed,
            "--",
            &max_total_time,
            &artifact_prefix,
            // One process (no -jobs, no -fork): the machine has two cores.
            "-print_final_stats=1",
        ],
    )
    .map_err(|e| {
        format!(
            "{e}: a crash; its input is in {} (reproduce with `cargo +nightly fuzz run -s {SANITIZER} {name} <file>`)",
            artifacts.display()
        )
    })
}

/// `cargo +nightly fuzz <args>` in the workspace root (cargo-fuzz finds
/// `fuzz/` there).
fn cargo_fuzz(root: &Path, args: &[&str]) -> Result {
    let mut all = vec!["+nightly", "fuzz"];
    all.extend_from_slice(args);
    let status = Command::new("cargo")
        .args(&all)
        .current_dir(root)
        .status()
        .map_err(|e| format!("cannot start cargo: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`cargo {}` failed ({status})", all.join(" ")))
    }
}

/// The nightly toolchain (checked) and cargo-fuzz (installed if missing).
pub fn prerequisites() -> Result {
    check_nightly()?;
    install_cargo_fuzz()
}

/// The nightly toolchain must be installed; CI fails here, saying so, if
/// it is not.
fn check_nightly() -> Result {
    let listed = output("rustup", &["toolchain", "list"])?;
    if listed
        .lines()
        .any(|l| l.trim_start().starts_with(&format!("{NIGHTLY}-")))
    {
        output("rustup", &["run", NIGHTLY, "rustc", "--version"]).map(|v| {
            eprintln!("    {}", v.trim());
        })
    } else {
        Err(format!(
            "the {NIGHTLY} toolchain is not installed, and the fuzz targets need it \
             (cargo-fuzz builds with libFuzzer's instrumentation, a nightly-only \
             rustc flag): install it with `rustup toolchain install {NIGHTLY} \
             --profile minimal`; installed: {}",
            listed.trim().replace('\n', ", ")
        ))
    }
}

/// cargo-fuzz, installed with cargo when missing.
fn install_cargo_fuzz() -> Result {
    if output("cargo", &["fuzz", "--version"]).is_ok() {
        return Ok(());
    }
    eprintln!("cargo-fuzz missing: installing it with cargo");
    run("cargo", &["install", "cargo-fuzz", "--locked"], &[])
}
