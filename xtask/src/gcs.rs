//! The pymavlink ground station against the SITL and against the firmware
//! under QEMU (`tools/gcs/gcs_check.py`, docs/mavlink.md "The SITL" and
//! "The firmware under QEMU"): a Python virtual environment under
//! `target/gcs-venv` with the pinned `tools/gcs/requirements.txt`, made
//! once and re-made when the requirements change.
//!
//! * `cargo xtask gcs`: builds `firmware-sim` (release) and runs the
//!   script against its SITL.
//! * `cargo xtask gcs --hil`: builds `firmware-sim` (release) and the
//!   QEMU-board firmware (as `cargo xtask firmware` does) and runs the
//!   script with `--hil` against `firmware-sim hil --mavlink`.
//! * `cargo xtask gcs --hil --particle-filter`: the same with the
//!   QEMU-board firmware built with `fusion-particle-filter` (as `cargo
//!   xtask ci` builds it for the HIL tests), the script's route run with
//!   the fusion estimator's particle filter (`--particle-filter`).
//! * `cargo xtask ci`: [`venv`] before the workspace tests, whose
//!   `firmware-sim/tests/sitl.rs` and `firmware-sim/tests/hil_mavlink.rs`
//!   run the script against the `firmware-sim` that the test build has
//!   just built (no build of their own), with the environment's Python in
//!   `WMR_GCS_PYTHON` and the firmware in `WMR_FIRMWARE_ELF`.

use std::path::PathBuf;

use crate::target::workspace_root;
use crate::{Result, cargo, run, step};

/// The script, from the workspace root.
const SCRIPT: &str = "tools/gcs/gcs_check.py";
/// Its pinned requirements, from the workspace root.
const REQUIREMENTS: &str = "tools/gcs/requirements.txt";

/// The environment's Python, made (or re-made) as needed: `python3 -m
/// venv target/gcs-venv`, then `pip install -r` the requirements; the
/// requirements installed are kept beside it, so that a later call with
/// the same requirements does nothing.
pub fn venv() -> std::result::Result<PathBuf, String> {
    let root = workspace_root();
    let dir = root.join("target").join("gcs-venv");
    let python = dir.join("bin").join("python");
    let requirements = root.join(REQUIREMENTS);
    let wanted = std::fs::read_to_string(&requirements)
        .map_err(|e| format!("{}: {e}", requirements.display()))?;
    let stamp = dir.join("requirements.installed");
    if python.exists() && std::fs::read_to_string(&stamp).is_ok_and(|s| s == wanted) {
        return Ok(python);
    }
    step("python venv for the ground station (pymavlink)", || {
        let dir_text = dir.display().to_string();
        run("python3", &["-m", "venv", "--clear", &dir_text], &[])?;
        let python_text = python.display().to_string();
        let requirements_text = requirements.display().to_string();
        run(
            &python_text,
            &[
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
                "-r",
                &requirements_text,
            ],
            &[],
        )?;
        run(&python_text, &["-c", "import pymavlink.mavutil"], &[])?;
        std::fs::write(&stamp, &wanted).map_err(|e| format!("{}: {e}", stamp.display()))
    })?;
    Ok(python)
}

/// Which QEMU-board firmware `cargo xtask gcs --hil` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HilFirmware {
    /// The default build (`cargo xtask firmware`'s).
    Default,
    /// The build with the fusion particle filter, on a route run with it.
    ParticleFilter,
}

/// `cargo xtask gcs [--hil [--particle-filter]]`: the script against a
/// release `firmware-sim`'s SITL, or with `hil` against the firmware
/// under QEMU.
pub fn gcs(hil: Option<HilFirmware>) -> Result {
    let python = venv()?;
    let firmware = match hil {
        Some(HilFirmware::Default) => {
            let elfs = crate::build_firmware()?;
            let elf = elfs
                .into_iter()
                .find(|(board, _)| *board == "qemu")
                .map(|(_, elf)| elf)
                .ok_or("no QEMU-board firmware")?;
            Some(elf.display().to_string())
        }
        Some(HilFirmware::ParticleFilter) => Some(
            crate::build_hil_variant(wmr_core::builds::FUSION_PARTICLE_FILTER)?
                .display()
                .to_string(),
        ),
        None => None,
    };
    step("build firmware-sim (release)", || {
        cargo(&["build", "--release", "-p", "firmware-sim"], &[])
    })?;
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| workspace_root().join("target"), PathBuf::from);
    let sim = target.join("release").join("firmware-sim");
    let script = workspace_root().join(SCRIPT).display().to_string();
    let sim = sim.display().to_string();
    let mut args = vec![script.as_str(), "--firmware-sim", sim.as_str()];
    if let Some(elf) = &firmware {
        // 20x: the firmware under QEMU keeps up with it on a loaded
        // 2-core machine (docs/mavlink.md, "The firmware under QEMU").
        args.extend(["--hil", "--firmware", elf.as_str(), "--speedup", "20"]);
    }
    if hil == Some(HilFirmware::ParticleFilter) {
        args.push("--particle-filter");
    }
    let against = match hil {
        Some(HilFirmware::Default) => "the firmware under QEMU",
        Some(HilFirmware::ParticleFilter) => "the particle filter's firmware under QEMU",
        None => "the SITL",
    };
    step(
        &format!("ground station (pymavlink) against {against}"),
        || {
            run(&python.display().to_string(), &args, &[]).map_err(|e| {
                format!("{e}: a check of the ground station failed (its output above)")
            })
        },
    )
}
