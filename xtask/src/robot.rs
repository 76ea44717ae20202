//! `cargo xtask firmware --robot FILE` and `cargo xtask flash --robot FILE`:
//! the Black Pill firmware with a robot file's configuration in flash.
//!
//! xtask uses no crate of the workspace, so the robot file is validated by
//! `firmware-sim robot-image FILE --out IMAGE`: the simulator's own
//! validation of the robot (the core's constructors included; a bad file
//! fails here, naming the file, key and reason), the tag map's capacity
//! checked, and the image written (`wmr_link::image`). The firmware's
//! `build.rs` then includes the image (`WMR_ROBOT_IMAGE`), which replaces
//! the board's compiled-in `PILOT`, tag table and telemetry decimation
//! (`TELEMETRY_EVERY_TICKS`: the robot file's `[telemetry] every_ticks`). The cargo features the
//! robot needs (the wheel-speed observer, the fusion estimator's UKF or
//! particle filter) are the ones `robot-image` prints.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::{step, target};

/// The chip probe-rs flashes (`.cargo/config.toml`'s runner).
pub const CHIP: &str = "STM32F411CEUx";

/// The robot file's path, absolute (cargo runs in the workspace root).
fn absolute(file: &str) -> Result<PathBuf, String> {
    std::path::absolute(file).map_err(|e| format!("{file}: {e}"))
}

/// Validates `file` and writes its image; returns the image and the
/// firmware features it needs.
pub(crate) fn robot_image(file: &Path, image: &Path) -> Result<Vec<String>, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(target::workspace_root())
        .args([
            "run",
            "--quiet",
            "--release",
            "-p",
            "firmware-sim",
            "--",
            "robot-image",
        ])
        .arg(file)
        .arg("--out")
        .arg(image)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| format!("cannot start cargo: {e}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    print!("{stdout}");
    if !out.status.success() {
        return Err(format!("the robot file {} was refused", file.display()));
    }
    Ok(stdout
        .lines()
        .filter_map(|l| l.strip_prefix("firmware features: "))
        .flat_map(|l| l.split(',').map(str::trim).map(str::to_owned))
        .filter(|f| !f.is_empty())
        .collect())
}

/// Builds the Black Pill firmware with `file`'s configuration, copied to
/// `target/firmware/wmr-firmware-blackpill-<robot file stem>.elf` (its
/// image beside it, `.robot`).
///
/// # Errors
/// The robot file refused, or the build failing.
pub fn build_robot_firmware(file: &str) -> Result<PathBuf, String> {
    let path = absolute(file)?;
    let stem = path
        .file_stem()
        .map_or_else(|| "robot".into(), |s| s.to_string_lossy().into_owned());
    let out_dir = target::workspace_root().join("target").join("firmware");
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let image = out_dir.join(format!("wmr-firmware-blackpill-{stem}.robot"));
    let mut extra = Vec::new();
    step(&format!("validate {file} and write its image"), || {
        extra = robot_image(&path, &image)?;
        Ok(())
    })?;
    let mut features = vec!["board-blackpill"];
    features.extend(extra.iter().map(String::as_str));
    let image_arg = image.to_string_lossy().into_owned();
    let mut built = Vec::new();
    step(
        &format!("build firmware blackpill with {file} (release)"),
        || {
            built = target::Build {
                bins: &["wmr-firmware"],
                no_default_features: true,
                features: &features,
                env: &[("WMR_ROBOT_IMAGE", &image_arg)],
            }
            .run(&format!("firmware-blackpill-{stem}"))?;
            Ok(())
        },
    )?;
    let built = built.first().ok_or("no ELF built")?;
    let elf = out_dir.join(format!("wmr-firmware-blackpill-{stem}.elf"));
    std::fs::copy(built, &elf).map_err(|e| format!("{}: {e}", built.display()))?;
    Ok(elf)
}

/// [`build_robot_firmware`], then flashes it through a debug probe:
/// `probe-rs run --chip STM32F411CEUx ELF` (flash, reset, print the defmt
/// log until Ctrl-C), the command printed first. Without probe-rs on the
/// `PATH`, the command is printed and the task fails, saying so.
///
/// # Errors
/// As [`build_robot_firmware`], probe-rs missing or failing.
pub fn flash(file: &str) -> Result<(), String> {
    let elf = build_robot_firmware(file)?;
    let args = ["run", "--chip", CHIP];
    println!("probe-rs {} {}", args.join(" "), elf.display());
    match Command::new("probe-rs").args(args).arg(&elf).status() {
        Ok(status) if status.success() => Ok(()),
        Ok(status) => Err(format!("probe-rs failed ({status})")),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(format!(
            "probe-rs is not installed (`cargo install probe-rs-tools`); the firmware is \
             built: run the command above with the board's probe attached ({})",
            elf.display()
        )),
        Err(e) => Err(format!("cannot start probe-rs: {e}")),
    }
}
