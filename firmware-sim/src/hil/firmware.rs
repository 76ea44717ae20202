//! The firmware under test: building the QEMU board's ELF with cargo, and
//! decoding its defmt log.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, ensure};

/// The firmware's target triple.
pub const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";

/// The workspace root (this crate's parent directory, fixed at build time).
#[must_use]
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// The environment variable naming the default QEMU-board firmware's ELF
/// for the HIL tests ([`hil_test_firmware`]).
pub const HIL_FIRMWARE_ENV: &str = "WMR_FIRMWARE_ELF";

/// The QEMU-board firmware a HIL test runs: the default build (`None`)
/// or an optional one (`wmr_core::builds`: one feature more). Its ELF is
/// the path in [`HIL_FIRMWARE_ENV`] (or the build's `hil_firmware_env`)
/// if set, relative paths taken from the workspace root (`cargo xtask
/// ci` builds each and sets its variable); else it is built here into
/// `target/hil-firmware` (or `target/hil-firmware-<feature>`): a target
/// directory of its own, so that the nested cargo never waits on the
/// test's own build lock.
///
/// # Errors
/// The build failing ([`build_firmware_with`]).
pub fn hil_test_firmware(
    build: Option<wmr_core::builds::OptionalBuild>,
) -> anyhow::Result<PathBuf> {
    let root = workspace_root();
    let env = build.map_or(HIL_FIRMWARE_ENV, |b| b.hil_firmware_env);
    if let Some(path) = std::env::var_os(env) {
        return Ok(root.join(path));
    }
    let (dir, features) = match build {
        None => ("hil-firmware".to_owned(), Vec::new()),
        Some(b) => (format!("hil-firmware-{}", b.feature), vec![b.feature]),
    };
    build_firmware_with(Some(&root.join("target").join(&dir)), &features)
        .with_context(|| format!("building the QEMU-board firmware into target/{dir}"))
}

/// Builds the QEMU-board firmware (release) with cargo and returns its ELF.
///
/// `target_dir`: cargo's target directory (`None`: the workspace's).
///
/// # Errors
/// cargo missing or the build failing.
pub fn build_firmware(target_dir: Option<&Path>) -> anyhow::Result<PathBuf> {
    build_firmware_with(target_dir, &[])
}

/// [`build_firmware`] with the firmware's cargo `features` added to its
/// default (`board-qemu`), e.g. `fusion-ukf`.
///
/// # Errors
/// cargo missing or the build failing.
pub fn build_firmware_with(
    target_dir: Option<&Path>,
    features: &[&str],
) -> anyhow::Result<PathBuf> {
    let root = workspace_root();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(&root).args([
        "build",
        "--quiet",
        "--release",
        "--package",
        "wmr-firmware",
        "--bin",
        "wmr-firmware",
        "--target",
        FIRMWARE_TARGET,
    ]);
    if let Some(dir) = target_dir {
        cmd.arg("--target-dir").arg(dir);
    }
    if !features.is_empty() {
        cmd.arg("--features").arg(features.join(","));
    }
    let status = cmd
        .status()
        .context("running cargo to build the firmware")?;
    ensure!(
        status.success(),
        "building the firmware failed ({status}); is the target installed? \
         `rustup target add {FIRMWARE_TARGET}`"
    );
    // Where cargo put it: the directory given, else `CARGO_TARGET_DIR`
    // (cargo honours it; relative to the workspace root, where cargo
    // runs), else the workspace's.
    let dir = match (target_dir, std::env::var_os("CARGO_TARGET_DIR")) {
        (Some(dir), _) => dir.to_path_buf(),
        (None, Some(env)) => root.join(env),
        (None, None) => root.join("target"),
    };
    Ok(dir
        .join(FIRMWARE_TARGET)
        .join("release")
        .join("wmr-firmware"))
}

/// Decodes a raw defmt log (the firmware's semihosting output) with the
/// firmware ELF's format table, one line per message.
///
/// # Errors
/// The ELF has no defmt table, or a file cannot be read.
pub fn decode_defmt_log(elf: &Path, raw_log: &Path) -> anyhow::Result<String> {
    let elf_bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let table = defmt_decoder::Table::parse(&elf_bytes)?
        .ok_or_else(|| anyhow::anyhow!("{} has no defmt table", elf.display()))?;
    let raw = std::fs::read(raw_log).with_context(|| format!("reading {}", raw_log.display()))?;
    let mut decoder = table.new_stream_decoder();
    decoder.received(&raw);
    let mut text = String::new();
    loop {
        match decoder.decode() {
            Ok(frame) => {
                text.push_str(&frame.display(false).to_string());
                text.push('\n');
            }
            Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
            Err(defmt_decoder::DecodeError::Malformed) => {
                text.push_str("(malformed defmt frame skipped)\n");
            }
        }
    }
    Ok(text)
}
